"""HDF5 checkpoints: every particle field in global-id order, the resolved scene, the clock.

One file per checkpoint, ``checkpoint_<step>.h5``. PyPI's h5py is serial, so the run driver
gathers the particles to rank 0 in bounded blocks of global ids (no rank ever holds more than one
block of other ranks' particles) and rank 0 writes them here; restart reads the file back on any
number of ranks. The file is written under a temporary name, flushed, fsynced and renamed, so a
kill at any moment leaves every earlier checkpoint whole.

**Integrity.** HDF5's Fletcher-32 covers the bytes of each data chunk, but not the chunk index
that says where a chunk lies: a flipped bit there can make a whole field read back as zeros with
no error. So the data themselves carry SHA-256 digests (FIPS 180-4): every field is cut into
blocks of ``block_rows`` rows (= its chunk size, 2^16, which divides the restart's 2^18-row
reads), and ``digests/<field>`` holds one digest per block, of the field's name, the block's
index and its rows' bytes (little-endian, C order). :meth:`CheckpointReader.read` reads the whole
blocks a slice touches and checks them. The digest tables are checked on open against
``data_digest`` (SHA-256 of all tables), and every root attribute, ``data_digest`` included, is
covered by ``digest``. So a damaged file either reads back exactly what was written or fails with
one line naming it.

**Space.** Before creating the file the writer compares its estimated size with the free space
of the folder (and, before each block, what is left to write with what is left free), so a full
disk is one line (``disk full writing '<path>': N MB needed, M MB free``) before HDF5 sees it.
Should the disk fill anyway, HDF5 never sees the failure: an HDF5 object whose close fails to
write (a dataset's cached chunks on a full disk) leaves the library in a state where the next
flush or close of the file crashes the process (segfault), after pages of error stacks. So HDF5
writes through a :class:`GuardedFile` (h5py's file-object driver) that records the first OSError
and drops every later write; with no chunk cache every block reaches the file in its
:meth:`CheckpointWriter.write`, which then finds the recorded error, closes HDF5 (cleanly: it
saw no error), removes the temporary file and raises one line.

Schema (format ``parmpm-checkpoint``, version 3), readable with plain h5py::

    /                 attrs: format, version, scene (resolved TOML), step, time, dt (last Δt),
                      vmax (max c+|v| for the next Δt), method, lcr (m, NaN = none), ranks
                      (that wrote it), particles, dim, state (JSON: metrics history, output
                      clock), lineage (optional: the id of the original run), block_rows,
                      data_digest, digest (SHA-256 of all other attributes, see attrs_digest)
    /particles/gid    (N,) int64, = 0..N-1
    /particles/mat    (N,) int64 material row
    /particles/x, v, x0, lh0        (N, dim) float64
    /particles/mass, vol0, damage   (N,) float64
    /particles/F, stress, r0, rf    (N, dim, dim) float64 (rf: frozen CPDI domain, 0 = none)
    /digests/<field>  (ceil(N / block_rows), 32) uint8: SHA-256 of each block of rows

Versions 1 (no ``rf``, read as 0) and 2 still read, with Fletcher-32 only (a warning says so).
"""
from __future__ import annotations

import errno
import hashlib
import json
import logging
import os
import shutil
from pathlib import Path

import numpy as np

from parmpm.errors import ParmpmError
from parmpm.io.guarded_file import GuardedFile, space_message  # noqa: F401 (re-exported)

logger = logging.getLogger(__name__)

FORMAT = "parmpm-checkpoint"
VERSION = 3  # 3: per-block SHA-256 of the data; 2: adds particles/rf; 1: rf read as 0
#: stored particle fields (``dx`` is MUSL scratch, ``patch`` is derived from ``x``)
FIELDS = ("gid", "mat", "x", "v", "x0", "mass", "vol0", "F", "stress", "r0", "lh0", "damage",
          "rf")
#: the stored type of every field (little-endian, as hashed)
DTYPES = {name: np.dtype("<i8") if name in ("gid", "mat") else np.dtype("<f8") for name in FIELDS}
ATTRS = ("scene", "step", "time", "dt", "vmax", "method", "lcr", "ranks", "particles", "dim", "state")
#: rows per chunk and per digest block: divides the 2^18-row blocks restart reads
BLOCK_ROWS = 1 << 16
#: what HDF5 adds beyond the data (object headers, chunk indexes, heaps), bounded from above
_OVERHEAD = 256 * 1024
_PER_CHUNK = 96  # chunk index entry + Fletcher-32
_NO_SPACE = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


def attrs_digest(attrs: dict) -> str:
    """SHA-256 of the root attributes (HDF5 checksums data chunks, not attributes)."""
    text = json.dumps({k: (v.item() if hasattr(v, "item") else v) for k, v in sorted(attrs.items())},
                      sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def _block_digest(name: str, k: int, rows: np.ndarray) -> bytes:
    """SHA-256 of block ``k`` of field ``name``: its name and index (so a block read from the
    wrong place fails), then its rows' bytes."""
    h = hashlib.sha256(f"{name}:{k}:".encode())
    h.update(np.ascontiguousarray(rows, dtype=DTYPES[name]).data)
    return h.digest()


def _tables_digest(tables: dict[str, np.ndarray]) -> str:
    h = hashlib.sha256()
    for name in sorted(tables):
        h.update(f"{name}:{tables[name].shape[0]}:".encode())
        h.update(np.ascontiguousarray(tables[name], dtype=np.uint8).data)
    return h.hexdigest()


def checkpoint_name(step: int) -> str:
    return f"checkpoint_{step:08d}.h5"


def _free_bytes(folder: Path) -> int:
    return int(shutil.disk_usage(folder).free)


def _os_problem(path: Path, exc: OSError) -> str:
    """One line for an OSError met writing ``path`` (h5py's messages span lines)."""
    if exc.errno in _NO_SPACE:
        try:
            free = f": {_free_bytes(path.parent) / 1e6:.1f} MB free"
        except OSError:
            free = ""
        return f"disk full writing '{path}' ({os.strerror(exc.errno)}){free}"
    what = os.strerror(exc.errno) if exc.errno else (str(exc).splitlines() or ["I/O error"])[0]
    return f"cannot write checkpoint '{path}': {what}"


def _row_bytes(like: dict[str, np.ndarray]) -> int:
    return sum(int(np.prod(a.shape[1:], dtype=np.int64)) * DTYPES[k].itemsize
               for k, a in like.items())


def estimate_bytes(n: int, like: dict[str, np.ndarray], attrs: dict,
                   block_rows: int = BLOCK_ROWS) -> int:
    """An upper bound of the size of a checkpoint of ``n`` particles: the stored rows (HDF5
    stores the last chunk whole) × bytes per row of every field, the digest tables, a chunk
    index entry per chunk, the attributes, and HDF5's fixed overhead."""
    chunks = -(-n // block_rows) if n else 0
    rows = chunks * min(n, block_rows)
    text = sum(len(str(v)) for v in attrs.values())
    return rows * _row_bytes(like) + len(like) * chunks * (32 + _PER_CHUNK) + 2 * text + _OVERHEAD


class CheckpointWriter:
    """Rank 0's side of writing one checkpoint: create, take blocks (ascending, contiguous
    global ids), commit atomically. Every failure removes the temporary file and raises a
    one-line ParmpmError; :meth:`abort` after one is harmless."""

    def __init__(self, path: Path, n: int, like: dict[str, np.ndarray], attrs: dict,
                 block_rows: int = BLOCK_ROWS):
        import h5py

        unknown = sorted(set(like) - set(DTYPES))
        if unknown:
            raise ValueError(f"not checkpoint fields: {unknown} (known: {FIELDS})")
        self.path = Path(path)
        self.tmp = self.path.with_name(self.path.name + ".tmp")
        self.n, self.block_rows = int(n), int(block_rows)
        self.f, self._ds, self._file = None, {}, None
        self._next = 0  # the next row expected
        self._digests = {name: [] for name in like}
        self._open = {name: None for name in like}  # the running hash of a partial block
        self.need = estimate_bytes(self.n, like, attrs, self.block_rows)
        self._row_bytes = _row_bytes(like)
        self._check_space(self.need)
        try:
            # no chunk cache: every write reaches the file in its call
            self._file = GuardedFile(self.tmp)
            self.f = h5py.File(self._file, "w", rdcc_nbytes=0)
            self.f.attrs["format"] = FORMAT
            self.f.attrs["version"] = VERSION
            for k, v in attrs.items():
                self.f.attrs[k] = v
            self.f.attrs["block_rows"] = self.block_rows
            g = self.f.create_group("particles")
            for name, a in like.items():
                shape = (self.n,) + a.shape[1:]
                chunk = (max(1, min(self.n, self.block_rows)),) + a.shape[1:]
                self._ds[name] = g.create_dataset(name, shape=shape, dtype=DTYPES[name],
                                                  chunks=chunk if self.n else None,
                                                  fletcher32=bool(self.n))
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
            raise ParmpmError(_os_problem(self.path, kept or exc)) from None
        raise exc

    # --- writing ------------------------------------------------------------------------------
    def _feed(self, name: str, lo: int, a: np.ndarray) -> None:
        """Hash the rows ``lo..lo+len(a)`` of ``name`` into its block digests."""
        B, done = self.block_rows, 0
        while done < a.shape[0]:
            row = lo + done
            k, off = divmod(row, B)
            take = min(B - off, a.shape[0] - done)
            h = self._open[name]
            if h is None:
                h = self._open[name] = hashlib.sha256(f"{name}:{k}:".encode())
            h.update(np.ascontiguousarray(a[done:done + take], dtype=DTYPES[name]).data)
            done += take
            if off + take == B or row + take == self.n:
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
                self._ds[name][lo:lo + m] = a
                self._check_io()
                self._feed(name, lo, a)
        except ParmpmError:
            raise
        except Exception as exc:  # noqa: BLE001 - _fail re-raises what is not an I/O error
            self._fail(exc)
        self._next = lo + m

    def commit(self) -> None:
        """Store the digests, close, fsync and rename into place."""
        if self.f is None:
            raise ParmpmError(f"cannot write checkpoint '{self.path}': already closed")
        if self._next != self.n:
            self._discard()
            raise ParmpmError(f"cannot write checkpoint '{self.path}': only {self._next} of "
                              f"{self.n} rows written")
        try:
            tables = {name: np.frombuffer(b"".join(d), dtype=np.uint8).reshape(len(d), 32)
                      for name, d in self._digests.items()}
            g = self.f.create_group("digests")
            for name, t in tables.items():
                g.create_dataset(name, data=t)
            self.f.attrs["data_digest"] = _tables_digest(tables)
            a = self.f.attrs
            self.f.attrs["digest"] = attrs_digest({k: a[k] for k in a if k != "digest"})
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
        try:
            dirfd = os.open(self.path.parent, os.O_RDONLY)
            try:
                os.fsync(dirfd)
            finally:
                os.close(dirfd)
        except OSError:
            pass

    def abort(self) -> None:
        """Throw the file away (idempotent)."""
        self._discard()


class CheckpointReader:
    """An open, validated checkpoint; every problem is a one-line ParmpmError naming the file.

    ``warn``: log a warning when the file's data carry no digests (versions 1 and 2); pass
    ``warn=rank == 0`` so that a restart on many ranks says it once."""

    def __init__(self, path, warn: bool = True):
        import h5py

        self.path = Path(path)
        where = self.where = f"checkpoint '{self.path}'"
        self.f = None
        if not self.path.is_file():
            raise ParmpmError(f"{where}: no such file")
        try:
            self.f = h5py.File(self.path, "r")
        except OSError as exc:
            raise ParmpmError(f"{where}: not a readable HDF5 file (truncated or damaged?): "
                              f"{(str(exc).splitlines() or ['unreadable'])[0]}") from None
        except Exception as exc:  # h5py reports a damaged superblock in many ways
            raise ParmpmError(f"{where}: not a readable HDF5 file (damaged?): "
                              f"{type(exc).__name__}") from None
        try:
            a = dict(self.f.attrs)  # one pass over the attributes
            if a.get("format") != FORMAT:
                raise ParmpmError(f"{where}: not a parmpm checkpoint (no format = '{FORMAT}' attribute)")
            version = self.version = int(a.get("version", -1))
            if version > VERSION:
                raise ParmpmError(f"{where}: written by a newer parmpm (format version {version}; "
                                  f"this parmpm reads up to {VERSION})")
            # digests are checked whenever present (a flipped version number does not skip them)
            self.digested = version >= 3 or "data_digest" in a
            required = ATTRS + ("digest",) + (("block_rows", "data_digest") if self.digested else ())
            missing = [k for k in required if k not in a]
            if missing or "particles" not in self.f:
                raise ParmpmError(f"{where}: damaged: missing {', '.join(missing) or 'particles group'}")
            keys = [k for k in a if k != "digest"] if self.digested else list(ATTRS)
            if attrs_digest({k: a[k] for k in keys}) != a["digest"]:
                raise ParmpmError(f"{where}: damaged: its attributes (scene, clock) fail their checksum")
            self.attrs = {k: a[k] for k in ATTRS + ("lineage",) if k in a}
            self._attrs_all = a
            self._check_datasets(where)
            if self.digested:
                self._load_digests(where)
            elif warn:
                logger.warning("%s has format version %d: its data carry no digests, only HDF5's "
                               "Fletcher-32 chunk checksums", where, version)
        except ParmpmError:
            self.close()
            raise
        except Exception as exc:  # h5py reports damaged metadata in many ways
            self.close()
            raise ParmpmError(f"{where}: damaged ({type(exc).__name__}: "
                              f"{(str(exc).splitlines() or ['unreadable'])[0]})") from None

    def _check_datasets(self, where: str) -> None:
        self.n = int(self.attrs["particles"])
        d = int(self.attrs["dim"])
        expected = {"gid": (), "mat": (), "mass": (), "vol0": (), "damage": (),
                    "x": (d,), "v": (d,), "x0": (d,), "lh0": (d,),
                    "F": (d, d), "stress": (d, d), "r0": (d, d)}
        if self.version >= 2 or self.digested:
            expected["rf"] = (d, d)
        g = self.f["particles"]
        self._datasets = {name: g[name] for name in g}
        for name, tail in expected.items():
            ds = self._datasets.get(name)
            if ds is None or ds.shape != (self.n,) + tail:
                got = "nothing" if ds is None else ds.shape
                raise ParmpmError(f"{where}: damaged: dataset particles/{name} is {got}, "
                                  f"expected {(self.n,) + tail}")
            if ds.dtype != DTYPES[name]:
                raise ParmpmError(f"{where}: damaged: dataset particles/{name} is of type "
                                  f"{ds.dtype}, expected {DTYPES[name]}")

    def _load_digests(self, where: str) -> None:
        """Read every digest table and check them all against ``data_digest``."""
        self.block_rows = int(self._attrs_all["block_rows"])
        if self.block_rows < 1:
            raise ParmpmError(f"{where}: damaged: block_rows = {self.block_rows}")
        nblocks = -(-self.n // self.block_rows)
        g = self.f.get("digests")
        self._digests = {}
        for name in self._datasets:
            t = g.get(name) if g is not None else None
            if t is None or t.shape != (nblocks, 32) or t.dtype != np.uint8:
                got = "nothing" if t is None else f"{t.shape} {t.dtype}"
                raise ParmpmError(f"{where}: damaged: digests/{name} is {got}, expected "
                                  f"({nblocks}, 32) uint8")
            self._digests[name] = t[()]
        if _tables_digest(self._digests) != self._attrs_all["data_digest"]:
            raise ParmpmError(f"{where}: damaged: its data digests fail their checksum")

    @property
    def state(self) -> dict:
        return json.loads(str(self.attrs["state"]))

    def has(self, name: str) -> bool:
        """Whether the file holds ``particles/name`` (version 1 files have no ``rf``)."""
        return name in self._datasets

    def read(self, name: str, lo: int = 0, hi: int | None = None) -> np.ndarray:
        """Rows ``lo..hi`` of ``particles/name``, checked: the whole digest blocks they touch are
        read and verified (aligned reads of whole blocks cost nothing extra)."""
        hi = self.n if hi is None else min(int(hi), self.n)
        lo = max(0, min(int(lo), hi))
        try:
            if not self.digested:
                return self._datasets[name][lo:hi]
            B = self.block_rows
            k0, k1 = lo // B, -(-hi // B)
            a = k0 * B
            data = self._datasets[name][a:min(k1 * B, self.n)]
        except Exception as exc:  # a Fletcher-32 mismatch, or damaged chunk index
            raise ParmpmError(f"{self.where}: damaged data in particles/{name} "
                              f"({type(exc).__name__}: {(str(exc).splitlines() or ['unreadable'])[0]})"
                              ) from None
        table = self._digests[name]
        for k in range(k0, k1):
            if _block_digest(name, k, data[k * B - a:(k + 1) * B - a]) != table[k].tobytes():
                raise ParmpmError(f"{self.where}: damaged data in particles/{name}: rows "
                                  f"{k * B}..{min((k + 1) * B, self.n) - 1} fail their digest")
        return data[lo - a:hi - a]

    def close(self) -> None:
        self._datasets = {}
        if self.f is not None:
            f, self.f = self.f, None
            f.close()


def read_lineage(path: Path) -> str | None:
    """The ``lineage`` attribute of a checkpoint, cheaply (one attribute; no checks); None when
    it has none. Raises OSError (or h5py's errors) for an unreadable file."""
    import h5py

    with h5py.File(path, "r") as f:
        if f.attrs.get("format") != FORMAT:
            raise OSError(f"'{path}' is not a parmpm checkpoint")
        v = f.attrs.get("lineage")
        return None if v is None else str(v)


def prune(folder: Path, keep: int, lineage: str | None = None) -> list[Path]:
    """Delete all but the newest ``keep`` checkpoints (by step) of ``lineage`` in ``folder``;
    ``lineage=None`` means the checkpoints that carry no lineage. Files of another lineage, and
    files that cannot be read, are never deleted. Returns the deleted paths."""
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
        try:
            old.unlink()
            gone.append(old)
        except FileNotFoundError:
            pass
    return gone


def remove_stale_tmp(folder: Path) -> list[Path]:
    """Delete the temporary files an interrupted writer left in ``folder``: checkpoints
    (``checkpoint_*.h5.tmp``) and snapshot indexes (``*.xdmf.tmp``). Returns them."""
    gone = []
    folder = Path(folder)
    if not folder.is_dir():
        return gone
    for pattern in ("checkpoint_*.h5.tmp", "*.xdmf.tmp"):
        for p in sorted(folder.glob(pattern)):
            if p.is_file() and not p.is_symlink():
                p.unlink(missing_ok=True)
                gone.append(p)
    return gone
