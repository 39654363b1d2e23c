"""Run-stopping errors under ``mpirun -n 2``: every rank stops together, promptly, with one clear
line (a support past the ghost layer is an error, never silent garbage; no hang)."""
import subprocess
import sys
import time

import pytest
from mpi_launch import MPI_MARKS, mpirun
from tools.rank_cases import CROSSING

pytestmark = MPI_MARKS  # every test here launches mpirun


def _run2(tmp_path, *args):
    t0 = time.monotonic()
    proc = subprocess.run([mpirun(), "-n", "2", sys.executable, "-m", "parmpm", "run", *args,
                           "--out", str(tmp_path / "out"), "--quiet"],
                          capture_output=True, text=True, timeout=120)
    return proc, time.monotonic() - t0


def test_ghost_reach_check_stops_both_ranks_with_the_fix(tmp_path):
    """Unscaled CPDI at one particle per cell stretches its domains past a one-cell ghost layer
    within a few dozen steps: the run must stop on both ranks with the particle, its position,
    its reach and the l_cr that avoids it."""
    proc, wall = _run2(tmp_path, "hanging_bar", "--set", "bodies.0.ppc=1", "--set", "method.lcr=none",
                       "--set", "grid.ghost=1", "--set", "grid.patch_size=4",
                       "--set", "metrics.stop_on_separation=false")
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("parmpm: error:")]
    assert len(lines) == 1, proc.stderr  # printed once, by rank 0
    msg = lines[0]
    for fragment in ("particle ", " at (", "reaches beyond the ghost layer", "domain reach",
                     "ghost width 1 cells", "method.lcr <= 1dx"):
        assert fragment in msg, msg
    assert "Traceback" not in proc.stderr
    assert wall < 60, f"took {wall:.1f} s"


def test_particle_leaving_the_grid_stops_every_rank(tmp_path):
    proc, _ = _run2(tmp_path, CROSSING, "--set", "time.steps=400")
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("parmpm: error:")]
    # the disk's supports reach the grid's edge (p2g) before a centre leaves it
    assert len(lines) == 1 and ("outside the grid" in lines[0] or "left the grid" in lines[0]), \
        proc.stderr


@pytest.mark.parametrize("kind,code", [("user", 2), ("bug", 1)])
def test_failure_on_one_rank_ends_every_rank(tmp_path, kind, code):
    """Rank 1 fails alone mid-run while rank 0 waits for it in a collective: the job must end
    (abort) with rank 1's whole message, never hang (rank 0 would wait forever: the timeout, long
    enough for a cold compile on a loaded machine, is the hang). The message once came through
    cut, or not at all, one time in six: the launcher drops what it has not forwarded when the
    job aborts (``parmpm.cli.main._abort`` waits for it)."""
    script = __import__("pathlib").Path(__file__).parent / "mpi_fail_one_rank.py"
    proc = subprocess.run([mpirun(), "-n", "2", sys.executable, str(script), kind, str(tmp_path / "o")],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode != 0
    assert f"injected {'failure' if kind == 'user' else 'bug'} on rank 1 only" in proc.stderr
    if kind == "user":
        assert "Traceback" not in proc.stderr
