"""Make one rank fail in the middle of a run, through the real CLI (``parmpm.cli.main.main``).

    mpirun -n 2 python tests/mpi/mpi_fail_one_rank.py {user|bug} OUT_DIR

Rank 1 raises at its 5th step — a ``SimulationError`` ("user") or a ``RuntimeError`` ("bug") —
while rank 0 goes on into the next collective. The CLI must end both ranks promptly.
"""
import sys

from parmpm.step import stepper
from parmpm.cli.main import main
from parmpm.core.errors import SimulationError

kind, out = sys.argv[1], sys.argv[2]
original = stepper.Stepper.step
calls = {"n": 0}


def failing_step(self, dt, gravity, *rest):
    calls["n"] += 1
    if self.patches.rank == 1 and calls["n"] == 5:
        if kind == "user":
            raise SimulationError("injected failure on rank 1 only")
        raise RuntimeError("injected bug on rank 1 only")
    return original(self, dt, gravity, *rest)


stepper.Stepper.step = failing_step
sys.exit(main(["run", "hanging_bar", "--quiet", "--out", out, "--set", "time.steps=50"]))
