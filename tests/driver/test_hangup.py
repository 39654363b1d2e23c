"""SIGHUP — a closed terminal, a dropped ssh session — stops a run as SIGTERM and Ctrl-C do (issue
28, item 4): a checkpoint, ``summary.json`` (``"stopped": "interrupted"``), the line to continue
and exit 130; before the time loop, one line and exit 130. Tested with real signals to real
runs:

* a run whose controlling terminal (a pseudo-terminal) is closed: the kernel hangs the line up
  and sends SIGHUP; every later write to that terminal would fail with EIO, so the run points its
  dead terminal at /dev/null and ``--log-file`` gets the closing line;
* ``kill -HUP`` of one rank of an ``mpirun -n 2`` run: the ranks agree and stop together;
* during set-up: one line, at once;
* ``nohup`` (SIGHUP ignored when parmpm starts) keeps the run going.

Before: the hang-up was swallowed by the MPI library's own handler (the 1-rank run went on
writing to a dead terminal, for ever with ``time.end = 1e6``), or the run was killed without a
checkpoint.
"""
from __future__ import annotations

import fcntl
import os
import pty
import signal
import subprocess
import sys
import termios
import time
from pathlib import Path

import pytest
from run_waits import signal_during_set_up, wait_for_steps

REPO = Path(__file__).resolve().parents[2]
ENV = dict(os.environ, PYTHONPATH=str(REPO))
LONG = ["--set", "time.end=1e6", "--set", "output.history.every_steps=1",
        "--set", "output.figure=false"]
#: how long a stopped run may take to checkpoint and exit (a run that ignores the signal never does)
STOP_S = 120


def _summary(out: Path) -> dict:
    import json

    return json.loads((out / "summary.json").read_text())


def _assert_interrupted(out: Path, rc: int, ranks: int = 1) -> Path:
    assert rc == 130
    summary = _summary(out)
    assert summary["stopped"] == "interrupted" and summary["ranks"] == ranks
    checkpoint = Path(summary["checkpoint"])
    assert checkpoint.is_file() and checkpoint.parent == out
    return checkpoint


def _wait(proc: subprocess.Popen, limit: float = STOP_S) -> int:
    try:
        return proc.wait(timeout=limit)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        pytest.fail(f"the run did not stop within {limit} s of the hang-up")


def _hang_ups_delivered():
    """In the child: SIGHUP's default disposition, whatever the test process inherited (under
    ``nohup make test`` it is ignored, and an ignored disposition survives exec: parmpm would
    rightly keep running, as :func:`test_nohup_keeps_the_run_going` wants)."""
    signal.signal(signal.SIGHUP, signal.SIG_DFL)


def _set_controlling_terminal():  # in the child, a session leader: stdin becomes its terminal
    _hang_ups_delivered()
    fcntl.ioctl(0, termios.TIOCSCTTY, 0)


def test_closing_the_terminal_checkpoints_and_stops(tmp_path):
    out, log = tmp_path / "o", tmp_path / "run.log"
    master, slave = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "parmpm", "run", "hanging_bar_1d", "-o",
                             str(out), *LONG, "--log-file", str(log)],
                            stdin=slave, stdout=slave, stderr=slave, env=ENV,
                            start_new_session=True, preexec_fn=_set_controlling_terminal)
    os.close(slave)
    os.set_blocking(master, False)
    deadline = time.monotonic() + 300
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                os.read(master, 1 << 16)  # a terminal is read by someone (the progress bar)
            except BlockingIOError:
                pass
            if (out / "history.csv").exists() and \
                    len((out / "history.csv").read_text().splitlines()) > 3:
                break
            time.sleep(0.1)
        assert proc.poll() is None, "the run ended before its time loop"
    finally:
        os.close(master)  # the terminal closes: the kernel hangs up the line, SIGHUP
    checkpoint = _assert_interrupted(out, _wait(proc))
    assert f"continue with: parmpm restart {checkpoint}" in log.read_text()


def _rank_pids(out: Path) -> list[int]:
    """The Python processes of a run writing to ``out`` (not the launcher)."""
    pids = []
    for entry in Path("/proc").iterdir():
        try:
            argv = (entry / "cmdline").read_bytes().split(b"\0")
        except (OSError, ValueError):
            continue
        if str(out).encode() in argv and b"parmpm" in argv and b"-n" not in argv:
            pids.append(int(entry.name))
    return sorted(pids)


def test_a_hang_up_of_one_rank_stops_both_with_a_checkpoint(tmp_path, mpirun):
    out = tmp_path / "o"
    proc = subprocess.Popen([mpirun, "-n", "2", sys.executable, "-m", "parmpm", "run",
                             "hanging_bar_1d", "-o", str(out), "--quiet", *LONG],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV,
                            start_new_session=True, preexec_fn=_hang_ups_delivered)
    try:
        wait_for_steps(proc, out / "history.csv")
        ranks = _rank_pids(out)
        assert len(ranks) == 2, ranks
        os.kill(ranks[1], signal.SIGHUP)
        _, err = proc.communicate(timeout=STOP_S)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        pytest.fail(f"the run did not stop within {STOP_S} s of the hang-up")
    checkpoint = _assert_interrupted(out, proc.returncode, ranks=2)
    assert err.strip().splitlines()[-1] == \
        f"parmpm: interrupted at step {_summary(out)['steps']} (t = {_summary(out)['time']:.6g} " \
        f"s); continue with: parmpm restart {checkpoint}", err


def test_a_hang_up_during_set_up_is_one_line_and_exit_130(tmp_path):
    returncode, err = signal_during_set_up(tmp_path / "o", signal.SIGHUP, 60, STOP_S)
    assert returncode == 130 and err.strip() == "parmpm: interrupted", err


def test_nohup_keeps_the_run_going(tmp_path):
    """A SIGHUP ignored when parmpm starts (``nohup``) stays ignored; SIGTERM still stops it."""
    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "parmpm", "run", "hanging_bar_1d", "-o",
                             str(out), "--quiet", *LONG], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=ENV,
                            preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN))
    wait_for_steps(proc, out / "history.csv")
    proc.send_signal(signal.SIGHUP)
    rows = len((out / "history.csv").read_text().splitlines())
    wait_for_steps(proc, out / "history.csv", rows=rows + 20)  # still stepping
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=STOP_S)
    _assert_interrupted(out, proc.returncode)


def test_only_a_terminal_that_hung_up_is_silenced():
    from parmpm.driver.signals import hung_up

    master, slave = pty.openpty()
    r, w = os.pipe()
    try:
        assert not hung_up(slave) and not hung_up(w)  # a live terminal, a pipe
        os.close(master)
        master = None
        assert hung_up(slave)
    finally:
        for fd in (master, slave, r, w):
            if fd is not None:
                os.close(fd)
