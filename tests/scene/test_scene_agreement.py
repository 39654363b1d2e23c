"""Every rank runs one scene (issue 28 item 1): rank 0 reads the scene file once and shares it,
and the ranks compare a digest of what they resolved. Before, each rank read the file itself:
a file replaced while mpirun started the ranks gave a run of mixed scenes that exited 0, and an
MPMD launch ran a.toml on one rank and b.toml on another."""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

from mpi_launch import needs_mpi, mpirun

from parmpm.scene.load import load_scene
from parmpm.scene.agreement import first_difference, input_digest, scene_digest

REPO = Path(__file__).resolve().parents[2]
TIMEOUT_S = 300
#: a 1D bar on two patches of 8 cells: on two ranks each holds half of it
BAR = (REPO / "parmpm" / "scene" / "builtin" / "hanging_bar_1d.toml").read_text()
QUIET = ["--quiet", "--set", "output.figure=false", "--set", "output.snapshots=false"]


def _scenes(tmp_path: Path) -> tuple[Path, Path]:
    """a.toml and b.toml: the same bar (one name) at two densities."""
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    bar = 'name = "bar"\n' + BAR.replace("end = 0.3", "steps = 3")
    a.write_text(bar.replace("density = 1050.0", "density = 1000.0"))
    b.write_text(bar.replace("density = 1050.0", "density = 3000.0"))
    return a, b


def _launch(args: list[str], cwd: Path) -> tuple[subprocess.CompletedProcess, float]:
    t0 = time.monotonic()
    proc = subprocess.run([mpirun(), *args], capture_output=True, text=True, timeout=TIMEOUT_S,
                          cwd=cwd)
    return proc, time.monotonic() - t0


def _errors(proc) -> list[str]:
    return [ln for ln in proc.stderr.splitlines() if ln.startswith("parmpm: error:")]


# --- the pieces ---------------------------------------------------------------------------------
def test_digest_and_first_difference():
    a = load_scene("hanging_bar").data
    b = load_scene("hanging_bar", ["materials.bar.density=5000"]).data
    assert scene_digest(a) == scene_digest(load_scene("hanging_bar").data)
    assert scene_digest(a) != scene_digest(b)
    assert scene_digest(a, "step 20") != scene_digest(a, "step 30")
    assert first_difference(a, b) == ("materials.bar.density", 1050.0, 5000.0)
    assert first_difference(a, a) is None
    assert first_difference({"x": [1, 2]}, {"x": [1, 2, 3]}) == ("x", [1, 2], [1, 2, 3])
    assert first_difference({"x": 1}, {"x": 1.0}) == ("x", 1, 1.0)  # what JSON tells apart


def test_input_digest_tells_apart_what_a_rank_would_resolve_differently(tmp_path, monkeypatch):
    """A rank takes rank 0's resolved scene (and its body files' records, never reading them)
    only when its input digest is rank 0's: the same text, label, --set and working folder
    (issue 43); a --set, a value's spelling of another type or another folder (relative body
    files) makes it resolve its own; an input that does not parse has none."""
    read = (BAR, "bar.toml", "bar")
    monkeypatch.chdir(tmp_path)
    one = input_digest(read, ["time.steps=2"])
    assert one is not None and one == input_digest(read, ["time.steps=2"])
    assert one != input_digest(read, ["time.steps=3"])
    assert one != input_digest(read, ["time.steps=2.0"])
    assert one != input_digest((BAR, "other.toml", "bar"), ["time.steps=2"])
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    assert one != input_digest(read, ["time.steps=2"])
    assert input_digest(("grid = [", "bad.toml", "bad"), []) is None
    assert input_digest(read, ["no_equals_sign"]) is None


# --- under mpirun -------------------------------------------------------------------------------
#: rank 1 reads b.toml's text where it opens a.toml: the file was replaced (an editor's atomic
#: save) after rank 0 read it and before rank 1 did
REPLACED = """
import pathlib, sys
from mpi4py import MPI
if MPI.COMM_WORLD.Get_rank() == 1:
    read = pathlib.Path.read_text
    def replaced(self, *args, **kwargs):
        return read(self.with_name("b.toml") if self.name == "a.toml" else self, *args, **kwargs)
    pathlib.Path.read_text = replaced
from parmpm.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


@needs_mpi
def test_a_scene_file_replaced_while_the_ranks_start_is_read_once(tmp_path):
    """HEAD: exit 0 with a mass of neither version (rank 1 seeded its half at b's density)."""
    a, _ = _scenes(tmp_path)
    script = tmp_path / "replaced.py"
    script.write_text(REPLACED)
    proc, _ = _launch(["-n", "2", sys.executable, str(script), "run", str(a), "-o", "two",
                       *QUIET], tmp_path)
    assert proc.returncode == 0, proc.stderr
    from parmpm.cli.main import main
    assert main(["run", str(a), "-o", str(tmp_path / "one"), *QUIET]) == 0
    two = json.loads((tmp_path / "two" / "summary.json").read_text())
    one = json.loads((tmp_path / "one" / "summary.json").read_text())
    assert two["ranks"] == 2 and min(two["decomposition"]["particles_per_rank"]) > 0
    assert two["final"]["mass"] == one["final"]["mass"]  # a's bar, all of it
    assert "density = 1000.0" in (tmp_path / "two" / "scene.toml").read_text()


@needs_mpi
def test_mpmd_launch_of_two_scene_files_fails_in_one_line(tmp_path):
    """HEAD: exit 0, each rank running its own density (scene.toml: rank 0's only)."""
    a, b = _scenes(tmp_path)
    run = [sys.executable, "-m", "parmpm", "run"]
    proc, wall = _launch(["-n", "1", *run, str(a), "-o", "x", *QUIET, ":",
                          "-n", "1", *run, str(b), "-o", "x", *QUIET], tmp_path)
    lines = _errors(proc)
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    for fragment in ("ranks would run different scenes", "rank 1 has materials.bar.density = "
                     "3000.0", "rank 0 1000.0", "b.toml", "a.toml"):
        assert fragment in lines[0], lines[0]
    assert not (tmp_path / "x").exists()  # refused before anything was written
    assert wall < 120, f"took {wall:.0f} s"


@needs_mpi
def test_mpmd_launch_with_different_set_fails_in_one_line(tmp_path):
    a, _ = _scenes(tmp_path)
    run = [sys.executable, "-m", "parmpm", "run", str(a), "-o", "x", *QUIET]
    proc, _ = _launch(["-n", "1", *run, ":", "-n", "1", *run, "--set", "time.steps=4"], tmp_path)
    lines = _errors(proc)
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert "rank 1 has time.steps = 4" in lines[0] and "rank 0 3" in lines[0], lines[0]


@needs_mpi
def test_mpmd_restart_with_different_set_or_checkpoint_fails_in_one_line(tmp_path):
    from parmpm.cli.main import main

    a, _ = _scenes(tmp_path)
    assert main(["run", str(a), "-o", str(tmp_path / "r"), *QUIET, "--set", "time.steps=4",
                 "--set", "checkpoint.every_steps=1", "--set", "checkpoint.keep=4"]) == 0
    ck1, ck2 = (str(tmp_path / "r" / f"checkpoint_0000000{k}.h5") for k in (1, 2))
    restart = [sys.executable, "-m", "parmpm", "restart"]
    proc, _ = _launch(["-n", "1", *restart, ck1, "-o", "x", *QUIET, ":",
                       "-n", "1", *restart, ck1, "-o", "x", *QUIET, "--set", "time.steps=9"],
                      tmp_path)
    lines = _errors(proc)
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert "rank 1 has time.steps = 9" in lines[0], lines[0]
    proc, _ = _launch(["-n", "1", *restart, ck1, "-o", "x", *QUIET, ":",
                       "-n", "1", *restart, ck2, "-o", "x", *QUIET], tmp_path)
    lines = _errors(proc)
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert "ranks were given different checkpoints" in lines[0] and "step 2" in lines[0], lines[0]
    assert not (tmp_path / "x").exists()
    # the same checkpoint and scene on both ranks: runs
    proc, _ = _launch(["-n", "2", *restart, ck1, "-o", "x", *QUIET], tmp_path)
    assert proc.returncode == 0, proc.stderr


@needs_mpi
def test_an_unreadable_scene_under_two_ranks_is_one_line(tmp_path):
    """Rank 0 reads, the others hear its problem: one line, exit 2 everywhere."""
    proc, _ = _launch(["-n", "2", sys.executable, "-m", "parmpm", "run", "missing.toml",
                       *QUIET], tmp_path)
    lines = _errors(proc)
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert "missing.toml" in lines[0]
