"""Waiting for a launched run to reach its time loop, without racing it.

A signal before the loop stops a run at once (no checkpoint); after it, the run checkpoints. A
fixed sleep loses that race on a loaded machine with a cold numba cache, so tests that signal a
run wait for proof of steps instead: ``history.csv`` (one row per step with
``output.history.every_steps = 1``, flushed row by row) holding a few rows.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

#: the ``--set`` options that make a run write one history row per step
HISTORY_EVERY_STEP = ["--set", "output.history.every_steps=1"]


def wait_for_steps(proc: subprocess.Popen, history: Path, rows: int = 3,
                   limit: float = 300.0) -> None:
    """Return once ``history`` holds more than ``rows`` lines (header + steps); fail the test
    (killing ``proc``) if the run ends or ``limit`` seconds pass first (a hang, not a timing)."""
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline and proc.poll() is None:
        if history.exists() and len(history.read_text().splitlines()) > rows:
            return
        time.sleep(0.2)
    if proc.poll() is None:
        proc.kill()
    _, err = proc.communicate()
    pytest.fail(f"the run did not reach its time loop (exit {proc.returncode}): {err[-2000:]}")


def signal_during_set_up(out: Path, sig: int, busy: float, limit: float) -> tuple[int, str]:
    """Run ``parmpm run hanging_bar_1d -o out`` in a process whose set-up (``Simulation``'s
    constructor) is replaced by ``busy`` seconds of busy waiting, send ``sig`` once it has begun,
    and return (exit code, stderr); ``limit``: seconds to wait for the end (a hang, not a timing).
    """
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    proc = subprocess.Popen([sys.executable, "-c",
                             "import time, sys; from parmpm.cli.main import main\n"
                             "import parmpm.driver.simulation as s\n"
                             "def slow(self, *a, **k):\n"
                             "    print('setting up', flush=True); t = time.time()\n"
                             f"    while time.time() - t < {busy}: pass  # busy, as set-up is\n"
                             "s.Simulation.__init__ = slow\n"
                             "sys.exit(main(['run', 'hanging_bar_1d', '--quiet', '-o', sys.argv[1]]))",
                             str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            # the signal's default disposition, even under nohup (an ignored
                            # one survives exec, and parmpm keeps an ignored signal ignored)
                            preexec_fn=lambda: signal.signal(sig, signal.SIG_DFL))
    assert proc.stdout.readline().strip() == "setting up"
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=limit)
    return proc.returncode, err
