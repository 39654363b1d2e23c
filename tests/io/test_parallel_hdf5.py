"""The collective checkpoint path against a real parallel HDF5, end to end: where the h5py of the
Python running the tests is built with MPI (a site's build, or Debian's ``python3-h5py-mpi``)
and an mpirun exists, run ``run_scripts/tools/parallel_hdf5_check.py`` (runs on 2 and 3 ranks
bit-identical to one rank, restarts 1→3, 3→2, 2→1, plain-h5py layout, digests, a flipped bit
and one rank's failed writes each one line). PyPI's h5py wheels are serial: there (CI) the test
skips at once, without launching anything. The check script's docstring says how to set up
Debian's packages."""
from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "run_scripts" / "tools" / "parallel_hdf5_check.py"


def _h5py_mpi() -> str | None:
    """Why this Python's h5py cannot write through MPI-IO (None: it can), without MPI."""
    try:
        import h5py
    except ImportError:
        return "no h5py"
    if h5py.get_config().mpi:
        return None
    try:  # Debian's split h5py loads its MPI build only under mpirun
        if importlib.util.find_spec("h5py._debian_h5py_mpi") is not None:
            return None
    except (ImportError, ValueError):
        pass
    return "h5py is serial (h5py.get_config().mpi is False; PyPI's wheels are)"


def _why_not() -> str | None:
    reason = _h5py_mpi()
    if reason is not None:
        return reason
    spec = importlib.util.spec_from_file_location("parallel_hdf5_check", SCRIPT)
    check = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(check)
    return check.why_not(sys.executable)


WHY_NOT = _why_not()


@pytest.mark.mpi
@pytest.mark.slow
@pytest.mark.skipif(WHY_NOT is not None, reason=f"collective checkpoint path: {WHY_NOT}")
def test_collective_checkpoints_end_to_end(tmp_path):
    out = subprocess.run([sys.executable, str(SCRIPT), "--out", str(tmp_path), "--timeout", "600"],
                         capture_output=True, text=True, timeout=1800, cwd=ROOT)
    assert out.returncode == 0 and "all checks passed" in out.stdout, \
        f"exit {out.returncode}\n{out.stdout[-4000:]}\n{out.stderr[-4000:]}"
