"""The signals that stop a run, and a terminal that hung up.

SIGTERM (a batch system's time limit, ``kill``), SIGINT (Ctrl-C) and SIGHUP (the terminal closed,
the ssh session dropped) all mean "stop, keeping what was computed": inside the time loop the
ranks agree, write a checkpoint and the summary and stop with exit 130
(:func:`parmpm.driver.callbacks.stop_signals`); before it the run stops at once, with one line
(:mod:`parmpm.__main__`).

A hang-up has one more consequence: the terminal is gone, and every later write to it (the
progress bar, a log record, the closing line) fails with EIO, which would turn an orderly stop
into a crash before the checkpoint. So on SIGHUP the standard streams that were that terminal are
pointed at ``/dev/null`` (a hung-up terminal is the one whose ``tcgetattr`` fails with EIO; a
pipe, a file or a terminal that is still open is left alone, so ``kill -HUP`` from another shell
still shows the line), and ``--log-file`` keeps the record. A SIGHUP that is ignored when parmpm
starts (``nohup``) stays ignored. Light: no numpy, no solver.
"""
from __future__ import annotations

import errno
import os
import signal

#: the signals that stop a run with a checkpoint (exit 130)
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGINT", "SIGHUP")
                     if hasattr(signal, name))


def hung_up(fd: int) -> bool:
    """Whether ``fd`` is a terminal that hung up (its line closed)."""
    try:
        import termios

        termios.tcgetattr(fd)
    except ImportError:  # pragma: no cover (no termios: no such terminals)
        return False
    except termios.error as exc:
        return bool(exc.args) and exc.args[0] == errno.EIO
    except OSError:
        return False
    return False


def silence_hung_up_terminal() -> None:
    """Point stdout and stderr at /dev/null where they are a terminal that hung up (called from
    the SIGHUP handlers; async-signal-safe enough: it runs in Python's main thread)."""
    dead = [fd for fd in (1, 2) if hung_up(fd)]
    if not dead:
        return
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in dead:
            os.dup2(null, fd)
    finally:
        os.close(null)


def is_hangup(signum: int) -> bool:
    return signum == getattr(signal, "SIGHUP", None)


def to_handle() -> tuple:
    """The stop signals to install a handler for: all, except a SIGHUP that is ignored already
    (``nohup parmpm ...`` asks for the run to outlive its terminal)."""
    return tuple(sig for sig in STOP_SIGNALS
                 if not (is_hangup(sig) and signal.getsignal(sig) == signal.SIG_IGN))
