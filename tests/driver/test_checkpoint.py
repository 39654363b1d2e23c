"""Checkpoints and restart: a run continued from a checkpoint is bit-for-bit the run
that never stopped, on the same or another number of ranks; bad files and unwritable folders are
one-line errors (exit 2) that leave earlier files intact; a kill while writing leaves every earlier
checkpoint valid; SIGTERM writes a final checkpoint."""
import json
import os
import shutil
import signal
import subprocess
import sys

import h5py
import numpy as np
import pytest
from cli_harness import parmpm_cli
from run_waits import HISTORY_EVERY_STEP, wait_for_steps
from mpi_launch import MPI_MARKS, mpirun, needs_mpi
from tools.rank_cases import CROSSING

from parmpm.cli.main import main

QUIET = ["--quiet"]
OFF = ["--set", "output.snapshots=false", "--set", "output.figure=false"]


def _cli(n, *args, timeout=600):
    return parmpm_cli(*args, ranks=n, timeout=timeout)


def _particles(path):
    """Every field as plain h5py reads it, sorted by global id (rows are in the writing ranks'
    order since format version 4), and the attributes."""
    with h5py.File(path, "r") as f:
        o = np.argsort(f["particles/gid"][:])
        return {k: f["particles"][k][:][o] for k in f["particles"]}, dict(f.attrs)


def _same(a, b):
    pa, aa = _particles(a)
    pb, ab = _particles(b)
    assert pa.keys() == pb.keys()
    for k in pa:
        np.testing.assert_array_equal(pa[k], pb[k], err_msg=k)
    assert (aa["step"], aa["time"], aa["dt"], aa["vmax"]) == (ab["step"], ab["time"], ab["dt"], ab["vmax"])




@pytest.fixture(scope="module")
def straight(tmp_path_factory, mpirun):
    """60 steps of the crossing scene (migration, patch-set changes, re-balancing) on 1 and 2
    ranks, a checkpoint every 30 steps; the hanging bar (with metrics) on 1 rank. It asks for the
    ``mpirun`` fixture, so every test using it is marked ``mpi`` (conftest.py): ``-m "not mpi"``
    never starts its 2-rank run."""
    root = tmp_path_factory.mktemp("ck")
    out = {}
    for n in (1, 2):
        d = root / f"cross{n}"
        proc = _cli(n, "run", CROSSING, "-o", str(d), *QUIET, "--set", "checkpoint.every_steps=30")
        assert proc.returncode == 0, proc.stderr
        out[f"cross{n}"] = d
    d = root / "hb"
    proc = _cli(1, "run", "hanging_bar", "-o", str(d), *QUIET, *OFF, "--set", "time.steps=40",
                "--set", "checkpoint.every_steps=20", "--set", "grid.patch_size=4")
    assert proc.returncode == 0, proc.stderr
    out["hb"] = d
    return out


def test_restart_on_one_rank_is_bit_identical_and_keeps_the_metrics(straight, tmp_path):
    d = straight["hb"]
    proc = _cli(1, "restart", str(d / "checkpoint_00000020.h5"), "-o", str(tmp_path), *QUIET)
    assert proc.returncode == 0, proc.stderr
    _same(d / "checkpoint_00000040.h5", tmp_path / "checkpoint_00000040.h5")
    s0 = json.loads((d / "summary.json").read_text())
    s1 = json.loads((tmp_path / "summary.json").read_text())
    assert s1["metrics"] == s0["metrics"] and s1["final"] == s0["final"]


@needs_mpi
@pytest.mark.parametrize("first,then", [(1, 1), (1, 2), (2, 2), (2, 1), (2, 3)])
def test_restart_on_any_rank_count_is_bit_identical(straight, tmp_path, first, then):
    d = straight[f"cross{first}"]
    proc = _cli(then, "restart", str(d / "checkpoint_00000030.h5"), "-o", str(tmp_path), *QUIET)
    assert proc.returncode == 0, proc.stderr
    _same(d / "checkpoint_00000060.h5", tmp_path / "checkpoint_00000060.h5")
    _same(straight["cross1"] / "checkpoint_00000060.h5", tmp_path / "checkpoint_00000060.h5")
    with h5py.File(d / "checkpoint_00000030.h5") as f:
        assert f.attrs["ranks"] == first


def test_restart_default_output_never_overwrites(straight):
    d = straight["hb"]
    before = {p.name: p.stat().st_mtime_ns for p in d.iterdir()}
    proc = _cli(1, "restart", str(d / "checkpoint_00000020.h5"), *QUIET)
    assert proc.returncode == 0, proc.stderr
    assert (d / "restart_00000020" / "summary.json").is_file()
    assert {p.name: p.stat().st_mtime_ns for p in d.iterdir() if p.is_file()} == \
        {k: v for k, v in before.items() if (d / k).is_file()}


def test_keep_deletes_older_checkpoints(tmp_path):
    assert main(["run", "hanging_bar_1d", "-o", str(tmp_path), "--quiet", "--set", "time.steps=10",
                 "--set", "checkpoint.every_steps=2", "--set", "checkpoint.keep=2",
                 "--set", "output.snapshots=false", "--set", "output.figure=false"]) == 0
    assert sorted(p.name for p in tmp_path.glob("checkpoint_*")) == \
        ["checkpoint_00000008.h5", "checkpoint_00000010.h5"]


# --- bad files ------------------------------------------------------------------------------------
def _bad(tmp_path, straight, how):
    good = straight["hb"] / "checkpoint_00000020.h5"
    bad = tmp_path / "checkpoint_00000020.h5"
    data = good.read_bytes()
    if how == "missing":
        return tmp_path / "nope.h5"
    if how == "truncated":
        bad.write_bytes(data[: len(data) // 2])
    elif how.startswith("flipped"):
        at = int(len(data) * float(how.split("@")[1]))
        b = bytearray(data)
        for i in range(at, at + 16):
            b[i] ^= 0xFF
        bad.write_bytes(bytes(b))
    elif how == "foreign":
        with h5py.File(bad, "w") as f:
            f["data"] = np.arange(10)
    elif how == "newer":
        shutil.copy(good, bad)
        with h5py.File(bad, "a") as f:
            f.attrs["version"] = 99
    elif how == "text":
        bad.write_text("not hdf5 at all\n")
    return bad


@pytest.mark.parametrize("how,fragment", [
    ("missing", "no such file"), ("truncated", ""), ("flipped@0.3", "damaged"),
    ("flipped@0.5", "damaged"), ("flipped@0.7", "damaged"), ("flipped@0.9", "damaged"),
    ("foreign", "not a parmpm checkpoint"), ("newer", "newer parmpm"), ("text", "HDF5"),
])
def test_bad_checkpoint_is_a_one_line_error(straight, tmp_path, capsys, how, fragment):
    path = _bad(tmp_path, straight, how)
    before = sorted(os.listdir(tmp_path))
    code = main(["restart", str(path), "--quiet", "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert err.startswith("parmpm: error: checkpoint '") and str(path) in err and "\n" not in err
    assert fragment in err
    assert "Traceback" not in err
    assert sorted(os.listdir(tmp_path)) == before  # nothing written, nothing removed


def test_unwritable_output_folder(straight, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code = main(["restart", str(straight["hb"] / "checkpoint_00000020.h5"), "--quiet",
                 "-o", str(blocker / "sub")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "cannot create output folder" in err, err


@needs_mpi
def test_bad_checkpoint_under_two_ranks_prints_once(straight, tmp_path):
    path = _bad(tmp_path, straight, "flipped@0.5")
    proc = _cli(2, "restart", str(path), *QUIET, "-o", str(tmp_path / "out"))
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("parmpm: error:")]
    assert proc.returncode == 2 and len(lines) == 1 and "damaged" in lines[0], proc.stderr


# --- kills and signals ---------------------------------------------------------------------------
KILL_WHILE_WRITING = """
import os, sys
from parmpm.io import checkpoint
from parmpm.cli.main import main
orig = checkpoint.CheckpointWriter.write
def write(self, lo, block):
    orig(self, lo, block)
    if self.path.name == "checkpoint_00000010.h5":
        self.f.flush()
        os._exit(9)  # killed in the middle of writing the second checkpoint
checkpoint.CheckpointWriter.write = write
sys.exit(main(sys.argv[1:]))
"""


def test_kill_while_writing_leaves_earlier_checkpoints_valid(tmp_path):
    proc = subprocess.run([sys.executable, "-c", KILL_WHILE_WRITING, "run", "hanging_bar_1d",
                           "-o", str(tmp_path), "--quiet", "--set", "time.steps=20",
                           "--set", "checkpoint.every_steps=5", "--set", "output.snapshots=false"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 9
    assert (tmp_path / "checkpoint_00000010.h5.tmp").exists()
    assert not (tmp_path / "checkpoint_00000010.h5").exists()
    proc = _cli(1, "restart", str(tmp_path / "checkpoint_00000005.h5"), "-o", str(tmp_path / "r"),
                "--set", "time.steps=10", *QUIET)
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("n", [1, pytest.param(2, marks=MPI_MARKS)])
def test_sigterm_writes_a_final_checkpoint(tmp_path, n):
    cmd = [sys.executable, "-m", "parmpm", "run", "vibrating_bar", "-o", str(tmp_path), "--quiet",
           *OFF, "--set", "time.end=1e6", *HISTORY_EVERY_STEP]
    if n > 1:
        cmd = [mpirun(), "-n", str(n)] + cmd
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for_steps(proc, tmp_path / "history.csv")
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    files = sorted(tmp_path.glob("checkpoint_*.h5"))
    assert len(files) == 1 and "continue with: parmpm restart" in err, err
    step = int(files[0].stem.split("_")[1])  # time.steps counts from the run's start
    proc2 = _cli(1, "restart", str(files[0]), "-o", str(tmp_path / "r"), "--set",
                 f"time.steps={step + 3}", *QUIET)
    assert proc2.returncode == 0, proc2.stderr


@needs_mpi
def test_xdmf_of_a_two_rank_run_reads_back(tmp_path):
    """The snapshot series of a 2-rank run: every step holds all particles in global-id order
    with velocity, stress, stretch, damage and the rank that held each particle — written in two
    parts (read with load_snapshots), or by one writer (read with meshio's public reader)."""
    import meshio

    from parmpm.io import load_snapshots

    args = (*QUIET, "--set", "time.end=0.02", "--set", "output.every=0.005",
            "--set", "grid.patch_size=4")
    proc = _cli(2, "run", "hanging_bar", "-o", str(tmp_path / "parts"), *args)
    assert proc.returncode == 0, proc.stderr
    assert len(list((tmp_path / "parts" / "hanging_bar.parts").glob("part_*.h5"))) == 2
    s = load_snapshots(tmp_path / "parts" / "hanging_bar.xdmf")
    assert s.times.size == 5
    for k in range(5):
        np.testing.assert_array_equal(s["gid"][k], np.arange(900))
        assert s["velocity"][k].shape == (900, 2) and s["stress"][k].shape == (900, 2, 2)
    assert set(np.unique(np.concatenate(s["rank"])).tolist()) == {0, 1}

    proc = _cli(2, "run", "hanging_bar", "-o", str(tmp_path / "one"), *args,
                "--set", "checkpoint.ranks_per_file=2")
    assert proc.returncode == 0, proc.stderr
    assert not (tmp_path / "one" / "hanging_bar.parts").exists()
    with meshio.xdmf.TimeSeriesReader(tmp_path / "one" / "hanging_bar.xdmf") as reader:
        points, cells = reader.read_points_cells()
        n = points.shape[0]
        assert n == 900 and len(cells[0].data) == n
        assert reader.num_steps == 5
        ranks = set()
        for k in range(reader.num_steps):
            t, pd, _ = reader.read_data(k)
            np.testing.assert_array_equal(pd["gid"], np.arange(n))
            assert pd["velocity"].shape == (n, 3) and pd["stress"].shape == (n, 9)
            assert pd["stretch"].shape == (n,) and pd["damage"].shape == (n,)
            ranks |= set(np.unique(pd["rank"]).tolist())
        assert ranks == {0, 1}


@needs_mpi
def test_restart_with_frozen_domains_is_bit_identical(tmp_path):
    """Damage and frozen CPDI domains (``damage``, ``rf``, the reset ``r0``) survive a restart:
    1 rank to step 100 with a checkpoint at 50, continued from 50 on 2 ranks, same step 100."""
    a, b = tmp_path / "a", tmp_path / "b"
    over = ["--set", "materials.bar.damage={onset=1.02, fracture=1.5, freeze=0.3}",
            "--set", "metrics.stop_on_separation=false", "--set", "grid.patch_size=4"]
    proc = _cli(1, "run", "hanging_bar", "-o", str(a), *QUIET, *OFF, *over, "--set",
                "time.steps=100", "--set", "checkpoint.every_steps=50")
    assert proc.returncode == 0, proc.stderr
    p, _ = _particles(a / "checkpoint_00000100.h5")
    assert np.any(p["rf"] != 0) and p["damage"].max() >= 0.3  # domains did freeze
    proc = _cli(2, "restart", str(a / "checkpoint_00000050.h5"), "-o", str(b), *QUIET)
    assert proc.returncode == 0, proc.stderr
    _same(a / "checkpoint_00000100.h5", b / "checkpoint_00000100.h5")
