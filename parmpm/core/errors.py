"""User-facing error types.

Anything a user can cause (a bad scene, a bad file, a particle that outruns the ghost layer) is
raised as a ``ParmpmError`` subclass with a one-line message; the CLI prints it as
``parmpm: error: <message>`` and exits with code 2, without a traceback. Anything else is a bug.
"""


class ParmpmError(Exception):
    """Base class: a one-line, user-facing problem (exit code 2)."""


class SceneError(ParmpmError):
    """The scene (TOML file or --set override) is invalid."""


class SimulationError(ParmpmError):
    """The run cannot go on (particle left the grid, reach past the ghost layer, NaN, ...)."""


class RunInterrupted(ParmpmError):
    """SIGTERM/SIGINT stopped the run after writing a final checkpoint (exit code 130)."""
