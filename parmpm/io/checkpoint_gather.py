"""The parallel strategy behind checkpoints: gather every rank's particles to the writer, and
read a rank's own rows back on restart (the file format itself is :mod:`parmpm.io.checkpoint`).

PyPI's h5py is serial, so rank 0 writes: particles are gathered in bounded blocks of global ids
(no rank ever holds more than one block of other ranks' particles). Every step is collective and
a problem found by one rank (a full disk on the writer, a damaged block on a reader) is raised on
every rank with the same one-line message (:func:`parmpm.collective.agree`), so no rank is left
waiting. Another strategy (per-rank files under one master file with HDF5 virtual datasets) would
sit beside this one with the same two functions.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from parmpm.collective import agree
from parmpm.errors import ParmpmError
from parmpm.io.checkpoint import FIELDS, CheckpointWriter, prune
from parmpm.particles import Particles

#: global ids per gathered block: bounds the writer's extra memory
BLOCK = 1 << 18


def write_checkpoint(comm, P: Particles, path: Path, n_total: int, attrs: dict, keep: int,
                     lineage: str) -> Path:
    """Write ``path`` (collective): atomic; then delete all but the newest ``keep`` checkpoints
    of this run (``lineage``) in its folder. Every rank returns or raises the same."""
    root = comm.Get_rank() == 0
    order = np.argsort(P.gid, kind="stable")
    gids = P.gid[order]
    writer, problem = None, None
    if root:
        try:
            writer = CheckpointWriter(path, n_total, {k: getattr(P, k)[:0] for k in FIELDS}, attrs)
        except ParmpmError as exc:
            problem = str(exc)
    agree(comm, problem)
    for lo in range(0, n_total, BLOCK):
        hi = min(lo + BLOCK, n_total)
        a, b = np.searchsorted(gids, [lo, hi])
        parts = comm.gather({k: getattr(P, k)[order[a:b]] for k in FIELDS}, root=0)
        if root and problem is None:
            try:
                merged = {k: np.concatenate([q[k] for q in parts]) for k in FIELDS}
                o = np.argsort(merged["gid"], kind="stable")
                merged = {k: v[o] for k, v in merged.items()}
                if not np.array_equal(merged["gid"], np.arange(lo, hi)):
                    raise ParmpmError(f"checkpoint: particle ids {lo}..{hi - 1} incomplete")
                writer.write(lo, merged)
            except ParmpmError as exc:
                problem = str(exc)
            except OSError as exc:
                problem = f"cannot write checkpoint '{path}': {exc}"
    if root:
        try:
            if problem is None:
                writer.commit()
                prune(path.parent, keep, lineage=lineage)
            else:
                writer.abort()
        except ParmpmError as exc:
            problem = str(exc)
        except OSError as exc:
            problem = f"cannot write checkpoint '{path}': {exc}"
    agree(comm, problem)
    return path


def load_particles(comm, reader, dim: int, n_total: int, n_materials: int,
                   mine: np.ndarray) -> Particles:
    """This rank's rows (``mine``, ascending global ids) of the checkpoint, read block by block
    (collective: a damaged block found by one rank stops every rank)."""
    problem = None
    P = Particles(dim, mine.size)
    try:
        for name in FIELDS:
            if not reader.has(name):  # an older format: the field keeps its initial value
                continue
            dst = getattr(P, name)
            for lo in range(0, n_total, BLOCK):
                hi = min(lo + BLOCK, n_total)
                a, b = np.searchsorted(mine, [lo, hi])
                if b > a:
                    dst[a:b] = reader.read(name, lo, hi)[mine[a:b] - lo]
        if not np.array_equal(P.gid, mine):
            raise ParmpmError(f"checkpoint '{reader.path}': damaged: particle ids out of order")
        if P.n and (P.mat.min() < 0 or P.mat.max() >= n_materials):
            raise ParmpmError(f"checkpoint '{reader.path}': particles of material row "
                              f"{int(P.mat.max())}, but the scene has {n_materials} material(s): "
                              "materials cannot be added or removed on restart")
    except ParmpmError as exc:
        problem = str(exc)
    agree(comm, problem, root=None)
    return P
