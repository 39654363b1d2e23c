"""What the tests share: the ``mpirun`` fixture, the markers that select tests, and the MPI
environment every launch inherits.

* ``mpirun`` (session fixture): the path of the launcher (:func:`mpi_launch.mpirun` finds it:
  the venv's MPICH wheel, else PATH); a test asking for it is skipped where none exists and is
  marked ``mpi`` here, so ``-m "not mpi"`` leaves out every launch. Tests that launch from a
  helper or a module fixture carry ``needs_mpi`` / ``MPI_MARKS`` (:mod:`mpi_launch`) instead.
* ``slow``: the studies' smoke runs (``run_scripts/`` in ``--quick`` mode) and other long runs;
  ``-m "not slow and not mpi"`` is the fast inner loop.
* The shared harnesses live in ``tests/harness/`` (on the path through ``pyproject.toml``'s
  ``pythonpath``), the tests in one folder per layer of ``parmpm/``.

Every ``mpirun`` of the suite runs more ranks than the two cores of a CI machine hold beside the
other pytest worker, and an MPICH rank waiting for a message spins on its core: the rank it waits
for gets a share of a core only when the scheduler takes the spinning one off.
``MPIR_CVAR_CH4_PROGRESS_THROTTLE`` makes a rank that polled 4096 times without progress sleep
1 µs, so the ranks that have work get the cores (measured: the 43 rank cases on 4 ranks, 41 s
without, 21 s with; on 1 and 2 ranks the same). It changes when a rank waits, never what it
computes: results are the same bit for bit. Set here (not in the run's code: a cluster job has
a core per rank), inherited by every launch of the suite; a value set outside is kept.
"""
import collections
import os

import mpi_launch
import pytest

os.environ.setdefault("MPIR_CVAR_CH4_PROGRESS_THROTTLE", "1")


@pytest.fixture(scope="session")
def mpirun() -> str:
    path = mpi_launch.mpirun()
    if path is None:
        pytest.skip("no mpirun (install the 'mpich' extra)")
    return path


def pytest_collection_modifyitems(config, items):
    """Mark every test that asks for ``mpirun`` as ``mpi``; then order the files: those with
    ``slow`` tests first (a study, a cold compile, a pip install: tens of seconds each), most
    first, then those with ``mpi`` tests (a launch: seconds each), most first, then the rest;
    each file's tests keep their order. pytest-xdist (``--dist loadfile``) hands out whole files
    in this order: the long ones start first and the short ones fill the workers in at the end
    (collection order put the 1-4 rank launches, the longest file, in the middle of the run)."""
    for item in items:
        if "mpirun" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.mpi)
    slow, mpi = collections.Counter(), collections.Counter()
    for item in items:
        slow[item.path] += bool(item.get_closest_marker("slow"))
        mpi[item.path] += bool(item.get_closest_marker("mpi"))
    # stable: a file's tests keep their order
    items.sort(key=lambda item: (-slow[item.path], -mpi[item.path]))
