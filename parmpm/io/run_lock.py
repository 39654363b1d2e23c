"""Whether the run that claimed an output folder is still going: a lock the OS releases when the
process dies, and the claimant's host and pid.

A run (its rank 0, under MPI) holds an exclusive ``flock`` on ``parmpm-run.lock`` in its folder
for as long as it runs, and writes its host, pid and the pid's start into that file and into
``parmpm-run.json``. The lock answers the question exactly: the kernel drops it when the process
exits for any reason (an exception, ``kill -9``, a segfault, the node's ``mpirun`` ending rank 0),
so a folder whose lock can be taken holds no live run, and a lock that cannot be taken is a live
run's, whose host and pid the lock file names. Under MPI only rank 0 holds it; when rank 0 dies
the launcher ends the other ranks, so a run whose lock is free is a run that is over.

*Why flock, and NFS.* ``flock`` locks belong to the open file, not to the process, so a second
claim from the same process (two runs in one Python session, the tests) also finds the folder
taken, and closing some other descriptor of the file cannot drop the lock (as it would drop a
POSIX ``fcntl`` lock). On an NFS mount, Linux carries ``flock`` to the server as a whole-file POSIX
lock (NFSv4 natively, NFSv3 through ``lockd``), so a run on another node sees it too. Where the
filesystem has no locks at all (``flock`` fails with ``ENOLCK``, ``EOPNOTSUPP``: NFSv3 without
``lockd``) the marker's record decides (:func:`alive_by_record`): a run that ended says so; on this
host a live pid (with the same start time) is a live run; on another host parmpm cannot tell and
refuses, saying how to release the folder by hand. A mount with ``nolock``/``local_lock=flock``
keeps locks on one node: there a run on another node is seen only through that record's
``ended``, which is why a run writes it when it ends.
"""
from __future__ import annotations

import errno
import fcntl
import json
import os
import socket
from pathlib import Path

LOCK = "parmpm-run.lock"
#: flock's answers that mean "another holds it", and "this filesystem has no locks"
_BUSY = {errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES}
_NO_LOCKS = {errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL, errno.EBADF}


def _process_start(pid: int) -> str | None:
    """An identity of process ``pid`` that a later process reusing the pid does not share (boot id
    and start time in clock ticks, from /proc); None where /proc does not tell."""
    try:
        boot = Path("/proc/sys/kernel/random/boot_id").read_text().strip()
        stat = Path(f"/proc/{pid}/stat").read_text()
        return f"{boot}:{stat.rsplit(')', 1)[1].split()[19]}"
    except (OSError, IndexError):
        return None


def me() -> dict:
    """This process as a run's claim records it."""
    return {"host": socket.gethostname(), "pid": os.getpid(), "pid_start": _process_start(os.getpid())}


def who(record: dict | None) -> str:
    """``host H, pid P`` of a claim's record (for the one-line messages)."""
    record = record or {}
    return f"host {record.get('host', '?')}, pid {record.get('pid', '?')}"


class RunLock:
    """The claim of a folder this process holds: the open, locked ``parmpm-run.lock``."""

    def __init__(self, fd: int, path: Path):
        self.fd, self.path = fd, path

    def release(self) -> None:
        """Drop the lock (closing the file does; idempotent)."""
        fd, self.fd = self.fd, None
        if fd is not None:
            os.close(fd)

    def __del__(self):
        self.release()


class Busy:
    """The folder's lock is held: a live run's (``record``: the lock file's host and pid; {} when
    it is being claimed this instant and has not written them yet)."""

    def __init__(self, record: dict):
        self.record = record


class NoLocks:
    """The filesystem offers no locks (``reason``: the error's text)."""

    def __init__(self, reason: str):
        self.reason = reason


def _read(fd: int) -> dict:
    try:
        text = os.pread(fd, 4096, 0).decode("utf-8", "replace")
        record = json.loads(text) if text.strip() else {}
        return record if isinstance(record, dict) else {}
    except (OSError, ValueError):
        return {}


def take(folder: Path, create: bool = True) -> RunLock | Busy | NoLocks | None:
    """Try to take ``folder``'s lock without waiting: a :class:`RunLock` held (this process's
    record written into it), :class:`Busy`, :class:`NoLocks`, or None (``create=False`` and no
    lock file: no run of this parmpm ever held the folder). Raises OSError when the lock file
    cannot be created (an unwritable folder)."""
    path = Path(folder) / LOCK
    flags = os.O_RDWR | (os.O_CREAT if create else 0)
    try:
        fd = os.open(path, flags, 0o644)
    except FileNotFoundError:
        if create:
            raise
        return None
    except PermissionError:
        if create:
            raise
        fd = os.open(path, os.O_RDONLY)  # another user's folder: read-only locks still tell
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        record = _read(fd)
        os.close(fd)
        if exc.errno in _BUSY:
            return Busy(record)
        if exc.errno in _NO_LOCKS:
            return NoLocks(exc.strerror or str(exc))
        raise
    lock = RunLock(fd, path)
    if create:
        try:
            text = (json.dumps(me()) + "\n").encode()
            os.ftruncate(fd, 0)
            os.pwrite(fd, text, 0)
        except OSError:
            lock.release()
            raise
    return lock


def alive_by_record(record: dict) -> bool | None:
    """Without locks: whether the run a marker describes is going (None: cannot tell, it ran on
    another host). A run that says it ended, or a marker of an older parmpm (no pid), is over."""
    if record.get("ended") or not record.get("host") or not isinstance(record.get("pid"), int):
        return False
    if record["host"] != socket.gethostname():
        return None
    pid = record["pid"]
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        pass
    except OverflowError:
        return False
    start = _process_start(pid)
    return not (record.get("pid_start") and start and start != record["pid_start"])
