"""A checkpoint as one: the top-level file that binds the part files (HDF5 virtual datasets, the
patch index, the part table), the rules that group ranks into parts, and the reader of every
format version (the rows' format and its checks are :mod:`parmpm.io.checkpoint`'s).

Schema of the top-level file, version 4 (format ``parmpm-checkpoint``)::

    /                   attrs: format, version, scene, step, time, dt, vmax, method, lcr, ranks,
                        particles, dim, state, lineage, block_rows, layout (JSON: the patch
                        grid: cells, patch_size, ghost, origin, h), part_files, ranks_per_file,
                        data_digest, digest
    /particles/<field>  (N, ...) every particle, rows in rank order: virtual datasets over the
                        parts' ``particles/<field>`` (relative file names), or, written by one
                        writer, the data themselves (then also ``segments`` and ``digests``)
    /index/patch_rows   (n_patches, 2) int64: each patch's first row and row count
    /parts/file         (K,) bytes: part file names relative to this file's folder ("." = here)
    /parts/rows         (K, 2) int64: each part's first row and row count
    /parts/digest       (K,) bytes: each part's ``digest`` attribute (empty for ".")

A part is what one group of ranks wrote (:func:`ranks_per_file`): its lead gathers the members'
rows in rank order. Rows are in rank order, not global-id order, because a rank's particles are
not a contiguous range of ids after migration: a virtual dataset in id order would map one row
at a time. With the ``gid`` column and the index, h5py users sort by ``gid``, and a restart reads
each patch's rows as one contiguous range of one part.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from parmpm.core.errors import ParmpmError
from parmpm.io.checkpoint import (ATTRS, DTYPES, FORMAT, OPTIONAL, PART_FORMAT, VERSION,
                                  CheckpointWriter, arrays_digest, attrs_digest, block_digest,
                                  required_fields, tables_digest)
from parmpm.io.checkpoint_paths import inside, part_paths

logger = logging.getLogger("parmpm.io.checkpoint")

#: ``checkpoint.ranks_per_file = "auto"``: one part per rank up to this many ranks, then groups
#: of consecutive ranks so that a checkpoint never has more part files
MAX_PARTS = 256


def ranks_per_file(size: int, setting) -> int:
    """Ranks per part file: ``"auto"`` → ⌈size / MAX_PARTS⌉ (one file per rank up to 256 ranks,
    at most 256 files beyond), else the integer given (at most ``size``: one file)."""
    if setting == "auto":
        return max(1, -(-size // MAX_PARTS))
    return max(1, min(int(setting), size))


def layout_record(disc) -> str:
    """The patch grid a checkpoint's index refers to (JSON; floats round-trip exactly)."""
    lay = disc.layout
    return json.dumps({"cells": [int(c) for c in lay.cells],
                       "patch_size": [int(p) for p in lay.patch_size], "ghost": int(lay.ghost),
                       "origin": [float(v) for v in disc.origin3], "h": [float(v) for v in disc.h3]})


def rank_rows(all_patches, n_patches: int):
    """(first row of each rank, ``patch_rows``) from every rank's (patch ids, row counts), in
    rank order: rows are in rank order, a rank's by patch (and id)."""
    sizes = np.array([int(np.sum(c)) for _, c in all_patches], np.int64)
    first = np.concatenate([[0], np.cumsum(sizes)])
    index = np.zeros((n_patches, 2), np.int64)
    for r, (ids, c) in enumerate(all_patches):
        c = np.asarray(c, np.int64)
        index[np.asarray(ids, np.int64), 0] = first[r] + np.concatenate([[0], np.cumsum(c)[:-1]])
        index[np.asarray(ids, np.int64), 1] = c
    return first, index


def top_tables(index: np.ndarray, bounds, files: list) -> dict:
    """The top-level file's tables: the patch index, and the part table of ``files`` ((name,
    digest) each) whose rows start at ``bounds`` (K+1 offsets)."""
    bounds = np.asarray(bounds, np.int64)
    return {"index/patch_rows": np.asarray(index, np.int64),
            "parts/rows": np.stack([bounds[:-1], np.diff(bounds)], axis=1).astype(np.int64),
            "parts/file": np.array([f.encode() for f, _ in files], dtype="S"),
            "parts/digest": np.array([(d or "").encode() for _, d in files], dtype="S")}


def write_top(path: Path, attrs: dict, like: dict, parts: list, n: int, tables: dict) -> None:
    """The top-level file of a checkpoint in parts (atomic): a virtual dataset per field over
    ``parts`` (relative file name, first row, rows), and ``tables`` (index, part table)."""
    import h5py

    w = CheckpointWriter(path, 0, {}, attrs, fmt=FORMAT,
                         extra_bytes=sum(t.nbytes for t in tables.values()) + 512 * len(parts)
                         * len(like))
    try:
        for name, a in like.items():
            tail = a.shape[1:]
            vl = h5py.VirtualLayout(shape=(n,) + tail, dtype=DTYPES[name])
            for file, lo, m in parts:
                if m:
                    vl[lo:lo + m] = h5py.VirtualSource(file, f"particles/{name}", shape=(m,) + tail)
            w.f.create_virtual_dataset(f"particles/{name}", vl)
    except Exception as exc:  # noqa: BLE001 - _fail re-raises what is not an I/O error
        w._fail(exc)
    w.commit(tables)


class RowFile:
    """The rows of one data file, read by whole segments and checked against their digests
    (``digests`` None: versions 1 and 2, unchecked). ``counter``: rows read per field."""

    def __init__(self, where: str, datasets: dict, n: int, bounds, digests, counter: dict):
        self.where, self.datasets, self.n = where, datasets, int(n)
        self.bounds, self.digests, self.counter = bounds, digests, counter

    def read(self, name: str, lo: int, hi: int) -> np.ndarray:
        lo, hi = int(lo), int(hi)
        if hi <= lo:
            return self.datasets[name][0:0]
        b = self.bounds
        k0, k1 = lo, hi
        if self.digests is not None:
            k0 = int(np.searchsorted(b, lo, side="right")) - 1
            k1 = int(np.searchsorted(b, hi, side="left"))
            a, z = int(b[k0]), int(b[k1])
        else:
            a, z = lo, hi
        try:
            data = self.datasets[name][a:z]
        except Exception as exc:  # a damaged chunk index or Fletcher-32 mismatch
            raise ParmpmError(f"{self.where}: damaged data in particles/{name} "
                              f"({type(exc).__name__}: {(str(exc).splitlines() or ['unreadable'])[0]})"
                              ) from None
        self.counter[name] = self.counter.get(name, 0) + (z - a)
        if self.digests is not None:
            table = self.digests[name]
            for k in range(k0, k1):
                s, e = int(b[k]) - a, int(b[k + 1]) - a
                if block_digest(name, k, data[s:e]) != table[k].tobytes():
                    raise ParmpmError(f"{self.where}: damaged data in particles/{name}: rows "
                                      f"{s + a}..{e + a - 1} fail their digest")
        return data[lo - a:hi - a]


def _first_line(exc: BaseException) -> str:
    return (str(exc).splitlines() or ["unreadable"])[0]


def _open_h5(path: Path, where: str):
    import h5py

    if not path.is_file():
        raise ParmpmError(f"{where}: no such file")
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        raise ParmpmError(f"{where}: not a readable HDF5 file (truncated or damaged?): "
                          f"{_first_line(exc)}") from None
    except Exception as exc:  # noqa: BLE001 - h5py reports a damaged superblock in many ways
        raise ParmpmError(f"{where}: not a readable HDF5 file (damaged?): "
                          f"{type(exc).__name__}") from None


def _check_fields(f, where: str, n: int, d: int, names) -> dict:
    """``particles/<field>`` of ``f``: every field of ``names`` there, and the optional ones
    it holds, of shape (n, ...) and its type."""
    tails = {"x": (d,), "v": (d,), "x0": (d,), "lh0": (d,), "F": (d, d), "stress": (d, d),
             "r0": (d, d), "rf": (d, d), "affine": (d, d), "corners": (1 << d, d)}
    g = f.get("particles")
    if g is None:
        raise ParmpmError(f"{where}: damaged: missing particles group")
    found = {name: g[name] for name in g}
    for name in tuple(names) + tuple(k for k in OPTIONAL if k in found):
        ds, shape = found.get(name), (n,) + tails.get(name, ())
        if ds is None or ds.shape != shape:
            got = "nothing" if ds is None else ds.shape
            raise ParmpmError(f"{where}: damaged: dataset particles/{name} is {got}, expected {shape}")
        if ds.dtype != DTYPES[name]:
            raise ParmpmError(f"{where}: damaged: dataset particles/{name} is of type "
                              f"{ds.dtype}, expected {DTYPES[name]}")
    return found


def _tables(f, where: str, names, shapes: dict) -> dict:
    out = {}
    for name in names:
        t = f.get(name)
        want = shapes.get(name)
        if t is None or (want is not None and (t.shape, t.dtype) != want):
            got = "nothing" if t is None else f"{t.shape} {t.dtype}"
            raise ParmpmError(f"{where}: damaged: {name} is {got}" +
                              (f", expected {want[0]} {want[1]}" if want else ""))
        out[name] = t[()]
    return out


def _segment_tables(f, where: str, n: int, fields) -> tuple[np.ndarray, dict]:
    """A version-4 data file's segment offsets and digest tables (not yet checksummed)."""
    seg = f.get("segments")
    if seg is None or seg.ndim != 1 or seg.dtype != np.int64:
        raise ParmpmError(f"{where}: damaged: segments is {'nothing' if seg is None else seg.shape}")
    bounds = seg[()]
    if bounds.size < 1 or bounds[0] != 0 or bounds[-1] != n or np.any(np.diff(bounds) <= 0):
        raise ParmpmError(f"{where}: damaged: segments do not rise from 0 to {n}")
    shapes = {f"digests/{k}": ((bounds.size - 1, 32), np.dtype(np.uint8)) for k in fields}
    return bounds, _tables(f, where, shapes, shapes)


class CheckpointReader:
    """An open, validated checkpoint of any version; every problem is a one-line ParmpmError
    naming the file (and, for a part, the part file). ``rows_read``: rows read per field.

    ``warn``: log a warning when the file's data carry no digests (versions 1 and 2); pass
    ``warn=rank == 0`` so that a restart on many ranks says it once."""

    def __init__(self, path, warn: bool = True):
        self.path = Path(path)
        where = self.where = f"checkpoint '{self.path}'"
        self.f, self._parts, self.rows_read = None, {}, {}
        self.f = _open_h5(self.path, where)
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
            extra = ("block_rows", "data_digest") if self.digested else ()
            extra += ("layout", "part_files") if version >= 4 else ()
            missing = [k for k in ATTRS + ("digest",) + extra if k not in a]
            if missing:
                raise ParmpmError(f"{where}: damaged: missing {', '.join(missing)}")
            keys = [k for k in a if k != "digest"] if self.digested else list(ATTRS)
            if attrs_digest({k: a[k] for k in keys}) != a["digest"]:
                raise ParmpmError(f"{where}: damaged: its attributes (scene, clock) fail their checksum")
            self.attrs = {k: a[k] for k in ATTRS + ("lineage",) if k in a}
            self._attrs_all = a
            self.n, self.dim = int(a["particles"]), int(a["dim"])
            if version >= 4:
                self._open_v4(where)
            else:
                self._open_v3(where, warn)
        except ParmpmError:
            self.close()
            raise
        except Exception as exc:  # noqa: BLE001 - h5py reports damaged metadata in many ways
            self.close()
            raise ParmpmError(f"{where}: damaged ({type(exc).__name__}: {_first_line(exc)})") from None

    # --- versions 1-3: one file in global-id order ----------------------------------------------
    def _open_v3(self, where: str, warn: bool) -> None:
        self._datasets = _check_fields(self.f, where, self.n, self.dim,
                                       required_fields(max(self.version, 2 if self.digested else 1)))
        self.patch_rows, self.layout = None, None
        bounds = digests = None
        if self.digested:
            B = int(self._attrs_all["block_rows"])
            if B < 1:
                raise ParmpmError(f"{where}: damaged: block_rows = {B}")
            bounds = np.unique(np.minimum(np.arange(0, self.n + B, B), self.n))
            shapes = {f"digests/{k}": ((bounds.size - 1, 32), np.dtype(np.uint8))
                      for k in self._datasets}
            digests = {k[len("digests/"):]: t for k, t in _tables(self.f, where, shapes, shapes).items()}
            if tables_digest(digests) != self._attrs_all["data_digest"]:
                raise ParmpmError(f"{where}: damaged: its data digests fail their checksum")
        elif warn:
            logger.warning("%s has format version %d: its data carry no digests, only HDF5's "
                           "Fletcher-32 chunk checksums", where, self.version)
        self._files = [RowFile(where, self._datasets, self.n, bounds, digests, self.rows_read)]
        self._part_rows = np.array([[0, self.n]], np.int64)

    # --- version 4: rows in rank order, a patch index, parts -------------------------------------
    def _open_v4(self, where: str) -> None:
        a = self._attrs_all
        self.layout = json.loads(str(a["layout"]))
        n_patches = int(np.prod([-(-c // p) for c, p in zip(self.layout["cells"],
                                                              self.layout["patch_size"])]))
        k = int(a["part_files"])
        i64 = np.dtype(np.int64)
        tables = _tables(self.f, where, ("index/patch_rows", "parts/rows", "parts/file",
                                         "parts/digest"),
                         {"index/patch_rows": ((n_patches, 2), i64), "parts/rows": ((k, 2), i64)})
        names = [bytes(s).decode() for s in tables["parts/file"]]
        inline = names == ["."]
        self._datasets = _check_fields(self.f, where, self.n, self.dim,
                                       required_fields(self.version))
        if inline:
            bounds, digests = _segment_tables(self.f, where, self.n, self._datasets)
            tables.update(digests, segments=bounds)
        if arrays_digest(tables) != a["data_digest"]:
            raise ParmpmError(f"{where}: damaged: its index and digests fail their checksum")
        rows, index = tables["parts/rows"], tables["index/patch_rows"]
        if (len(tables["parts/digest"]) != k or np.any(rows[:, 1] < 0) or rows[0, 0] != 0
                or np.any(rows[1:, 0] != np.cumsum(rows[:, 1])[:-1]) or rows[:, 1].sum() != self.n):
            raise ParmpmError(f"{where}: damaged: its part table does not cover {self.n} rows")
        part = np.searchsorted(rows[:, 0], index[:, 0], side="right") - 1
        used = index[:, 1] > 0
        if (index[:, 1].sum() != self.n or np.any(index[used, 0] < 0) or np.any(
                index[used, 0] + index[used, 1] > rows[part[used], 0] + rows[part[used], 1])):
            raise ParmpmError(f"{where}: damaged: its patch index does not match its parts")
        self.patch_rows, self._part_rows = index, rows
        self._part_names, self._part_digests = names, [bytes(s).decode() for s in tables["parts/digest"]]
        self._part_paths = [] if inline else part_paths(self.path, names, where)
        self._files = [None] * k
        if inline:
            digests = {name[len("digests/"):]: t for name, t in digests.items()}
            self._files[0] = RowFile(where, self._datasets, self.n, bounds, digests, self.rows_read)
        else:
            self._check_virtual(where)

    def _check_virtual(self, where: str) -> None:
        """Each field's virtual dataset maps the parts as the part table says."""
        want = sorted((self._part_names[p], int(lo), int(lo + m - 1))
                      for p, (lo, m) in enumerate(self._part_rows) if m)
        for name, ds in self._datasets.items():
            got = sorted((m.file_name, int(m.vspace.get_select_bounds()[0][0]),
                          int(m.vspace.get_select_bounds()[1][0])) for m in ds.virtual_sources()
                         if m.dset_name == f"particles/{name}") if ds.is_virtual else None
            if got != want:
                raise ParmpmError(f"{where}: damaged: particles/{name} does not map its part files")

    def _part(self, p: int) -> RowFile:
        """Part ``p``, opened and checked the first time it is read."""
        if self._files[p] is not None:
            return self._files[p]
        path = self._part_paths[p]
        where = f"{self.where}: part '{path}'"
        inside(path, where)
        f = _open_h5(path, where)
        self._parts[p] = f
        try:
            a = dict(f.attrs)
            first, rows = (int(v) for v in self._part_rows[p])
            if a.get("format") != PART_FORMAT or int(a.get("version", -1)) != self.version:
                raise ParmpmError(f"{where}: not a part of a version-{self.version} checkpoint")
            if ("digest" not in a or a["digest"] != self._part_digests[p]
                    or attrs_digest({k: v for k, v in a.items() if k != "digest"}) != a["digest"]):
                raise ParmpmError(f"{where}: damaged, or a part of another checkpoint (its "
                                  "attributes fail their checksum)")
            if (int(a.get("part", -1)), int(a.get("first_row", -1)), int(a.get("rows", -1))) != \
                    (p, first, rows):
                raise ParmpmError(f"{where}: damaged: not part {p} of this checkpoint")
            datasets = _check_fields(f, where, rows, self.dim, required_fields(self.version))
            bounds, digests = _segment_tables(f, where, rows, datasets)
            if arrays_digest({**digests, "segments": bounds}) != a.get("data_digest"):
                raise ParmpmError(f"{where}: damaged: its digests fail their checksum")
        except ParmpmError:
            raise
        except Exception as exc:  # noqa: BLE001 - h5py reports damaged metadata in many ways
            raise ParmpmError(f"{where}: damaged ({type(exc).__name__}: {_first_line(exc)})") from None
        digests = {name[len("digests/"):]: t for name, t in digests.items()}
        self._files[p] = RowFile(where, datasets, rows, bounds, digests, self.rows_read)
        return self._files[p]

    # --- reading ----------------------------------------------------------------------------------
    @property
    def state(self) -> dict:
        return json.loads(str(self.attrs["state"]))

    def has(self, name: str) -> bool:
        """Whether the file holds ``particles/name`` (version 1 files have no ``rf``, versions
        before 5 no ``affine``; ``affine`` and ``corners`` only when the run carried them)."""
        return name in self._datasets

    def read(self, name: str, lo: int = 0, hi: int | None = None) -> np.ndarray:
        """Rows ``lo..hi`` of ``particles/name`` in the file's row order (versions 1-3: global
        ids; 4: rank order), checked: the whole segments they touch are read and verified."""
        hi = self.n if hi is None else min(int(hi), self.n)
        lo = max(0, min(int(lo), hi))
        first, m = self._part_rows[:, 0], self._part_rows[:, 1]
        p0 = int(np.searchsorted(first + m, lo, side="right"))
        p1 = int(np.searchsorted(first, hi, side="left"))
        out = [self._part(p).read(name, max(lo, first[p]) - first[p], min(hi, first[p] + m[p])
                                  - first[p]) for p in range(p0, p1) if m[p]]
        if not out:
            ds = self._datasets[name]
            return np.zeros((0,) + ds.shape[1:], ds.dtype)
        return out[0] if len(out) == 1 else np.concatenate(out)

    def read_ranges(self, name: str, ranges: np.ndarray) -> np.ndarray:
        """The rows of ``ranges`` ((R, 2): first row, count; ascending, disjoint), concatenated;
        adjacent ranges are read as one."""
        ranges = np.asarray(ranges, np.int64).reshape(-1, 2)
        ranges = ranges[ranges[:, 1] > 0]
        if ranges.size == 0:
            return self.read(name, 0, 0)
        ends = ranges[:, 0] + ranges[:, 1]
        cut = np.flatnonzero(ranges[1:, 0] != ends[:-1]) + 1
        starts, stops = ranges[np.r_[0, cut], 0], ends[np.r_[cut - 1, len(ranges) - 1]]
        parts = [self.read(name, a, b) for a, b in zip(starts, stops)]
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def patch_counts(self) -> np.ndarray | None:
        """Particles per patch of the stored layout (version 4; None before)."""
        return None if self.patch_rows is None else self.patch_rows[:, 1].copy()

    def indexed_for(self, disc) -> bool:
        """Whether the patch index refers to ``disc``'s patch grid (the scene's, unless the
        restart overrides the grid or the patch size)."""
        return self.layout is not None and self.layout == json.loads(layout_record(disc))

    def close(self) -> None:
        self._datasets, self._files = {}, []
        for f in [self.f, *self._parts.values()]:
            if f is not None:
                f.close()
        self.f, self._parts = None, {}
