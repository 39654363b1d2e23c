"""What the tests share: the ``mpirun`` fixture and the markers that select tests.

* ``mpirun`` (session fixture): the path of the launcher (:func:`mpi_launch.mpirun` finds it:
  the venv's MPICH wheel, else PATH); a test asking for it is skipped where none exists and is
  marked ``mpi`` here, so ``-m "not mpi"`` leaves out every launch. Tests that launch from a
  helper or a module fixture carry ``needs_mpi`` / ``MPI_MARKS`` (:mod:`mpi_launch`) instead.
* ``slow``: the studies' smoke runs (``run_scripts/`` in ``--quick`` mode) and other long runs;
  ``-m "not slow"`` is the fast loop.
"""
import mpi_launch
import pytest


@pytest.fixture(scope="session")
def mpirun() -> str:
    path = mpi_launch.mpirun()
    if path is None:
        pytest.skip("no mpirun (install the 'mpich' extra)")
    return path


def pytest_collection_modifyitems(config, items):
    for item in items:
        if "mpirun" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.mpi)
