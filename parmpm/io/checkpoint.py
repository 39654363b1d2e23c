"""HDF5 checkpoints, the format: what a file of particle rows holds, how it is checked, how it is
written atomically, and which files belong to which checkpoint (docs/checkpoints.md says why).

A checkpoint ``checkpoint_<step>.h5`` is one file to h5py, ParaView and ``parmpm restart``: its
``particles/<field>`` datasets hold every particle. Since version 4 the rows are in *rank order*
(the ranks that wrote it in turn, each rank's rows sorted by patch, then global id; the ``gid``
column says which particle a row is), and ``index/patch_rows`` says where each patch's rows lie,
so a restart reads exactly the rows of its own patches. With more than one writer the rows live
in part files, ``checkpoint_<step>.parts/part_<k>.h5``, that the top-level file binds with HDF5
virtual datasets (relative source names: the folder can be moved); with one writer they are in
the top-level file itself. :mod:`parmpm.io.checkpoint_parts` reads checkpoints and writes the
top-level file; :mod:`parmpm.driver.checkpoint_writer` is the parallel strategy.

**Integrity.** A file's rows are cut into *segments* (``segments``: offsets; version 4: each
patch's rows, cut at ``block_rows``; versions 1–3: fixed blocks of ``block_rows``) and
``digests/<field>`` holds one SHA-256 (FIPS 180-4) per segment, of the field's name, the
segment's index and its rows' bytes (little-endian, C order). A read takes the whole segments it
touches and checks them; a restart asks for whole patches, so it reads nothing more. HDF5's own
checksums (Fletcher-32 of chunks, in version 3) do not cover the index that locates the data: a
flipped bit there read whole fields back as zeros without an error. The digest tables, the
segment offsets, the patch index and the part table are checked on open against
``data_digest``; every root attribute, ``data_digest`` included, is covered by ``digest``; the
top-level file records each part's ``digest``. So a damaged file reads back exactly what was
written or fails with one line naming it.

**Atomic, and space.** Every file is written under a temporary name, fsynced and renamed: parts
first, the top-level file last, so a kill at any moment leaves every earlier checkpoint whole
(a new checkpoint's parts live in a folder named by its step, never in an older one's). Before
creating a file the writer compares its estimated size with the free space (and, before each
block, what is left to write with what is left free), so a full disk is one line (``disk full
writing '<path>': N MB needed, M MB free``). Should the disk fill anyway, HDF5 never sees the
failure: it writes through a :class:`GuardedFile` (h5py's file-object driver) that records the
first OSError and drops every later write (HDF5 crashes the process when it closes a file whose
writes failed); the writer then closes HDF5 cleanly, removes the temporary file and raises one
line.

Schema of a data file (a part, format ``parmpm-checkpoint-part``, or a one-writer checkpoint)::

    /particles/gid, mat             (n,) int64: global id, material row
    /particles/x, v, x0, lh0        (n, dim) float64
    /particles/mass, vol0, damage   (n,) float64
    /particles/F, stress, r0, rf    (n, dim, dim) float64 (rf: frozen CPDI domain, 0 = none)
    /particles/affine               (n, dim, dim) float64 (APIC's C_p; 0 under FLIP)
    /particles/corners              (n, 2^dim, dim) float64 (CPDI2's corners; cpdi2 runs only)
    /segments                       (K+1,) int64 offsets of the digest segments
    /digests/<field>                (K, 32) uint8: SHA-256 of each segment
    part attrs: format, version, part, parts, first_row, rows, step, lineage, block_rows,
                data_digest, digest

Versions 1–3 (one file in global-id order, fixed blocks, Fletcher-32 chunks) still read;
versions 1 (no ``rf``, read as 0) and 2 without digests (a warning says so); before version 5
there is no ``affine`` (read as 0: those runs were FLIP runs).
"""
from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np

from parmpm.core.errors import ParmpmError
from parmpm.io.guarded_file import GuardedFile, space_message  # noqa: F401 (re-exported)

FORMAT = "parmpm-checkpoint"
PART_FORMAT = "parmpm-checkpoint-part"
#: 5: adds particles/affine; 4: rows in rank order with a patch index, parts bound by virtual
#: datasets, digests per segment; 3: per-block SHA-256 of the data; 2: adds particles/rf;
#: 1: rf read as 0
VERSION = 5
#: stored particle fields (``dx`` is MUSL scratch, ``patch`` is derived from ``x``)
FIELDS = ("gid", "mat", "x", "v", "x0", "mass", "vol0", "F", "stress", "r0", "lh0", "damage",
          "rf", "affine", "corners")


#: fields a checkpoint holds only when the run carries them (:data:`parmpm.particles.store.OPTIONAL_FIELDS`)
OPTIONAL = ("affine", "corners")


def required_fields(version: int) -> tuple[str, ...]:
    """The particle fields every checkpoint of format ``version`` holds (an optional field is
    there when the run carried it; a missing one reads as 0)."""
    base = tuple(k for k in FIELDS if k not in OPTIONAL)
    return base if version >= 2 else tuple(k for k in base if k != "rf")
#: the stored type of every field (little-endian, as hashed)
DTYPES = {name: np.dtype("<i8") if name in ("gid", "mat") else np.dtype("<f8") for name in FIELDS}
ATTRS = ("scene", "step", "time", "dt", "vmax", "method", "lcr", "ranks", "particles", "dim", "state")
#: the most rows of one digest segment (version 3: the chunk size, every block)
BLOCK_ROWS = 1 << 16
#: HDF5 format bounds: version-2 object headers (checksummed), virtual datasets; HDF5 >= 1.10
LIBVER = ("v110", "v110")
#: what HDF5 adds beyond the data (object headers, heaps), bounded from above
_OVERHEAD = 256 * 1024
_PER_SEGMENT = 8  # a segment offset
_NO_SPACE = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


def attrs_digest(attrs: dict) -> str:
    """SHA-256 of the root attributes (HDF5 checksums data chunks, not attributes)."""
    text = json.dumps({k: (v.item() if hasattr(v, "item") else v) for k, v in sorted(attrs.items())},
                      sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def block_digest(name: str, k: int, rows: np.ndarray) -> bytes:
    """SHA-256 of segment ``k`` of field ``name``: its name and index (so a segment read from
    the wrong place fails), then its rows' bytes."""
    h = hashlib.sha256(f"{name}:{k}:".encode())
    h.update(np.ascontiguousarray(rows, dtype=DTYPES[name]).data)
    return h.digest()


def tables_digest(tables: dict[str, np.ndarray]) -> str:
    """Version 3's ``data_digest``: SHA-256 of the digest tables."""
    h = hashlib.sha256()
    for name in sorted(tables):
        h.update(f"{name}:{tables[name].shape[0]}:".encode())
        h.update(np.ascontiguousarray(tables[name], dtype=np.uint8).data)
    return h.hexdigest()


def arrays_digest(arrays: dict[str, np.ndarray]) -> str:
    """Version 4's ``data_digest``: SHA-256 of named tables (their names, types, shapes, bytes)."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}:{a.dtype.str}:{a.shape}:".encode())
        h.update(a.data)
    return h.hexdigest()


def checkpoint_name(step: int) -> str:
    return f"checkpoint_{step:08d}.h5"


def parts_folder(path: Path) -> Path:
    """The folder of the part files of checkpoint ``path``: ``checkpoint_<step>.parts``."""
    path = Path(path)
    return path.with_name(path.name[:-3] + ".parts" if path.name.endswith(".h5") else
                          path.name + ".parts")


def part_name(k: int) -> str:
    return f"part_{k:05d}.h5"


def segments_of(counts: np.ndarray, block_rows: int = BLOCK_ROWS) -> np.ndarray:
    """Segment offsets of consecutive runs of ``counts`` rows (one per patch; empty runs
    skipped), each run cut into pieces of at most ``block_rows``: (K+1,) int64 from 0."""
    counts = np.asarray(counts, np.int64)
    counts = counts[counts > 0]
    pieces = -(-counts // block_rows)
    sizes = np.full(int(pieces.sum()), block_rows, np.int64)
    last = np.cumsum(pieces) - 1
    sizes[last] = counts - (pieces - 1) * block_rows
    return np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)


def _free_bytes(folder: Path) -> int:
    return int(shutil.disk_usage(folder).free)


def os_problem(path: Path, exc: OSError) -> str:
    """One line for an OSError met writing ``path`` (h5py's messages span lines)."""
    if exc.errno in _NO_SPACE:
        try:
            free = f": {_free_bytes(path.parent) / 1e6:.1f} MB free"
        except OSError:
            free = ""
        return f"disk full writing '{path}' ({os.strerror(exc.errno)}){free}"
    what = os.strerror(exc.errno) if exc.errno else (str(exc).splitlines() or ["I/O error"])[0]
    return f"cannot write checkpoint '{path}': {what}"


def row_bytes(like: dict[str, np.ndarray]) -> int:
    return sum(int(np.prod(a.shape[1:], dtype=np.int64)) * DTYPES[k].itemsize
               for k, a in like.items())


def estimate_bytes(n: int, like: dict[str, np.ndarray], attrs: dict, block_rows: int = BLOCK_ROWS,
                   segments: int | None = None, extra: int = 0) -> int:
    """An upper bound of the size of a file of ``n`` rows: the rows × bytes per row of every
    field, the digest tables and segment offsets (``segments``: their number, default
    ⌈n/block_rows⌉), ``extra`` bytes of tables, the attributes, and HDF5's fixed overhead."""
    k = (-(-n // block_rows) if n else 0) if segments is None else int(segments)
    text = sum(len(str(v)) for v in attrs.values())
    return (n * row_bytes(like) + len(like) * k * 32 + (k + 1) * _PER_SEGMENT + int(extra)
            + 2 * text + _OVERHEAD)


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
        self.need = estimate_bytes(self.n, like, attrs, self.block_rows, self.segments.size - 1,
                                   extra_bytes)
        self._row_bytes = row_bytes(like)
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
        except Exception as exc:  # noqa: BLE001 - _fail re-raises what is not an I/O error
            self._fail(exc)
        self._check_io()

    # --- failure paths ------------------------------------------------------------------------
    def _check_space(self, need: int) -> None:
        try:
            free = _free_bytes(self.path.parent)
        except OSError as exc:
            self._fail(exc)
        if need > free:
            self._discard()
            raise ParmpmError(space_message(self.path, need, free))

    def _check_io(self) -> None:
        """Raise the write error the guarded file kept, if any."""
        if self._file is not None and self._file.error is not None:
            self._fail(self._file.error)

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

    def _fail(self, exc: BaseException):
        """Throw the file away and raise one line: the write error the guarded file kept (what
        HDF5 trips over after it is the consequence), else ``exc`` if an OSError, else
        ``exc`` itself (a bug)."""
        kept = self._file.error if self._file is not None else None
        self._discard()
        if kept is not None or isinstance(exc, OSError):
            raise ParmpmError(os_problem(self.path, kept or exc)) from None
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
                h = self._open[name] = hashlib.sha256(f"{name}:{k}:".encode())
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
        except Exception as exc:  # noqa: BLE001 - _fail re-raises what is not an I/O error
            self._fail(exc)
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
        except Exception as exc:  # noqa: BLE001 - _fail re-raises what is not an I/O error
            self._fail(exc)
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


# --- which files are whose ------------------------------------------------------------------------
def read_lineage(path: Path) -> str | None:
    """The ``lineage`` attribute of a checkpoint, cheaply (one attribute; no checks); None when
    it has none. Raises OSError (or h5py's errors) for an unreadable file."""
    import h5py

    with h5py.File(path, "r") as f:
        if f.attrs.get("format") != FORMAT:
            raise OSError(f"'{path}' is not a parmpm checkpoint")
        v = f.attrs.get("lineage")
        return None if v is None else str(v)


def remove_checkpoint(path: Path) -> None:
    """Delete checkpoint ``path`` and its part files (the top-level file first, so that a kill
    meanwhile leaves stale parts, which :func:`remove_stale_tmp` clears, never a checkpoint
    without them)."""
    Path(path).unlink(missing_ok=True)
    shutil.rmtree(parts_folder(path), ignore_errors=True)


def prune(folder: Path, keep: int, lineage: str | None = None) -> list[Path]:
    """Delete all but the newest ``keep`` checkpoints (by step) of ``lineage`` in ``folder``,
    with their parts; ``lineage=None`` means the checkpoints that carry no lineage. Files of
    another lineage, and files that cannot be read, are never deleted. Returns the deleted
    paths (the top-level files)."""
    if keep <= 0:
        return []
    mine = []
    for p in sorted(Path(folder).glob("checkpoint_*.h5")):
        try:
            if read_lineage(p) == lineage:
                mine.append(p)
        except Exception:  # noqa: BLE001 - unreadable: not ours to delete
            continue
    gone = []
    for old in mine[:-keep]:
        if old.exists():
            remove_checkpoint(old)
            gone.append(old)
    return gone


def remove_stale_tmp(folder: Path) -> list[Path]:
    """Delete what an interrupted writer left in ``folder``: temporary checkpoints
    (``checkpoint_*.h5.tmp``) and snapshot indexes (``*.xdmf.tmp``), part folders whose
    checkpoint was never committed (``checkpoint_<step>.parts`` without ``checkpoint_<step>.h5``)
    and temporary parts. Returns them."""
    gone = []
    folder = Path(folder)
    if not folder.is_dir():
        return gone
    for pattern in ("checkpoint_*.h5.tmp", "*.xdmf.tmp"):
        for p in sorted(folder.glob(pattern)):
            if p.is_file() and not p.is_symlink():
                p.unlink(missing_ok=True)
                gone.append(p)
    for d in sorted(folder.glob("checkpoint_*.parts")):
        if not d.is_dir() or d.is_symlink():
            continue
        if not d.with_name(d.name[:-len(".parts")] + ".h5").exists():
            shutil.rmtree(d, ignore_errors=True)
            gone.append(d)
            continue
        for p in sorted(d.glob("part_*.h5.tmp")):
            p.unlink(missing_ok=True)
            gone.append(p)
    return gone
