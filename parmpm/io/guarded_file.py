"""Files that HDF5 writes through without ever seeing a failed write, and the one-line message
of a full disk (shared by checkpoints and snapshots).

An HDF5 object whose close fails to write (a dataset's cached chunks on a full disk) leaves the
library in a state where the next flush or close of the file crashes the process (segfault),
after pages of error stacks. :class:`GuardedFile` records the first OSError and drops every later
write, so HDF5 closes cleanly and the owner reports the recorded error in one line.
"""
from __future__ import annotations

import io
import os
from pathlib import Path


def space_message(path: Path, need: int, free: int) -> str:
    """``disk full writing '<path>': N MB needed, M MB free``, with as many decimals as it takes
    for N and M to differ."""
    digits = 1
    while digits < 6 and f"{need / 1e6:.{digits}f}" == f"{free / 1e6:.{digits}f}":
        digits += 1
    return f"disk full writing '{path}': {need / 1e6:.{digits}f} MB needed, {free / 1e6:.{digits}f} MB free"


class GuardedFile(io.RawIOBase):
    """A binary file for h5py's file-object driver (``h5py.File(GuardedFile(path), "w")``)
    that keeps HDF5 from ever seeing a failed write: the first OSError of a write or truncate is
    kept in :attr:`error`, and from then on writes are dropped (reported as done). The owner
    checks :attr:`error` after each operation, closes the h5py file, then this one."""

    def __init__(self, path: Path):
        super().__init__()
        self.path = Path(path)
        self._f = open(self.path, "w+b", buffering=0)  # noqa: SIM115 - closed in close()
        self.error: OSError | None = None

    def readable(self) -> bool:
        return True

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def readinto(self, b) -> int:
        return self._f.readinto(b)

    def write(self, b) -> int:
        view = memoryview(b).cast("B")
        if self.error is None:
            done = 0
            try:
                while done < len(view):
                    done += self._f.write(view[done:])
            except OSError as exc:
                self.error = exc
        return len(view)

    def seek(self, pos: int, whence: int = 0) -> int:
        return self._f.seek(pos, whence)

    def tell(self) -> int:
        return self._f.tell()

    def truncate(self, size: int | None = None) -> int:
        if self.error is None:
            try:
                return self._f.truncate(size)
            except OSError as exc:
                self.error = exc
        return self._f.tell() if size is None else size

    def flush(self) -> None:  # unbuffered: nothing held here
        pass

    def fsync(self) -> None:
        """Force the written bytes to the device (an OSError is kept in :attr:`error`)."""
        if self.error is None:
            try:
                os.fsync(self._f.fileno())
            except OSError as exc:
                self.error = exc

    def close(self) -> None:
        if not self.closed:
            try:
                self._f.close()
            except OSError as exc:
                self.error = self.error or exc
            super().close()
