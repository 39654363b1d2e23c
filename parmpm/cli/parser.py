"""The ``parmpm`` command line's grammar: the commands, their options and help texts.

Light on purpose: building the parser imports no solver module, so ``parmpm --help`` and a
mistyped option answer at once (the docs build the CLI reference from :func:`build_parser`).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from parmpm.cli.launch import launcher_rank as _launcher_rank
from parmpm.core.errors import ParmpmError
from parmpm.shapes import interpolator_names

DEFAULT_SCENE = "hanging_bar"
DEFAULT_OUT = Path("parmpm-out")

_EPILOG = """\
examples:
  mpirun -n 2 python -m parmpm                       the default scene (2D hanging bar, cpdi, l_cr = 2dx)
  python -m parmpm scenes                            list the built-in scenes
  mpirun -n 4 python -m parmpm run hanging_bar --set method.interpolator=mpm --set time.end=0.1
  python -m parmpm run path/to/scene.toml --out results/
  python -m parmpm show hanging_bar > my.toml        the resolved scene, a file to edit and run
  python -m parmpm compile --dim 2 3                 fill numba's cache (all cases: ~1 min, once)

Without a command, parmpm runs the built-in scene 'hanging_bar'.
"""

_RUN_EPILOG = """\
--set takes a dotted scene key and a TOML value (a bare word is read as a string), e.g.
  --set method.interpolator=ugimp    --set method.lcr=1.5dx     --set grid.cells=[40,60]
  --set time.end=0.1                 --set bodies.0.ppc=3       --set gravity.g=[0,-9.81]
The scene keys are listed in the documentation's scene reference.
"""


def _version() -> str:
    try:
        from importlib.metadata import PackageNotFoundError, version
    except ImportError:  # pragma: no cover
        return "unknown"
    try:
        return version("parmpm")
    except PackageNotFoundError:
        return "unknown (not installed)"


class _Parser(argparse.ArgumentParser):
    """argparse that prints (usage, errors, help) on rank 0 only: under ``mpirun -n 4`` a
    mistyped option is reported once; every rank still exits with code 2."""

    def _print_message(self, message, file=None):
        if _launcher_rank() == 0:
            super()._print_message(message, file)




def build_parser() -> argparse.ArgumentParser:
    """The whole command line: one sub-parser per command."""
    parser = _Parser(
        prog="parmpm",
        description=f"MPI-parallel explicit Material Point Method solver ({interpolator_names()} "
        "with CPDI domain scaling). Run it under mpirun for several ranks.",
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    commands = parser.add_subparsers(dest="command", title="commands", metavar="COMMAND")
    _add_run(commands)
    _add_restart(commands)
    _add_show(commands)
    commands.add_parser("scenes", help="list the built-in scenes",
                        description="List the built-in scenes: name and one-line description.")
    _add_tools(commands)
    return parser


def _add_run(commands) -> None:
    run = commands.add_parser(
        "run",
        help="run a scene (the default command)",
        description="Run a scene on all MPI ranks; write snapshots, figures and summary.json to the "
        "output folder and print a summary.",
        epilog=_RUN_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    run.add_argument("scene", metavar="SCENE", nargs="?", default=DEFAULT_SCENE,
                     help="a built-in scene name (see 'parmpm scenes') or the path to a TOML scene "
                     f"file (default: {DEFAULT_SCENE})")
    run.add_argument("-s", "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                     help="override a scene value (repeatable; applied after the scene file)")
    run.add_argument("-o", "--out", type=_out_folder, default=None, metavar="DIR",
                     help=f"output folder (default: {DEFAULT_OUT}/<scene name>/)")
    run.add_argument("-q", "--quiet", action="store_true",
                     help="no progress bar, no info messages (warnings and errors still show)")
    run.add_argument("--overwrite", action="store_true",
                     help="if the --out folder holds another run, delete that run's results and "
                     "write there; if it holds files parmpm did not write, write among them "
                     "(without it such a folder is refused; a file the run reads never goes)")
    _logging_arguments(run)


def _add_restart(commands) -> None:
    restart = commands.add_parser(
        "restart", help="continue a run from a checkpoint (any number of ranks)",
        description="Continue the run saved in CHECKPOINT (checkpoint_<step>.h5) bit for bit, on "
        "any number of ranks. --set changes the stored scene (e.g. time.end=0.5).",
        epilog=_RUN_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    restart.add_argument("checkpoint", metavar="CHECKPOINT", type=Path,
                         help="a checkpoint_<step>.h5 written by a run")
    restart.add_argument("-s", "--set", dest="overrides", action="append", default=[],
                         metavar="KEY=VALUE", help="override a value of the stored scene (repeatable)")
    restart.add_argument("-o", "--out", type=_out_folder, default=None, metavar="DIR",
                         help="output folder (default: restart_<step>/ beside the checkpoint)")
    restart.add_argument("-q", "--quiet", action="store_true",
                         help="no progress bar, no info messages (warnings and errors still show)")
    restart.add_argument("--overwrite", action="store_true",
                         help="if the --out folder holds another run, delete that run's results "
                         "(or files parmpm did not write: write among them)")
    _logging_arguments(restart)


def _add_show(commands) -> None:
    show = commands.add_parser(
        "show", help="print a scene, resolved, as TOML (a scene file to start from)",
        description="Print the scene with every default filled in and the --set overrides "
        "applied, as TOML: 'parmpm show hanging_bar > my.toml; parmpm run my.toml' runs the "
        "same scene.", epilog=_RUN_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    show.add_argument("scene", metavar="SCENE", nargs="?", default=DEFAULT_SCENE,
                      help=f"a built-in scene name or a TOML scene file (default: {DEFAULT_SCENE})")
    show.add_argument("-s", "--set", dest="overrides", action="append", default=[],
                      metavar="KEY=VALUE", help="override a scene value (repeatable)")


def _add_tools(commands) -> None:
    """``bench`` and ``compile``: their options live beside their code."""
    bench = commands.add_parser(
        "bench", help="time steps of a synthetic block (time per step, phases, halo share)",
        description="Benchmark the time-step loop on a translating neo-Hookean block of about "
        "--particles particles; print time per step and its phases (rank 0). Run under mpirun "
        "for several ranks; run_scripts/benchmarks/scaling.py compares rank counts.")
    from parmpm.cli.bench import add_arguments  # light: the solver is imported only when it runs
    add_arguments(bench)

    compile_ = commands.add_parser(
        "compile", help="compile the kernels into numba's cache (before a batch job's runs)",
        description="Run a tiny scene of each dimension, interpolator and update (USL, MUSL) "
        "for two steps, so that numba's cache holds every kernel a run uses and later runs "
        "start at once. The cache is the __pycache__ beside the installed sources, or "
        "NUMBA_CACHE_DIR (set it on a shared filesystem when the install is read-only).")
    from parmpm.cli.compile import add_arguments as add_compile_arguments
    add_compile_arguments(compile_)


def _out_folder(text: str):
    """``--out``: a Path; an empty one stays "" so that the run refuses it (it would otherwise
    mean the current folder, written into without a word)."""
    return Path(text) if text else ""


def check_out(args: argparse.Namespace) -> None:
    if getattr(args, "out", None) == "":
        raise ParmpmError("--out is empty: name the output folder (e.g. --out results; "
                          "'--out .' is the current folder)")


def _logging_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="debug messages (rank 0): set-up details, every kernel compiled")
    parser.add_argument("--log-file", type=str, default=None, metavar="PATH",
                        help="also write rank 0's messages (info, or debug with -v, even with "
                        "--quiet), the progress lines and the closing error to PATH (appended)")



def default_command(argv: list[str]) -> list[str]:
    """``run`` is the default command: ``parmpm``, ``parmpm --quiet`` and ``parmpm --set k=v``
    mean ``parmpm run hanging_bar ...`` (the top-level --help and --version stay)."""
    if not argv or (argv[0].startswith("-") and argv[0] not in ("-h", "--help", "--version")):
        return ["run", *argv]
    return argv

