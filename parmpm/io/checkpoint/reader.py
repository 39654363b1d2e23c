"""Reading a checkpoint of any format version back, every row checked: the top-level file's
attributes, index and part table validated on open, each part opened and validated the first time
its rows are read, and rows read by whole digest segments (:mod:`parmpm.io.checkpoint.data_file`).
Which rows each rank reads on restart is :mod:`parmpm.driver.checkpoint_writer`'s.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from parmpm.core.errors import ParmpmError
from parmpm.io.checkpoint.data_file import (RowFile, check_fields, first_line, open_h5,
                                            read_tables, segment_tables)
from parmpm.io.checkpoint.digests import arrays_digest, attrs_digest, tables_digest
from parmpm.io.checkpoint.format import ATTRS, FORMAT, PART_FORMAT, VERSION, required_fields
from parmpm.io.checkpoint.parts import layout_record
from parmpm.io.checkpoint.paths import inside, part_paths

logger = logging.getLogger("parmpm.io.checkpoint")


class CheckpointReader:
    """An open, validated checkpoint of any version; every problem is a one-line ParmpmError
    naming the file (and, for a part, the part file). ``rows_read``: rows read per field.

    ``warn``: log a warning when the file's data carry no digests (versions 1 and 2); pass
    ``warn=rank == 0`` so that a restart on many ranks says it once."""

    def __init__(self, path, warn: bool = True):
        self.path = Path(path)
        where = self.where = f"checkpoint '{self.path}'"
        self.f, self._parts, self.rows_read = None, {}, {}
        self.f = open_h5(self.path, where)
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
            raise ParmpmError(f"{where}: damaged ({type(exc).__name__}: {first_line(exc)})") from None

    # --- versions 1-3: one file in global-id order ----------------------------------------------
    def _open_v3(self, where: str, warn: bool) -> None:
        self._datasets = check_fields(self.f, where, self.n, self.dim,
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
            digests = {k[len("digests/"):]: t for k, t in read_tables(self.f, where, shapes, shapes).items()}
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
        tables = read_tables(self.f, where, ("index/patch_rows", "parts/rows", "parts/file",
                                             "parts/digest"),
                             {"index/patch_rows": ((n_patches, 2), i64), "parts/rows": ((k, 2), i64)})
        names = [bytes(s).decode() for s in tables["parts/file"]]
        inline = names == ["."]
        self._datasets = check_fields(self.f, where, self.n, self.dim,
                                      required_fields(self.version))
        if inline:
            bounds, digests = segment_tables(self.f, where, self.n, self._datasets)
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
        f = open_h5(path, where)
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
            datasets = check_fields(f, where, rows, self.dim, required_fields(self.version))
            bounds, digests = segment_tables(f, where, rows, datasets)
            if arrays_digest({**digests, "segments": bounds}) != a.get("data_digest"):
                raise ParmpmError(f"{where}: damaged: its digests fail their checksum")
        except ParmpmError:
            raise
        except Exception as exc:  # noqa: BLE001 - h5py reports damaged metadata in many ways
            raise ParmpmError(f"{where}: damaged ({type(exc).__name__}: {first_line(exc)})") from None
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
