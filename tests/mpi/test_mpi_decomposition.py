"""The decomposition package alone under ``mpirun -n 1..4`` (see ``mpi_decomposition_check.py``):
accumulate + fill over ranks equal the one-rank exchange bit for bit (the global sum on every copy
of every node), migrate delivers every record exactly once intact, and all ranks agree on the
patch set after updates and re-balancing."""
import subprocess
import sys
from pathlib import Path

import pytest
from mpi_launch import MPI_MARKS, mpirun

pytestmark = MPI_MARKS  # every test here launches mpirun


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_decomposition_checks_under_mpirun(n):
    script = Path(__file__).parent / "mpi_decomposition_check.py"
    proc = subprocess.run([mpirun(), "-n", str(n), sys.executable, str(script)],
                          capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip().endswith("OK")
