"""How this process was started, and its MPI world, for the command line.

MPI is optional: mpi4py may be missing, or installed from PyPI as a wheel that finds no MPI
library to load (``pip install parmpm`` without the ``mpich`` extra on a machine without MPI:
``from mpi4py import MPI`` raises ``RuntimeError: cannot load MPI library``). Then parmpm runs on
one rank — unless a launcher started several processes (its environment says how many), which
would each run the whole scene alone into the same folder: they stop instead, with one line on
how to get MPI. The launcher's environment also gives the rank before MPI starts, so argument
errors are printed once.
"""
from __future__ import annotations

import os
import time

from parmpm.core.errors import ParmpmError

#: how to get an MPI library mpi4py can load
MPI_HELP = ("pip install 'parmpm[mpich]' (MPICH's wheel, with its own mpirun), or build mpi4py "
            "against the system MPI: pip install --force-reinstall --no-binary mpi4py mpi4py")
#: seconds that ranks failing together get to reach the error handler before the job is aborted
AGREE_TIMEOUT_S = 5.0


def launcher_rank() -> int:
    """This process's rank as the MPI launcher announces it (0 when not launched by one)."""
    for var in ("PMI_RANK", "OMPI_COMM_WORLD_RANK", "PMIX_RANK", "MV2_COMM_WORLD_RANK",
                "SLURM_PROCID"):
        value = os.environ.get(var, "")
        if value.isdigit():
            return int(value)
    return 0


def launcher_size() -> int:
    """How many ranks the MPI launcher started (1 when not launched by one): MPICH's and Intel
    MPI's hydra, Open MPI, MVAPICH, Slurm's srun (not a batch script's own shell)."""
    for var in ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "MV2_COMM_WORLD_SIZE",
                "SLURM_STEP_NUM_TASKS"):
        value = os.environ.get(var, "")
        if value.isdigit():
            return int(value)
    return 1


def _one_line(message) -> str:
    return " ".join(part.strip() for part in str(message).splitlines() if part.strip())


def world():
    """(rank, size, comm) of MPI_COMM_WORLD; (0, 1, None) when there is no MPI to use (mpi4py
    missing, or unable to load an MPI library); a :class:`ParmpmError` when a launcher started
    several ranks all the same."""
    try:
        from mpi4py import MPI
    except (ImportError, RuntimeError) as exc:
        ranks = launcher_size()
        if ranks > 1:
            why = ("mpi4py is not installed" if isinstance(exc, ImportError)
                   else f"mpi4py cannot load an MPI library ({_one_line(exc)})")
            raise ParmpmError(f"started as {ranks} MPI ranks, but {why}; {MPI_HELP}") from None
        return 0, 1, None
    comm = MPI.COMM_WORLD
    return comm.Get_rank(), comm.Get_size(), comm


def all_ranks_here(comm, timeout: float = AGREE_TIMEOUT_S) -> bool:
    """True when every rank of ``comm`` reaches this call within ``timeout`` seconds.

    A non-blocking barrier, polled: ranks that fail together agree here; a rank that failed alone
    gets False, because the others are elsewhere (possibly blocked waiting for it).
    """
    if comm is None or comm.Get_size() == 1:
        return True
    request = comm.Ibarrier()
    deadline = time.monotonic() + timeout
    while not request.Test():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.005)
    return True
