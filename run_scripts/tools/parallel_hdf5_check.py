"""The collective checkpoint path (every rank writes its rows into one file through h5py's MPI-IO
driver) run against a real parallel HDF5, end to end.

PyPI's h5py wheels are serial, so the main venv never takes this path; Debian's packages give an
h5py built against parallel HDF5 with OpenMPI. On Debian bookworm (as root)::

    apt-get install -y python3-h5py-mpi python3-mpi4py openmpi-bin python3-numpy
    /usr/bin/python3.11 -m venv --system-site-packages /tmp/pvenv
    printf 'numpy==1.24.2\\nh5py==3.7.0\\nmpi4py==3.1.4\\n' > /tmp/pcons.txt  # keep Debian's
    /tmp/pvenv/bin/pip install -c /tmp/pcons.txt 'numba<0.61' meshio tqdm pytest
    PYTHONPATH=$PWD NUMBA_CACHE_DIR=/tmp/pnumba /tmp/pvenv/bin/python \\
        run_scripts/tools/parallel_hdf5_check.py --reference-python .venv/bin/python

(no ``pip install`` of parmpm: ``PYTHONPATH`` leaves the checkout untouched; a separate
``NUMBA_CACHE_DIR`` keeps numba 0.60's cache apart from the main venv's). Debian's ``h5py``
loads its MPI build only under ``mpirun`` (``OMPI_COMM_WORLD_SIZE`` set) or with
``H5PY_ALWAYS_USE_MPI``; a one-rank run never takes the collective path anyway.

Run this script itself, not under mpirun: it launches ``mpirun`` (beside this Python, else on
PATH; OpenMPI gets ``--oversubscribe``, and ``--allow-run-as-root`` as root). It checks, on the
hanging bar (900 particles, 40 steps, a checkpoint every 20):

1. runs on 2 and 3 ranks write one file each (no parts folder, no virtual dataset: plain h5py
   sees one contiguous dataset per field) whose particles, sorted by ``gid``, equal bit for bit
   those of the 1-rank run of ``--reference-python`` (the one-writer path; the main venv's
   serial h5py, by default this Python), at both checkpoints; so does a 4-rank run where three
   ranks hold no particle (``grid.patch_size = 16``: one patch holds the bar);
2. restarts 1→3, 3→2, 2→1 from step 20 end with the same particles and ``summary.json``
   ``final`` as the run that never stopped (and 3→1 with ``--reference-python``, if another);
3. parmpm's reader opens each file and reads every field (every segment digest verified);
4. a file with one flipped bit in ``particles/x`` stops a 2-rank restart with one line;
5. a rank whose row writes fail (ENOSPC injected on rank 1) stops every rank with the same
   one line, leaves no checkpoint and no ``.tmp``, and nobody hangs.

Expected: ``all checks passed`` and exit 0 (1 and the failed check otherwise; 77 when this
Python has no parallel h5py or no mpirun). Runtime: about a minute (plus ~40 s of numba
compilation the first time). tests/io/test_parallel_hdf5.py runs it where it can.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # parmpm from this checkout, installed or not
SCENE = ["run", "hanging_bar", "-q", "--set", "time.steps=40", "--set", "checkpoint.every_steps=20",
         "--set", "checkpoint.keep=5", "--set", "output.snapshots=false",
         "--set", "output.figure=false"]
STEPS = (20, 40)
#: one rank's row writes fail: the collective path must still end on every rank with one line
INJECT = """
import errno, os, sys
import parmpm.driver.checkpoint_writer.collective as g
if os.environ.get("OMPI_COMM_WORLD_RANK", os.environ.get("PMI_RANK")) == "1":
    def _full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")
    g.block_digest = _full
from parmpm.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


def why_not(python: str = sys.executable) -> str | None:
    """Why the collective path cannot run here (None: it can): ``python``'s h5py must have an
    MPI build (Debian's split package loads it under mpirun only) and an mpirun must exist."""
    probe = ("import importlib.util, h5py; print(bool(h5py.get_config().mpi) or "
             "importlib.util.find_spec('h5py._debian_h5py_mpi') is not None)")
    try:
        out = subprocess.run([python, "-c", probe], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"cannot run {python}: {exc}"
    if out.returncode != 0:
        return f"{python} cannot import h5py"
    if out.stdout.strip() != "True":
        return f"{python}'s h5py is serial (h5py.get_config().mpi is False; PyPI's wheels are)"
    if launcher(python) is None:
        return "no mpirun"
    return None


def launcher(python: str = sys.executable) -> list[str] | None:
    """``mpirun`` (beside ``python``, else on PATH) with the flags OpenMPI needs here."""
    beside = Path(python).parent / "mpirun"
    exe = str(beside) if beside.exists() else shutil.which("mpirun")
    if exe is None:
        return None
    try:
        version = subprocess.run([exe, "--version"], capture_output=True, text=True,
                                 timeout=60).stdout
    except (OSError, subprocess.TimeoutExpired):
        return None
    cmd = [exe]
    if "Open MPI" in version or "OpenRTE" in version:
        cmd.append("--oversubscribe")
        if hasattr(os, "geteuid") and os.geteuid() == 0:
            cmd.append("--allow-run-as-root")
    return cmd


class Check:
    def __init__(self, python: str, work: Path, timeout: float):
        self.python, self.work, self.timeout = python, work, timeout
        self.mpirun = launcher(python)
        self.env = {**os.environ, "PYTHONPATH": os.pathsep.join(
            [str(ROOT)] + ([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else []))}

    def run(self, ranks: int | None, args: list[str], python: str | None = None,
            expect_ok: bool = True) -> subprocess.CompletedProcess:
        """``python -m parmpm args`` (on ``ranks`` ranks via mpirun; None: no mpirun)."""
        python = python or self.python
        env = self.env
        if python != self.python:  # another numba: never share its cache folder
            env = {k: v for k, v in env.items() if k != "NUMBA_CACHE_DIR"}
        cmd = [python, *(["-m", "parmpm"] if args[:1] != ["-c"] else []), *args]
        if ranks is not None:
            cmd = [*self.mpirun, "-n", str(ranks), *cmd]
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=self.timeout,
                             env=env, cwd=self.work)
        if expect_ok and out.returncode != 0:
            fail(f"{' '.join(cmd)} exited {out.returncode}:\n{out.stderr[-3000:]}")
        return out


def fail(message: str) -> None:
    print(f"FAILED: {message}", flush=True)
    sys.exit(1)


def ok(message: str) -> None:
    print(f"ok  {message}", flush=True)


def by_gid(path: Path) -> tuple[dict, dict]:
    """Every ``particles/<field>`` of ``path`` in gid order, read with plain h5py, and each
    dataset's (virtual, chunks); checks the reader verifies every segment."""
    import h5py

    from parmpm.io.checkpoint import FIELDS, CheckpointReader

    with h5py.File(path, "r") as f:
        g = f["particles"]
        kinds = {k: (g[k].is_virtual, g[k].chunks) for k in g}
        o = np.argsort(g["gid"][:], kind="stable")
        data = {k: g[k][:][o] for k in g}
    r = CheckpointReader(path)
    try:
        for k in FIELDS:
            if r.read(k).tobytes() != np.asarray(h5py_rows(path, k)).tobytes():
                fail(f"{path}: parmpm's reader and h5py disagree on particles/{k}")
    finally:
        r.close()
    return data, kinds


def h5py_rows(path: Path, name: str) -> np.ndarray:
    import h5py

    with h5py.File(path, "r") as f:
        return f[f"particles/{name}"][:]


def same(a: Path, b: Path) -> None:
    da, _ = by_gid(a)
    db, kinds = by_gid(b)
    diff = [k for k in da if k not in db or da[k].tobytes() != db[k].tobytes()]
    if diff:
        fail(f"{b} differs from {a} in {diff}")
    odd = [k for k, (virtual, chunks) in kinds.items() if virtual or chunks]
    if odd:
        fail(f"{b}: virtual or chunked datasets {odd} (one contiguous dataset per field expected)")


def final(run: Path) -> dict:
    return json.loads((run / "summary.json").read_text())["final"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reference-python", default=sys.executable,
                    help="interpreter of the 1-rank reference run (e.g. the main venv's, serial h5py)")
    ap.add_argument("--out", type=Path, default=None, help="work folder (default: a temporary one)")
    ap.add_argument("--timeout", type=float, default=300, help="seconds per launched run")
    args = ap.parse_args()
    reason = why_not(sys.executable)
    if reason is not None:
        print(f"skipped: {reason}")
        return 77
    work = args.out or Path(tempfile.mkdtemp(prefix="parallel_hdf5_"))
    work.mkdir(parents=True, exist_ok=True)
    c = Check(sys.executable, work, args.timeout)
    ckpt = "checkpoint_{:08d}.h5".format

    c.run(None, [*SCENE, "-o", "p1"], python=args.reference_python)
    for n in (2, 3):
        c.run(n, [*SCENE, "-o", f"p{n}"])
        for step in STEPS:
            path = work / f"p{n}" / ckpt(step)
            import h5py

            with h5py.File(path, "r") as f:
                if int(f.attrs["ranks"]) != n or int(f.attrs["part_files"]) != 1:
                    fail(f"{path}: ranks {f.attrs['ranks']}, part files {f.attrs['part_files']}")
            if any(work.glob(f"p{n}/*.parts")) or any(work.glob(f"p{n}/*.tmp")):
                fail(f"p{n}: a parts folder or a temporary file (collective path not taken?)")
            same(work / "p1" / ckpt(step), path)
        if final(work / f"p{n}") != final(work / "p1"):
            fail(f"p{n}/summary.json final differs from the 1-rank run's")
        ok(f"{n} ranks: one file per checkpoint, particles bit-identical to the 1-rank run")

    # one patch of 16x16 cells holds every particle: ranks 0, 1 and 3 write no rows
    coarse = [*SCENE, "--set", "grid.patch_size=16"]
    c.run(None, [*coarse, "-o", "e1"], python=args.reference_python)
    c.run(4, [*coarse, "-o", "e4"])
    for step in STEPS:
        same(work / "e1" / ckpt(step), work / "e4" / ckpt(step))
    ok("4 ranks, 3 of them without particles: bit-identical to the 1-rank run")

    for a, b in ((1, 3), (3, 2), (2, 1)):
        out = f"r{a}to{b}"
        c.run(b, ["restart", str(work / f"p{a}" / ckpt(STEPS[0])), "-q", "-o", out])
        same(work / "p1" / ckpt(STEPS[1]), work / out / ckpt(STEPS[1]))
        if final(work / out) != final(work / "p1"):
            fail(f"{out}/summary.json final differs from the run that never stopped")
        ok(f"restart {a}→{b} ranks: bit-identical to the run that never stopped")

    if args.reference_python != sys.executable:
        c.run(None, ["restart", str(work / "p3" / ckpt(STEPS[0])), "-q", "-o", "r3to1ref"],
              python=args.reference_python)
        same(work / "p1" / ckpt(STEPS[1]), work / "r3to1ref" / ckpt(STEPS[1]))
        ok("restart 3→1 with --reference-python (its h5py) reads the collective file: "
           "bit-identical")

    bad = work / "damaged.h5"
    shutil.copyfile(work / "p3" / ckpt(STEPS[0]), bad)
    import h5py

    with h5py.File(bad, "r") as f:
        at = f["particles/x"].id.get_offset() + 100
    with open(bad, "r+b") as fh:
        fh.seek(at)
        byte = fh.read(1)[0]
        fh.seek(at)
        fh.write(bytes([byte ^ 0x10]))
    out = c.run(2, ["restart", str(bad), "-q", "-o", "damaged_restart"], expect_ok=False)
    errors = [ln for ln in out.stderr.splitlines() if ln.startswith("parmpm: error:")]
    if out.returncode == 0 or "Traceback" in out.stderr or not errors or \
            "fail their digest" not in errors[0]:
        fail(f"a flipped bit: exit {out.returncode}, stderr:\n{out.stderr[-2000:]}")
    ok(f"a flipped bit stops a 2-rank restart: {errors[0]}")

    out = c.run(2, ["-c", INJECT, *SCENE, "-o", "full"], expect_ok=False)
    errors = [ln for ln in out.stderr.splitlines() if ln.startswith("parmpm: error:")]
    left = sorted(p.name for p in (work / "full").glob("checkpoint_*"))
    if out.returncode == 0 or "Traceback" in out.stderr or not errors or \
            "disk full" not in errors[0] or left:
        fail(f"a rank's failed writes: exit {out.returncode}, left {left}, stderr:\n"
             f"{out.stderr[-2000:]}")
    ok(f"one rank's failed writes stop every rank, nothing left: {errors[0]}")
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
