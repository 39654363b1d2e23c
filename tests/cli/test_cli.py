"""The command line (``python -m parmpm``) and its helpers (rank-aware logging, progress bar).

The command as a user runs it: exit codes, help text, the one-line error contract
(``parmpm: error: <message>``, exit 2, no traceback), and the same contract under ``mpirun -n 2``
(printed once, not once per rank). One-rank commands run inside the test process
(:mod:`cli_harness`; ``PARMPM_TEST_CLI=subprocess`` runs them as subprocesses), launches under
``mpirun`` as subprocesses. A few in-process tests check the error paths of ``main``
(KeyboardInterrupt, a bug) with the scene loader replaced, without starting MPI.
"""

from __future__ import annotations

import io
import json
import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest
from cli_harness import parmpm_cli

import parmpm.cli.main as cli
from parmpm.core.errors import SceneError

REPO = Path(__file__).resolve().parents[2]
TIMEOUT_S = 120


def parmpm(*args: str, cwd: Path, timeout: float = TIMEOUT_S) -> subprocess.CompletedProcess:
    """``python -m parmpm ARGS`` in ``cwd``, one rank (in this process: :mod:`cli_harness`)."""
    return parmpm_cli(*args, cwd=cwd, timeout=timeout)


def assert_one_line_error(proc: subprocess.CompletedProcess, *fragments: str) -> None:
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("parmpm: error: "), proc.stderr
    assert "Traceback" not in proc.stderr
    for fragment in fragments:
        assert fragment in lines[0]


# ---------------------------------------------------------------- help, version, scenes


def test_help(tmp_path):
    proc = parmpm("--help", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    for word in ("usage: parmpm", "run", "scenes", "--version", "mpirun -n 2 python -m parmpm"):
        assert word in proc.stdout


def test_run_help(tmp_path):
    proc = parmpm("run", "--help", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    for word in ("usage: parmpm run", "SCENE", "--set", "KEY=VALUE", "--out", "--quiet"):
        assert word in proc.stdout


def test_run_and_restart_help_name_logging_options(tmp_path):
    for command in ("run", "restart"):
        proc = parmpm(command, "--help", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
        for word in ("-v, --verbose", "--log-file PATH"):
            assert word in proc.stdout, (command, proc.stdout)


def test_help_does_not_import_numba_or_mpi(tmp_path):
    """``parmpm --help`` builds every command's options, the benchmark's too: without numba
    (about a second) and without starting MPI."""
    code = ("import sys; from parmpm.cli.parser import build_parser; build_parser()\n"
            "print(sorted(m for m in ('numba', 'mpi4py') if m in sys.modules))")
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=TIMEOUT_S)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"


def test_version(tmp_path):
    proc = parmpm("--version", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("parmpm ")


def test_scenes_lists_builtins(tmp_path):
    proc = parmpm("scenes", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    names = {line.split()[0] for line in proc.stdout.splitlines() if line.strip()}
    assert {"hanging_bar", "vibrating_bar"} <= names
    for line in proc.stdout.splitlines():  # every scene has a description after its name
        assert len(line.split(maxsplit=1)) == 2, line


def test_unknown_command_is_a_usage_error(tmp_path):
    proc = parmpm("frobnicate", cwd=tmp_path)
    assert proc.returncode == 2
    assert "usage: parmpm" in proc.stderr and "Traceback" not in proc.stderr


# ---------------------------------------------------------------- user errors: one line, exit 2


def test_bad_scene_path(tmp_path):
    missing = tmp_path / "no_such_scene.toml"
    assert_one_line_error(parmpm("run", str(missing), cwd=tmp_path), "no_such_scene.toml")


def test_unknown_builtin_scene(tmp_path):
    assert_one_line_error(parmpm("run", "no_such_builtin", cwd=tmp_path), "no_such_builtin")


def test_broken_toml(tmp_path):
    scene = tmp_path / "broken.toml"
    scene.write_text("dim = 2\n[grid\ncells = [1, 2]\n")
    assert_one_line_error(parmpm("run", str(scene), cwd=tmp_path), "broken.toml")


@pytest.mark.parametrize("override, fragment", [
    ("no_equals_sign", "no_equals_sign"),
    ("nosuch.key=1", "nosuch"),
    ("method.interpolator=warp_drive", "warp_drive"),
    ("time.cfl=-1", "cfl"),
])
def test_bad_set(tmp_path, override, fragment):
    proc = parmpm("run", "hanging_bar", "--set", override, "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert_one_line_error(proc, fragment)
    assert not (tmp_path / "out").exists()  # rejected before the run starts


def test_bad_scene_under_mpirun_prints_once(tmp_path, mpirun):
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.run([mpirun, "-n", "2", sys.executable, "-m", "parmpm", "run", "missing.toml"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
    assert_one_line_error(proc, "missing.toml")


# ---------------------------------------------------------------- MPI that cannot be loaded


@pytest.fixture
def mpi4py_without_mpi(tmp_path):
    """An mpi4py whose ``MPI`` module fails as PyPI's mpi4py does on a machine without an MPI
    library (``RuntimeError: cannot load MPI library``), first on the path."""
    fake = tmp_path / "fake" / "mpi4py"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("")
    (fake / "MPI.py").write_text('raise RuntimeError("cannot load MPI library\\n'
                                 'libmpi.so.12: cannot open shared object file")\n')
    return tmp_path / "fake"


def _run_without_mpi(tmp_path, fake, **launcher):
    env = {k: v for k, v in os.environ.items()
           if k not in ("PMI_SIZE", "PMI_RANK", "OMPI_COMM_WORLD_SIZE", "SLURM_STEP_NUM_TASKS")}
    env.update(launcher, PYTHONPATH=os.pathsep.join([str(fake), str(REPO)]))
    return subprocess.run([sys.executable, "-m", "parmpm", "run", "hanging_bar_1d", "--quiet",
                           "--set", "time.steps=2", "--set", "output.figure=false",
                           "-o", str(tmp_path / "out")],
                          cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=TIMEOUT_S)


def test_an_mpi4py_without_mpi_library_runs_on_one_rank(tmp_path, mpi4py_without_mpi):
    """``pip install parmpm`` without the mpich extra, no MPI on the machine: before, the
    RuntimeError of ``from mpi4py import MPI`` was a 30-line traceback."""
    proc = _run_without_mpi(tmp_path, mpi4py_without_mpi)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["ranks"] == 1


@pytest.mark.parametrize("launcher", [{"PMI_SIZE": "2", "PMI_RANK": "0"},
                                      {"OMPI_COMM_WORLD_SIZE": "4"},
                                      {"SLURM_STEP_NUM_TASKS": "3"}])
def test_several_ranks_without_mpi_library_say_how_to_get_mpi(tmp_path, mpi4py_without_mpi,
                                                              launcher):
    proc = _run_without_mpi(tmp_path, mpi4py_without_mpi, **launcher)
    assert_one_line_error(proc, "MPI ranks", "cannot load MPI library", "parmpm[mpich]",
                          "--no-binary mpi4py")
    assert not (tmp_path / "out").exists()


def test_several_ranks_without_mpi_other_ranks_stay_silent(tmp_path, mpi4py_without_mpi):
    proc = _run_without_mpi(tmp_path, mpi4py_without_mpi, PMI_SIZE="2", PMI_RANK="1")
    assert proc.returncode == 2 and proc.stderr == ""


def test_no_folder_for_numbas_cache_is_one_line(tmp_path):
    """A read-only install and no writable ~/.cache: numba finds no folder to cache the kernels
    in (here: only the zip-file locator allowed) and raised a traceback at import."""
    env = dict(os.environ, PYTHONPATH=str(REPO), NUMBA_CACHE_LOCATOR_CLASSES="ZipCacheLocator")
    env.pop("NUMBA_CACHE_DIR", None)
    proc = subprocess.run([sys.executable, "-m", "parmpm", "run", "hanging_bar_1d", "-o", "out"],
                          cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=TIMEOUT_S)
    assert_one_line_error(proc, "numba cannot cache the kernels", "NUMBA_CACHE_DIR")
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- error paths of main(), in process


@pytest.fixture
def restore_logging():
    """Undo setup_logging() afterwards, so that other tests see the default logger again."""
    logger = logging.getLogger("parmpm")
    saved = logger.handlers[:], logger.level, logger.propagate
    yield
    logger.handlers[:], logger.level, logger.propagate = saved


@pytest.fixture
def serial(monkeypatch, restore_logging):
    """main() as a single rank without importing mpi4py."""
    monkeypatch.setattr(cli, "_world", lambda: (0, 1, None))


def _raise(exc):
    def loader(*args, **kwargs):
        raise exc
    return loader


def test_main_scene_error_returns_2(serial, monkeypatch, capsys):
    monkeypatch.setattr("parmpm.scene.load.load_scene", _raise(SceneError("bad\nscene")))
    assert cli.main(["run", "x"]) == 2
    assert capsys.readouterr().err == "parmpm: error: bad scene\n"


def test_main_default_command_is_run_hanging_bar(serial, monkeypatch, capsys):
    seen = {}

    def loader(source, overrides=()):
        seen.update(source=source, overrides=list(overrides))
        raise SceneError("stop here")

    monkeypatch.setattr("parmpm.scene.load.load_scene", loader)
    assert cli.main([]) == 2
    assert seen == {"source": "hanging_bar", "overrides": []}


def test_main_passes_overrides_in_order(serial, monkeypatch):
    seen = {}

    def loader(source, overrides=()):
        seen.update(source=source, overrides=list(overrides))
        raise SceneError("stop here")

    monkeypatch.setattr("parmpm.scene.load.load_scene", loader)
    cli.main(["run", "vibrating_bar", "--set", "a.b=1", "-s", "a.b=2"])
    assert seen == {"source": "vibrating_bar", "overrides": ["a.b=1", "a.b=2"]}


def test_main_keyboard_interrupt_returns_130(serial, monkeypatch, capsys):
    monkeypatch.setattr("parmpm.scene.load.load_scene", _raise(KeyboardInterrupt()))
    assert cli.main(["run", "x"]) == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_main_bug_prints_traceback_returns_1(serial, monkeypatch, capsys):
    monkeypatch.setattr("parmpm.scene.load.load_scene", _raise(ZeroDivisionError("a bug")))
    assert cli.main(["run", "x"]) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and "ZeroDivisionError: a bug" in err


# ---------------------------------------------------------------- logging and progress


@pytest.mark.parametrize("rank, size, quiet, shown", [
    (0, 1, False, ["info", "warning"]),
    (0, 1, True, ["warning"]),
    (1, 4, False, ["warning"]),
])
def test_logging_levels_by_rank(restore_logging, rank, size, quiet, shown):
    from parmpm.core.log import get_logger, setup_logging

    stream = io.StringIO()
    setup_logging(rank, size, quiet=quiet, stream=stream)
    setup_logging(rank, size, quiet=quiet, stream=stream)  # a repeat call does not double the output
    logger = get_logger("parmpm.test_cli")
    logger.info("info")
    logger.warning("warning")
    lines = stream.getvalue().splitlines()
    assert [line.rsplit(": ", 1)[1] for line in lines] == shown
    assert all(line.startswith(f"[{rank}/{size}] ") == (size > 1) for line in lines)


def test_get_logger_places_foreign_names_under_parmpm():
    from parmpm.core.log import get_logger

    assert get_logger("parmpm.step.stepper").name == "parmpm.step.stepper"
    assert get_logger("__main__").name == "parmpm.__main__"


def test_progress_disabled_writes_nothing(capsys):
    from parmpm.driver.progress import Progress

    with Progress(total_steps=10, end_time=1.0, enabled=False) as bar:
        for step in range(1, 11):
            bar.update(step, 0.1 * step, 1e6)
    assert capsys.readouterr() == ("", "")


@pytest.mark.parametrize("kwargs, expected", [
    ({"end_time": 1.0}, "t=1/1"),
    ({"total_steps": 10}, "10/10"),
    ({}, "10step"),
])
def test_progress_shows_steps_time_and_rate(capsys, kwargs, expected):
    from parmpm.driver.progress import Progress

    bar = Progress(**kwargs, interactive=True)  # a terminal's bar (capsys is none)
    for step in range(1, 11):
        bar.update(step, 0.1 * step, 2.5e6)
    bar.close()
    out, err = capsys.readouterr()
    assert out == ""
    final = err.replace("\r", "\n").strip().splitlines()[-1]
    assert expected in final and "2.50M particle-steps/s" in final
    assert ("step 10" in final) if "end_time" in kwargs else ("t=1" in final)
