"""Progress and logging of a run: an honest ETA, plain lines in a batch log, -v and --log-file.

* the first step pays for compiling the kernels: the remaining time is estimated from the steps
  after it only, and shown as "--" until there are some;
* stderr not a terminal: a log line every ``interval`` seconds (step, t, % done,
  particle-steps/s, ETA), no ``\\r`` redraws;
* ``setup_logging(verbose=...)``: DEBUG on rank 0; ``log_file``: rank 0's records (INFO, DEBUG with
  verbose, also under quiet), the progress lines, a file that cannot be opened is one line.
"""
from __future__ import annotations

import io
import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest

import parmpm.driver.progress as progress
from parmpm.core.errors import ParmpmError
from parmpm.core.log import get_logger, setup_logging
from parmpm.driver.progress import Progress

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def restore_logging():
    logger = logging.getLogger("parmpm")
    saved = logger.handlers[:], logger.level, logger.propagate
    yield
    for handler in logger.handlers:
        if handler not in saved[0]:
            handler.close()
    logger.handlers[:], logger.level, logger.propagate = saved


@pytest.fixture
def clock(monkeypatch):
    """A wall clock the test moves by hand (``clock.now``)."""
    class Clock:
        now = 0.0

    monkeypatch.setattr(progress._time, "monotonic", lambda: Clock.now)
    return Clock


def test_eta_leaves_out_the_first_step(clock):
    bar = Progress(total_steps=101, interactive=False, interval=1e9)
    clock.now = 20.0  # the first step compiled the kernels for 20 s
    bar.update(1, 0.01, 0.0)
    assert bar.eta(1, 0.01) is None and "ETA --" in bar.line(1, 0.01, 0.0)
    for step in range(2, 12):  # then 0.1 s per step
        clock.now += 0.1
        bar.update(step, 0.01 * step, 1e6)
    assert bar.eta(11, 0.11) == pytest.approx(90 * 0.1)  # not 90 * (21 / 11) s
    assert "ETA 00:09" in bar.line(11, 0.11, 1e6)
    bar.close()


def test_eta_by_simulated_time(clock):
    bar = Progress(end_time=1.0, interactive=False, interval=1e9)
    clock.now = 30.0
    bar.update(1, 0.1, 0.0)
    clock.now = 31.0
    bar.update(2, 0.3, 1e6)  # 0.2 s of simulated time per wall second, 0.7 s to go
    assert bar.eta(2, 0.3) == pytest.approx(0.7 / 0.2)
    bar.close()


@pytest.mark.parametrize("kwargs, expected", [
    ({"end_time": 1.0}, ["step 5", "t = 0.5 s of 1 (50 %)", "2.50M particle-steps/s", "ETA "]),
    ({"total_steps": 10}, ["step 5 of 10", "t = 0.5 s (50 %)", "2.50M particle-steps/s", "ETA "]),
    ({}, ["step 5", "t = 0.5 s", "2.50M particle-steps/s", "ETA --"]),
])
def test_a_batch_log_gets_plain_lines(restore_logging, capsys, clock, kwargs, expected):
    stream = io.StringIO()
    setup_logging(0, 1, stream=stream)
    bar = Progress(**kwargs, interactive=False, interval=10.0)
    for step in range(1, 11):
        clock.now += 3.0  # a line every 10 s: after steps 4 and 7, and one at the end
        bar.update(step, 0.1 * step, 2.5e6)
        if step == 5:
            fifth = bar.line(5, 0.5, 2.5e6)
    bar.close()
    lines = stream.getvalue().splitlines()
    assert len(lines) == 3 and all("INFO parmpm.driver.progress: step " in line for line in lines)
    for fragment in expected:
        assert fragment in fifth, fifth
    assert capsys.readouterr().err == ""  # nothing but the log's own lines, no \r redraws


def test_quiet_and_other_ranks_write_no_progress(restore_logging, capsys, clock):
    stream = io.StringIO()
    setup_logging(0, 1, stream=stream)
    bar = Progress(total_steps=3, enabled=False, interactive=False, interval=0.0)
    for step in range(1, 4):
        bar.update(step, 0.1 * step, 1e6)
    bar.close()
    assert stream.getvalue() == "" and capsys.readouterr() == ("", "")


def test_records_are_written_above_a_bar_and_the_file_gets_its_lines(restore_logging, tmp_path,
                                                                    capsys, clock):
    log_file = tmp_path / "run.log"
    setup_logging(0, 1, log_file=log_file)
    bar = Progress(total_steps=4, interactive=True, interval=0.0)
    for step in range(1, 5):
        clock.now += 1.0
        bar.update(step, 0.1 * step, 1e6)
        get_logger("parmpm.test").info("a record at step %d", step)
    bar.close()
    err = capsys.readouterr().err
    assert "a record at step 2" in err and "4/4" in err
    text = log_file.read_text()
    assert "INFO parmpm.test: a record at step 4" in text
    assert text.count("parmpm.driver.progress: step ") == 5  # one per update (interval 0) and the end


@pytest.mark.parametrize("rank, verbose, quiet, console, in_file", [
    (0, True, False, ["debug", "info", "warning"], ["debug", "info", "warning"]),
    (0, False, True, ["warning"], ["info", "warning"]),
    (0, False, False, ["info", "warning"], ["info", "warning"]),
    (1, True, False, ["warning"], None),
])
def test_verbose_and_log_file_levels(restore_logging, tmp_path, rank, verbose, quiet, console,
                                     in_file):
    stream, log_file = io.StringIO(), tmp_path / "run.log"
    setup_logging(rank, 2, quiet=quiet, stream=stream, verbose=verbose, log_file=log_file)
    logger = get_logger("parmpm.test_progress")
    for level in ("debug", "info", "warning"):
        getattr(logger, level)(level)
    logging.getLogger("parmpm").handlers[-1].flush()
    assert [line.rsplit(": ", 1)[1] for line in stream.getvalue().splitlines()] == console
    if in_file is None:
        assert not log_file.exists()  # rank 0's file only
    else:
        lines = log_file.read_text().splitlines()
        assert [line.rsplit(": ", 1)[1] for line in lines] == in_file
        assert all(line.startswith(f"[{rank}/2] 20") for line in lines)  # dated


def test_a_log_file_that_cannot_be_opened_is_one_line(restore_logging, tmp_path):
    with pytest.raises(ParmpmError, match="cannot write log file '.*missing/run.log'"):
        setup_logging(0, 1, log_file=tmp_path / "missing" / "run.log")


def test_cli_log_file(tmp_path):
    """``--log-file`` from the command line: the run's records and, when it fails, its error
    line; an unwritable path is a one-line error before anything runs."""
    env = dict(os.environ, PYTHONPATH=str(REPO))

    def run(*args):
        return subprocess.run([sys.executable, "-m", "parmpm", "run", "hanging_bar_1d", *args],
                              cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)

    proc = run("--set", "time.steps=3", "--set", "output.figure=false", "-o", "a", "--quiet",
               "--log-file", "run.log", "-v")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    text = (tmp_path / "run.log").read_text()
    assert "DEBUG parmpm: parmpm " in text and "run hanging_bar_1d" in text
    proc = run("--set", "time.steps=3", "-o", "a", "--log-file", "run.log")  # a taken folder
    assert proc.returncode == 2
    assert (tmp_path / "run.log").read_text().splitlines()[-1].endswith(
        "ERROR parmpm.cli.main: " + proc.stderr.strip())
    proc = run("--log-file", str(tmp_path / "no" / "such" / "run.log"), "-o", "b")
    assert proc.returncode == 2 and proc.stderr.startswith("parmpm: error: cannot write log file")
    assert len(proc.stderr.strip().splitlines()) == 1 and not (tmp_path / "b").exists()
