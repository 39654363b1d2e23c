"""A checkpoint in parts: the top-level file that binds the part files (HDF5 virtual datasets, the
patch index, the part table), and the rule that groups ranks into parts.

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
from pathlib import Path

import numpy as np

from parmpm.io.checkpoint.format import DTYPES, FORMAT
from parmpm.io.checkpoint.writer import CheckpointWriter

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
    except Exception as exc:  # noqa: BLE001 - fail re-raises what is not an I/O error
        w.fail(exc)
    w.commit(tables)
