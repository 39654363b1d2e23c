"""Writing one checkpoint file atomically, and so that a full disk is one line.

Every file is written under a temporary name, fsynced and renamed: parts first, the top-level
file last, so a kill at any moment leaves every earlier checkpoint whole (a new checkpoint's
parts live in a folder named by its step, never in an older one's). Before creating a file the
writer compares its estimated size with the free space (and, before each block, what is left to
write with what is left free: :mod:`parmpm.io.checkpoint.space`). Should the disk fill anyway,
HDF5 never sees the failure: it writes through a :class:`parmpm.io.guarded_file.GuardedFile`
(h5py's file-object driver) that records the first OSError and drops every later write (HDF5
crashes the process when it closes a file whose writes failed); the writer then closes HDF5
cleanly, removes the temporary file and raises one line.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

import parmpm.io.checkpoint.space as space
from parmpm.core.errors import ParmpmError
from parmpm.io.checkpoint.digests import arrays_digest, attrs_digest, segment_hash
from parmpm.io.checkpoint.format import BLOCK_ROWS, DTYPES, FIELDS, FORMAT, LIBVER, VERSION
from parmpm.io.guarded_file import GuardedFile, space_message


class CheckpointWriter:
    """Writes one file of particle rows (a part, or a one-writer checkpoint), or with no fields
    (``like = {}``) the top-level file of parts: create, take blocks of rows (ascending,
    contiguous), commit atomically. Every failure removes the temporary file and raises a
    one-line ParmpmError; :meth:`abort` after one is harmless.

    ``segments``: the digest segments' offsets (default: fixed blocks of ``block_rows``);
    ``fmt``: the ``format`` attribute (:data:`FORMAT` or :data:`PART_FORMAT`)."""

    def __init__(self, path: Path, n: int, like: dict[str, np.ndarray], attrs: dict,
                 block_rows: int = BLOCK_ROWS, segments: np.ndarray | None = None,
                 fmt: str = FORMAT, extra_bytes: int = 0):
        import h5py

        unknown = sorted(set(like) - set(DTYPES))
        if unknown:
            raise ValueError(f"not checkpoint fields: {unknown} (known: {FIELDS})")
        self.path = Path(path)
        self.tmp = self.path.with_name(self.path.name + ".tmp")
        self.n, self.block_rows = int(n), int(block_rows)
        if segments is None:
            segments = np.minimum(np.arange(0, self.n + self.block_rows, self.block_rows), self.n)
            segments = np.unique(segments)
        self.segments = np.asarray(segments, np.int64)
        if (self.segments[0] != 0 or self.segments[-1] != self.n
                or np.any(np.diff(self.segments) <= 0)):
            raise ValueError(f"segments must rise from 0 to {self.n}")
        self.f, self._ds, self._file = None, {}, None
        self._next = 0  # the next row expected
        self._digests = {name: [] for name in like}
        self._open = {name: None for name in like}  # the running hash of a partial segment
        self.need = space.estimate_bytes(self.n, like, attrs, self.block_rows,
                                         self.segments.size - 1, extra_bytes)
        self._row_bytes = space.row_bytes(like)
        self._check_space(self.need)
        try:
            self._file = GuardedFile(self.tmp)
            self.f = h5py.File(self._file, "w", libver=LIBVER, rdcc_nbytes=0)
            self.f.attrs["format"] = fmt
            self.f.attrs["version"] = VERSION
            for k, v in attrs.items():
                self.f.attrs[k] = v
            self.f.attrs["block_rows"] = self.block_rows
            if like:
                g = self.f.create_group("particles")
                for name, a in like.items():  # contiguous: a read takes exactly its rows
                    self._ds[name] = g.create_dataset(name, shape=(self.n,) + a.shape[1:],
                                                      dtype=DTYPES[name])
        except ParmpmError:
            raise
        except Exception as exc:  # noqa: BLE001 - fail re-raises what is not an I/O error
            self.fail(exc)
        self._check_io()

    # --- failure paths ------------------------------------------------------------------------
    def _check_space(self, need: int) -> None:
        try:
            free = space.free_bytes(self.path.parent)
        except OSError as exc:
            self.fail(exc)
        if need > free:
            self._discard()
            raise ParmpmError(space_message(self.path, need, free))

    def _check_io(self) -> None:
        """Raise the write error the guarded file kept, if any."""
        if self._file is not None and self._file.error is not None:
            self.fail(self._file.error)

    def _discard(self) -> None:
        """Close every handle (errors ignored: the file is thrown away) and remove it."""
        self._ds.clear()
        if self.f is not None:
            f, self.f = self.f, None
            try:
                f.close()
            except Exception:  # noqa: BLE001 - the file is being thrown away
                pass
        if self._file is not None:
            self._file.close()
        try:
            self.tmp.unlink(missing_ok=True)
        except OSError:
            pass

    def fail(self, exc: BaseException):
        """Throw the file away and raise one line: the write error the guarded file kept (what
        HDF5 trips over after it is the consequence), else ``exc`` if an OSError, else
        ``exc`` itself (a bug). For whoever adds to :attr:`f` directly (the top-level file's
        virtual datasets)."""
        kept = self._file.error if self._file is not None else None
        self._discard()
        if kept is not None or isinstance(exc, OSError):
            raise ParmpmError(space.os_problem(self.path, kept or exc)) from None
        raise exc

    # --- writing ------------------------------------------------------------------------------
    def _feed(self, name: str, lo: int, a: np.ndarray) -> None:
        """Hash the rows ``lo..lo+len(a)`` of ``name`` into its segment digests."""
        seg, done = self.segments, 0
        while done < a.shape[0]:
            row = lo + done
            k = int(np.searchsorted(seg, row, side="right")) - 1
            take = min(int(seg[k + 1]) - row, a.shape[0] - done)
            h = self._open[name]
            if h is None:
                h = self._open[name] = segment_hash(name, k)
            h.update(np.ascontiguousarray(a[done:done + take], dtype=DTYPES[name]).data)
            done += take
            if row + take == seg[k + 1]:
                self._digests[name].append(h.digest())
                self._open[name] = None

    def write(self, lo: int, block: dict[str, np.ndarray]) -> None:
        """Store rows ``lo..lo+m`` of every field (blocks come in ascending, contiguous order)."""
        if self.f is None:
            raise ParmpmError(f"cannot write checkpoint '{self.path}': already closed")
        m = {a.shape[0] for a in block.values()}
        if lo != self._next or len(m) != 1 or set(block) != set(self._ds):
            self._discard()
            raise ParmpmError(f"cannot write checkpoint '{self.path}': block at row {lo} "
                              f"(expected {self._next}, every field, equal lengths)")
        m = m.pop()
        self._check_space(self.need - lo * self._row_bytes)  # what is left to write
        try:
            for name, a in block.items():
                a = np.ascontiguousarray(a, dtype=DTYPES[name])
                if m:
                    self._ds[name][lo:lo + m] = a
                self._check_io()
                self._feed(name, lo, a)
        except ParmpmError:
            raise
        except Exception as exc:  # noqa: BLE001 - fail re-raises what is not an I/O error
            self.fail(exc)
        self._next = lo + m

    def commit(self, extra: dict[str, np.ndarray] | None = None) -> str:
        """Store the digests, the segment offsets and the ``extra`` tables (path → array), the
        checksums of all of them and of the attributes; close, fsync and rename into place.
        Returns the file's ``digest``."""
        if self.f is None:
            raise ParmpmError(f"cannot write checkpoint '{self.path}': already closed")
        if self._next != self.n:
            self._discard()
            raise ParmpmError(f"cannot write checkpoint '{self.path}': only {self._next} of "
                              f"{self.n} rows written")
        try:
            tables = dict(extra or {})
            if self._ds:
                tables["segments"] = self.segments
                for name, d in self._digests.items():
                    tables[f"digests/{name}"] = np.frombuffer(b"".join(d), np.uint8).reshape(-1, 32)
            for where, t in tables.items():
                self.f.create_dataset(where, data=t)
            self.f.attrs["data_digest"] = arrays_digest(tables)
            a = self.f.attrs
            digest = attrs_digest({k: a[k] for k in a if k != "digest"})
            self.f.attrs["digest"] = digest
            self._ds.clear()
            self.f.flush()
            f, self.f = self.f, None
            f.close()
            self._file.fsync()
            self._check_io()
            self._file.close()
            self._check_io()
            os.replace(self.tmp, self.path)
        except ParmpmError:
            raise
        except Exception as exc:  # noqa: BLE001 - fail re-raises what is not an I/O error
            self.fail(exc)
        fsync_folder(self.path.parent)
        return digest

    def abort(self) -> None:
        """Throw the file away (idempotent)."""
        self._discard()


def fsync_folder(folder: Path) -> None:
    """Make a rename in ``folder`` durable (best effort)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError:
        pass
