"""The parallel strategy behind checkpoints: who writes which rows, and which rows a rank reads
back on restart (the format is :mod:`parmpm.io.checkpoint`, the top-level file and the reader
:mod:`parmpm.io.checkpoint_parts`; docs/checkpoints.md says why).

**Writing** (:func:`write_checkpoint`). Ranks form groups of consecutive ranks
(:func:`parmpm.io.checkpoint_parts.ranks_per_file`: one per rank up to 256 ranks); the lowest rank
of a group, its *lead*, receives the members' rows in blocks of 2^18 (it never holds more than
one block of another rank's rows) and writes them, in rank order and each rank's by (patch, id),
into its part file ``checkpoint_<step>.parts/part_<k>.h5``; rank 0 then writes the top-level
file that binds the parts and holds the patch index. With one group the rows go into the
top-level file itself. Where h5py is built with MPI (``h5py.get_config().mpi``; PyPI's wheels
are not) every rank instead writes its own rows into one file, collectively
(:func:`write_collective`), same schema. Every step is collective and a problem found by one
rank (a full disk at a lead) is raised on every rank with the same one-line message
(:func:`parmpm.core.collective.agree`), so no rank is left waiting; on failure the parts are removed.

**Reading** (:func:`load_patches`). A version-4 restart deals the patches out from the index's
counts and each rank reads exactly its patches' rows (contiguous ranges of the parts);
:func:`load_rows` reads given rows (versions 1–3, whose rows are global ids, or a restart that
changed the patch grid).
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np

from parmpm.core.collective import agree
from parmpm.core.errors import ParmpmError
from parmpm.io.checkpoint import (BLOCK_ROWS, DTYPES, FIELDS, FORMAT, LIBVER, PART_FORMAT,
                                  CheckpointWriter, arrays_digest, attrs_digest, block_digest,
                                  estimate_bytes, fsync_folder, os_problem, part_name,
                                  parts_folder, prune, remove_checkpoint, segments_of,
                                  space_message, VERSION)
from parmpm.io.checkpoint_parts import (layout_record, rank_rows, ranks_per_file, top_tables,
                                        write_top)
from parmpm.particles.store import OPTIONAL_FIELDS, Particles

#: rows per message from a member to its lead: bounds the lead's extra memory
BLOCK = 1 << 18
_TAG = 0x5EC7


def _mpio(comm) -> bool:
    """Whether h5py can write one file from all ranks (built with MPI, and a real MPI run)."""
    if comm.Get_size() == 1 or not hasattr(comm, "Send"):
        return False
    try:
        import h5py

        return bool(h5py.get_config().mpi)
    except Exception:  # noqa: BLE001 - no h5py: the writer will say so
        return False


def _free(folder: Path) -> int:
    from parmpm.io import checkpoint

    return checkpoint._free_bytes(folder)


def write_checkpoint(comm, P: Particles, path: Path, n_total: int, attrs: dict, keep: int,
                     lineage: str, disc, ranks_per_file_setting="auto") -> Path:
    """Write ``path`` (collective): atomic (parts first, the top-level file last); then delete
    all but the newest ``keep`` checkpoints of this run (``lineage``) in its folder, with their
    parts. ``disc``: the run's :class:`parmpm.transfer.discretisation.Discretisation` (its patch grid is
    what the index refers to). Every rank returns or raises the same."""
    path = Path(path)
    rank, size = comm.Get_rank(), comm.Get_size()
    order = np.lexsort((P.gid, P.patch))
    pids, pcounts = np.unique(P.patch[order], return_counts=True)
    all_patches = comm.allgather((pids, pcounts))
    first, index = rank_rows(all_patches, disc.layout.n_patches)
    like = {k: getattr(P, k)[:0] for k in stored(P)}
    top = {**attrs, "layout": layout_record(disc)}
    if lineage is not None:
        top["lineage"] = lineage
    if int(first[-1]) != n_total:  # the same on every rank
        raise ParmpmError(f"cannot write checkpoint '{path}': the ranks hold {int(first[-1])} "
                          f"particles, not {n_total}")
    if _mpio(comm):
        return write_collective(comm, P, order, path, top, like, all_patches, first, index,
                                keep, lineage, driver="mpio")
    rpf = ranks_per_file(size, ranks_per_file_setting)
    n_parts = -(-size // rpf)
    top.update(part_files=n_parts, ranks_per_file=rpf)
    lead, part = rank - rank % rpf, rank // rpf
    members = range(lead, min(lead + rpf, size))
    inline = n_parts == 1
    folder = parts_folder(path)
    problem = None
    if rank == 0:
        problem = _prepare(path, folder, inline, n_total, like, top, all_patches, index)
    agree(comm, problem)
    writer = None
    if rank == lead:
        seg = segments_of(np.concatenate([all_patches[r][1] for r in members] + [[]]))
        rows = int(first[members[-1] + 1] - first[lead])
        try:
            if inline:
                writer = CheckpointWriter(path, rows, like, top, segments=seg, fmt=FORMAT,
                                          extra_bytes=index.nbytes + 256)
            else:
                writer = CheckpointWriter(
                    folder / part_name(part), rows, like,
                    {"part": part, "parts": n_parts, "first_row": int(first[lead]), "rows": rows,
                     "step": attrs["step"], "lineage": lineage or ""}, segments=seg,
                    fmt=PART_FORMAT)
        except ParmpmError as exc:
            problem = str(exc)
    problem = _stream(comm, P, order, writer, members, first, problem)
    digest = None
    if writer is not None:
        try:
            if problem is None:
                digest = writer.commit(top_tables(index, np.array([0, n_total]), [(".", "")])
                                       if inline else None)
            else:
                writer.abort()
        except ParmpmError as exc:
            problem = str(exc)
    results = comm.gather((problem, digest), root=0)
    if rank == 0:
        problem = next((p for p, _ in results if p), None)
        try:
            if problem is None and not inline:
                files = [(f"{folder.name}/{part_name(k)}", results[k * rpf][1])
                         for k in range(n_parts)]
                bounds = first[[min(k * rpf, size) for k in range(n_parts + 1)]]
                write_top(path, top, like,
                          [(f, int(bounds[k]), int(bounds[k + 1] - bounds[k]))
                           for k, (f, _) in enumerate(files)],
                          n_total, top_tables(index, bounds, files))
            if problem is None:
                prune(path.parent, keep, lineage=lineage)
        except ParmpmError as exc:
            problem = str(exc)
        except OSError as exc:
            problem = f"cannot write checkpoint '{path}': {exc}"
        if problem is not None and not inline:
            shutil.rmtree(folder, ignore_errors=True)
    agree(comm, problem)
    return path


def _prepare(path: Path, folder: Path, inline: bool, n_total: int, like: dict, top: dict,
             all_patches, index) -> str | None:
    """Rank 0, before any rank writes: the space all files need, a clean parts folder (a
    checkpoint of the same step in this folder is replaced). Returns a problem or None."""
    segs = sum(int(np.sum(-(-np.asarray(c, np.int64) // BLOCK_ROWS))) for _, c in all_patches)
    need = estimate_bytes(n_total, like, top, segments=segs, extra=index.nbytes)
    if not inline:  # each part's own overhead
        need += estimate_bytes(0, like, {}) * len(all_patches)
    try:
        free = _free(path.parent)
        if need > free:
            return space_message(path, need, free)
        if path.exists() or folder.exists():
            remove_checkpoint(path)
        if not inline:
            folder.mkdir()
    except OSError as exc:
        return os_problem(path, exc)
    return None


def _stream(comm, P: Particles, order: np.ndarray, writer, members, first, problem):
    """Members send their rows (rank order, by patch and id) to the lead in blocks; the lead
    writes them (and, after a problem, still receives them, so no member waits)."""
    rank = comm.Get_rank()
    lead = members[0]
    if rank != lead:
        for a in range(0, P.n, BLOCK):
            idx = order[a:a + BLOCK]
            for k in stored(P):
                comm.Send(np.ascontiguousarray(getattr(P, k)[idx], dtype=DTYPES[k]), dest=lead,
                          tag=_TAG)
        return problem
    lo = 0
    for r in members:
        n_r = int(first[r + 1] - first[r])
        for a in range(0, n_r, BLOCK):
            m = min(BLOCK, n_r - a)
            if r == rank:
                idx = order[a:a + m]
                block = {k: getattr(P, k)[idx] for k in stored(P)}
            else:
                block = {}
                for k in stored(P):
                    block[k] = np.empty((m,) + getattr(P, k).shape[1:], DTYPES[k])
                    comm.Recv(block[k], source=r, tag=_TAG)
            if problem is None:
                try:
                    writer.write(lo, block)
                except ParmpmError as exc:
                    problem = str(exc)
            lo += m
    return problem


def write_collective(comm, P, order, path, top, like, all_patches, first, index, keep, lineage,
                     driver="mpio") -> Path:
    """Every rank writes its rows into one file through h5py's MPI-IO driver (the schema of a
    one-writer checkpoint: rows in rank order, the index, segment digests), then rank 0 fsyncs
    and renames it. Only where h5py is built with MPI; ``driver=None`` on one rank runs the same
    code serially (the tests' only way to run it with PyPI's h5py; tests/test_parallel_hdf5.py
    runs the driver itself where a parallel HDF5 is installed). No :class:`GuardedFile` here
    (MPI-IO writes the file): the free space is checked first.

    Parallel HDF5 wants every metadata call (creating datasets, writing attributes, closing)
    made by every rank with the same values: the attributes are rank 0's (broadcast), and a
    rank whose own (independent) row writes fail keeps the error until every rank has written,
    so all ranks close the file together and raise the same line. A rank writes its rows in
    blocks of whole segments of about :data:`BLOCK` rows (one copy of a block, never of a
    field; no single MPI-IO request above 2 GiB)."""
    import h5py

    rank, size = comm.Get_rank(), comm.Get_size()
    tmp = path.with_name(path.name + ".tmp")
    segs = [segments_of(np.asarray(c, np.int64)) for _, c in all_patches]
    seg_first = np.concatenate([[0], np.cumsum([s.size - 1 for s in segs])])
    bounds = np.concatenate([[0]] + [s[1:] + first[r] for r, s in enumerate(segs)]).astype(np.int64)
    top = comm.bcast({**top, "part_files": 1, "ranks_per_file": size, "format": FORMAT}, root=0)
    problem = None
    if rank == 0:
        try:
            need = estimate_bytes(int(first[-1]), like, top, segments=bounds.size - 1,
                                  extra=index.nbytes)
            free = _free(path.parent)
            problem = space_message(path, need, free) if need > free else None
        except OSError as exc:
            problem = os_problem(path, exc)
    agree(comm, problem)
    try:
        kw = {"driver": driver, "comm": comm} if driver else {}
        with h5py.File(tmp, "w", libver=LIBVER, **kw) as f:
            ds = {name: f.create_dataset(f"particles/{name}", shape=(int(first[-1]),) + a.shape[1:],
                                         dtype=DTYPES[name]) for name, a in like.items()}
            try:
                mine = _write_rows(P, order, ds, segs[rank], int(first[rank]), int(seg_first[rank]))
            except ParmpmError as exc:
                problem, mine = str(exc), {name: b"" for name in like}
            except OSError as exc:
                problem, mine = os_problem(path, exc), {name: b"" for name in like}
            except Exception as exc:  # noqa: BLE001 - raised alone, it would hang the others
                problem = (f"cannot write checkpoint '{path}': {type(exc).__name__}: "
                           f"{(str(exc).splitlines() or ['error'])[0]}")
                mine = {name: b"" for name in like}
            gathered = comm.allgather((problem, [mine[k] for k in like]))
            problem = next((p for p, _ in gathered if p), None)
            if problem is None:
                tables = top_tables(index, np.array([0, int(first[-1])]), [(".", "")])
                tables["segments"] = bounds
                for name, parts in zip(like, zip(*(d for _, d in gathered))):
                    tables[f"digests/{name}"] = np.frombuffer(b"".join(parts),
                                                              np.uint8).reshape(-1, 32)
                for where, t in tables.items():
                    d = f.create_dataset(where, shape=t.shape, dtype=t.dtype)
                    if rank == 0:
                        d[...] = t
                attrs = {**top, "version": VERSION, "block_rows": BLOCK_ROWS,
                         "data_digest": arrays_digest(tables)}
                attrs["digest"] = attrs_digest(attrs)
                for k, v in attrs.items():
                    f.attrs[k] = v
        comm.Barrier()
        if rank == 0 and problem is None:
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
    except ParmpmError as exc:
        problem = str(exc)
    except OSError as exc:
        problem = os_problem(path, exc)
    if problem is not None and rank == 0:
        tmp.unlink(missing_ok=True)
    agree(comm, problem, root=None)
    return path


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


# --- restart --------------------------------------------------------------------------------------
def _check_loaded(reader, P: Particles, n_materials: int) -> None:
    if P.n and (P.gid.min() < 0 or P.gid.max() >= reader.n):
        raise ParmpmError(f"checkpoint '{reader.path}': damaged: particle ids out of range")
    if P.n and (P.mat.min() < 0 or P.mat.max() >= n_materials):
        raise ParmpmError(f"checkpoint '{reader.path}': particles of material row "
                          f"{int(P.mat.max())}, but the scene has {n_materials} material(s): "
                          "materials cannot be added or removed on restart")


def stored(P: Particles) -> list[str]:
    """The fields a checkpoint of ``P`` holds: :data:`FIELDS` but the optional fields ``P``
    does not carry (the same on every rank: the scene decides)."""
    return [k for k in FIELDS if k not in OPTIONAL_FIELDS or k in P.optional]


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
