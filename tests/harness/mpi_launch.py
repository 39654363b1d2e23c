"""Launching ``mpirun`` from the tests (one definition for every test file).

``mpirun()`` is the launcher beside this Python (the venv's MPICH wheel), else the one on PATH,
else None. ``needs_mpi`` marks a test that launches it: marker ``mpi`` (so ``-m "not mpi"``
leaves it out) and a skip where no launcher exists.
"""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest


def mpirun() -> str | None:
    beside = Path(sys.executable).parent / "mpirun"
    return str(beside) if beside.exists() else shutil.which("mpirun")


def needs_mpi(test):
    """Decorator (or ``pytestmark``-style mark list via :data:`MPI_MARKS`) for a test that
    launches mpirun."""
    for mark in MPI_MARKS:
        test = mark(test)
    return test


MPI_MARKS = [pytest.mark.mpi,
             pytest.mark.skipif(mpirun() is None, reason="no mpirun (install the 'mpich' extra)")]
