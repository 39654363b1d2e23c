"""A checkpoint written by every rank into one file through h5py's MPI-IO driver, where h5py is
built with MPI (PyPI's wheels are not): the schema of a one-writer checkpoint (rows in rank
order, the index, segment digests), no gathering at a lead.

Parallel HDF5 wants every metadata call (creating datasets, writing attributes, closing) made by
every rank with the same values: the attributes are rank 0's (broadcast), and a rank whose own
(independent) row writes fail keeps the error until every rank has written, so all ranks close
the file together and raise the same line. A rank writes its rows in blocks of whole segments of
about :data:`parmpm.driver.checkpoint_writer.rows.BLOCK` rows (one copy of a block, never of a
field; no single MPI-IO request above 2 GiB).
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np

import parmpm.io.checkpoint.space as space
from parmpm.core.collective import agree
from parmpm.core.errors import ParmpmError
from parmpm.driver.checkpoint_writer.rows import BLOCK
from parmpm.io.checkpoint.cleanup import prune
from parmpm.io.checkpoint.digests import arrays_digest, attrs_digest, block_digest
from parmpm.io.checkpoint.format import (BLOCK_ROWS, DTYPES, FORMAT, LIBVER, VERSION,
                                         segments_of)
from parmpm.io.checkpoint.parts import top_tables
from parmpm.io.checkpoint.paths import parts_folder
from parmpm.io.checkpoint.writer import fsync_folder
from parmpm.io.guarded_file import space_message


def mpio(comm) -> bool:
    """Whether h5py can write one file from all ranks (built with MPI, and a real MPI run)."""
    if comm.Get_size() == 1 or not hasattr(comm, "Send"):
        return False
    try:
        import h5py

        return bool(h5py.get_config().mpi)
    except Exception:  # noqa: BLE001 - no h5py: the writer will say so
        return False


def write_collective(comm, P, order, path, top, like, all_patches, first, index, keep, lineage,
                     driver="mpio") -> Path:
    """Every rank writes its rows into ``path`` (through ``<path>.tmp``), then rank 0 fsyncs
    and renames it and prunes this run's older checkpoints. ``driver=None`` on one rank runs
    the same code serially (the tests' only way to run it with PyPI's h5py;
    tests/io/test_parallel_hdf5.py runs the driver itself where a parallel HDF5 is installed). No
    :class:`parmpm.io.guarded_file.GuardedFile` here (MPI-IO writes the file): the free space
    is checked first."""
    rank = comm.Get_rank()
    tmp = _tmp(path)
    segs = [segments_of(np.asarray(c, np.int64)) for _, c in all_patches]
    bounds = np.concatenate([[0]] + [s[1:] + first[r] for r, s in enumerate(segs)]).astype(np.int64)
    top = comm.bcast({**top, "part_files": 1, "ranks_per_file": comm.Get_size(),
                      "format": FORMAT}, root=0)
    agree(comm, _space_problem(path, like, top, bounds, first, index) if rank == 0 else None)
    problem = None
    try:
        problem = _write_file(comm, P, order, path, top, like, segs, bounds, first, index,
                              driver)
        comm.Barrier()
        if rank == 0 and problem is None:
            _publish(tmp, path, keep, lineage)
    except ParmpmError as exc:
        problem = str(exc)
    except OSError as exc:
        problem = space.os_problem(path, exc)
    if problem is not None and rank == 0:
        tmp.unlink(missing_ok=True)
    agree(comm, problem, root=None)
    return path


def _tmp(path: Path) -> Path:
    return path.with_name(path.name + ".tmp")


def _space_problem(path: Path, like: dict, top: dict, bounds, first, index) -> str | None:
    """Rank 0: whether the file fits the free space (a problem, or None)."""
    try:
        need = space.estimate_bytes(int(first[-1]), like, top, segments=bounds.size - 1,
                                    extra=index.nbytes)
        free = space.free_bytes(path.parent)
        return space_message(path, need, free) if need > free else None
    except OSError as exc:
        return space.os_problem(path, exc)


def _write_file(comm, P, order, path: Path, top: dict, like: dict, segs, bounds, first, index,
                driver) -> str | None:
    """Create ``<path>.tmp`` on every rank, write this rank's rows, and, when no rank had a
    problem, the tables and attributes (every rank, the same calls). ``segs``: every rank's
    segment offsets; ``bounds``: the file's. Returns the first rank's problem."""
    import h5py

    rank = comm.Get_rank()
    seg_first = np.concatenate([[0], np.cumsum([s.size - 1 for s in segs])])
    kw = {"driver": driver, "comm": comm} if driver else {}
    with h5py.File(_tmp(path), "w", libver=LIBVER, **kw) as f:
        ds = {name: f.create_dataset(f"particles/{name}", shape=(int(first[-1]),) + a.shape[1:],
                                     dtype=DTYPES[name]) for name, a in like.items()}
        problem, mine = _write_mine(path, P, order, ds, segs[rank], int(first[rank]),
                                    int(seg_first[rank]))
        gathered = comm.allgather((problem, [mine[k] for k in like]))
        problem = next((p for p, _ in gathered if p), None)
        if problem is None:
            tables = top_tables(index, np.array([0, int(first[-1])]), [(".", "")])
            tables["segments"] = bounds
            for name, parts in zip(like, zip(*(d for _, d in gathered))):
                tables[f"digests/{name}"] = np.frombuffer(b"".join(parts), np.uint8).reshape(-1, 32)
            _write_tables(f, rank, top, tables)
    return problem


def _write_mine(path: Path, P, order, ds: dict, s: np.ndarray, lo: int, k_first: int):
    """This rank's rows, written; (its problem or None, each field's segment digests). A
    problem is kept, not raised: raised alone, it would hang the other ranks."""
    try:
        return None, _write_rows(P, order, ds, s, lo, k_first)
    except ParmpmError as exc:
        problem = str(exc)
    except OSError as exc:
        problem = space.os_problem(path, exc)
    except Exception as exc:  # noqa: BLE001 - raised alone, it would hang the others
        problem = (f"cannot write checkpoint '{path}': {type(exc).__name__}: "
                   f"{(str(exc).splitlines() or ['error'])[0]}")
    return problem, {name: b"" for name in ds}


def _write_tables(f, rank: int, top: dict, tables: dict) -> None:
    """The tables (created by every rank, filled by rank 0) and the attributes with their
    checksums (every rank, the same values)."""
    for where, t in tables.items():
        d = f.create_dataset(where, shape=t.shape, dtype=t.dtype)
        if rank == 0:
            d[...] = t
    attrs = {**top, "version": VERSION, "block_rows": BLOCK_ROWS,
             "data_digest": arrays_digest(tables)}
    attrs["digest"] = attrs_digest(attrs)
    for k, v in attrs.items():
        f.attrs[k] = v


def _publish(tmp: Path, path: Path, keep: int, lineage: str | None) -> None:
    """Rank 0: fsync the file, rename it into place, prune."""
    fd = os.open(tmp, os.O_RDWR)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
    os.replace(tmp, path)
    # a checkpoint of this step written in parts before (a run started again with
    # --overwrite): its parts folder is no part of this one
    shutil.rmtree(parts_folder(path), ignore_errors=True)
    fsync_folder(path.parent)
    prune(path.parent, keep, lineage=lineage)


def _write_rows(P, order, ds: dict, s: np.ndarray, lo: int, k_first: int) -> dict:
    """This rank's rows (``order``) into ``ds`` from row ``lo``, in blocks of whole segments
    (``s``: this rank's segment offsets, the first numbered ``k_first``); returns each field's
    segment digests, concatenated."""
    mine = {name: [] for name in ds}
    k0, n_seg = 0, s.size - 1
    while k0 < n_seg:
        k1 = max(k0 + 1, int(np.searchsorted(s, s[k0] + BLOCK, side="right")) - 1)
        a, b = int(s[k0]), int(s[k1])
        idx = order[a:b]
        for name, d in ds.items():
            rows = np.ascontiguousarray(getattr(P, name)[idx], dtype=DTYPES[name])
            d[lo + a:lo + b] = rows
            mine[name] += [block_digest(name, k_first + k, rows[int(s[k]) - a:int(s[k + 1]) - a])
                           for k in range(k0, k1)]
        k0 = k1
    return {name: b"".join(v) for name, v in mine.items()}
