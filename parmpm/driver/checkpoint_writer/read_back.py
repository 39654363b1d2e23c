"""Reading a checkpoint back on restart (collective): exactly the rows of this rank's patches
(version 4, by the patch index), or given rows (versions 1–3, whose rows are global ids, or a
restart that changed the patch grid); a damaged part found by one rank stops every rank."""
from __future__ import annotations

import numpy as np

from parmpm.core.collective import agree
from parmpm.core.errors import ParmpmError
from parmpm.driver.checkpoint_writer.rows import BLOCK
from parmpm.io.checkpoint.format import DTYPES, FIELDS
from parmpm.particles.store import OPTIONAL_FIELDS, Particles


def _check_loaded(reader, P: Particles, n_materials: int) -> None:
    if P.n and (P.gid.min() < 0 or P.gid.max() >= reader.n):
        raise ParmpmError(f"checkpoint '{reader.path}': damaged: particle ids out of range")
    if P.n and (P.mat.min() < 0 or P.mat.max() >= n_materials):
        raise ParmpmError(f"checkpoint '{reader.path}': particles of material row "
                          f"{int(P.mat.max())}, but the scene has {n_materials} material(s): "
                          "materials cannot be added or removed on restart")


def _optional(reader) -> tuple[str, ...]:
    return tuple(k for k in OPTIONAL_FIELDS if reader.has(k))


def load_patches(comm, reader, dim: int, n_materials: int, patch_ids: np.ndarray) -> Particles:
    """Version 4: exactly the rows of ``patch_ids`` (by the index), with ``patch`` set, in the
    file's order (each patch's rows by id; the stepper groups them by patch anyway), collective:
    a damaged part found by one rank stops every rank."""
    problem = None
    ids = np.asarray(patch_ids, np.int64)
    ranges = reader.patch_rows[ids]
    ids, ranges = ids[ranges[:, 1] > 0], ranges[ranges[:, 1] > 0]
    o = np.argsort(ranges[:, 0], kind="stable")
    ids, ranges = ids[o], ranges[o]
    P = Particles(dim, int(ranges[:, 1].sum()), _optional(reader))
    try:
        for name in FIELDS:  # the arrays read become the fields (no copy)
            if not reader.has(name):  # an older format: the field keeps its initial value
                continue
            setattr(P, name, reader.read_ranges(name, ranges).astype(DTYPES[name].newbyteorder("="),
                                                                     copy=False))
        P.patch = np.repeat(ids, ranges[:, 1])
        _check_loaded(reader, P, n_materials)
    except ParmpmError as exc:
        problem = str(exc)
    agree(comm, problem, root=None)
    return P


def load_rows(comm, reader, dim: int, n_materials: int, rows: np.ndarray,
              patch: np.ndarray | None = None) -> Particles:
    """The file's rows ``rows`` (ascending; versions 1–3: global ids), ``patch`` (of each row)
    set (collective). Versions 1–3 are read in blocks of 2^18 rows, version 4 by runs of
    consecutive rows."""
    problem = None
    rows = np.asarray(rows, np.int64)
    P = Particles(dim, rows.size, _optional(reader))
    if patch is not None:
        P.patch = np.asarray(patch, np.int64).copy()
    try:
        if reader.version >= 4:
            cut = np.flatnonzero(np.diff(rows) != 1) + 1
            starts = rows[np.r_[0, cut]] if rows.size else rows
            counts = np.diff(np.r_[0, cut, rows.size]) if rows.size else rows
            ranges = np.stack([starts, counts], axis=1)
            for name in FIELDS:
                if reader.has(name):  # an older format: the field keeps its initial value
                    getattr(P, name)[:] = reader.read_ranges(name, ranges)
        else:
            for name in FIELDS:
                if not reader.has(name):  # an older format: the field keeps its initial value
                    continue
                dst = getattr(P, name)
                for lo in range(0, reader.n, BLOCK):
                    hi = min(lo + BLOCK, reader.n)
                    a, b = np.searchsorted(rows, [lo, hi])
                    if b > a:
                        dst[a:b] = reader.read(name, lo, hi)[rows[a:b] - lo]
            if not np.array_equal(P.gid, rows):
                raise ParmpmError(f"checkpoint '{reader.path}': damaged: particle ids out of order")
        _check_loaded(reader, P, n_materials)
    except ParmpmError as exc:
        problem = str(exc)
    agree(comm, problem, root=None)
    return P
