"""What a file of checkpoint rows holds: the format's names and versions, the stored fields and
their types, and how the rows are cut into digest segments.

Schema of a data file (a part, format ``parmpm-checkpoint-part``, or a one-writer checkpoint)::

    /particles/gid, mat             (n,) int64: global id, material row
    /particles/x, v, x0, lh0        (n, dim) float64
    /particles/mass, vol0, damage   (n,) float64
    /particles/F, stress, r0, rf    (n, dim, dim) float64 (rf: frozen CPDI domain, 0 = none)
    /particles/affine               (n, dim, dim) float64 (APIC's C_p; 0 under FLIP)
    /particles/corners              (n, 2^dim, dim) float64 (CPDI2's corners; cpdi2 runs only)
    /particles/plastic              (n, 8) float64 (plastic state: C_p^-1, eps_p, W_p; runs with
                                    a plastic material only)
    /segments                       (K+1,) int64 offsets of the digest segments
    /digests/<field>                (K, 32) uint8: SHA-256 of each segment
    part attrs: format, version, part, parts, first_row, rows, step, lineage, block_rows,
                data_digest, digest

Versions 1–3 (one file in global-id order, fixed blocks, Fletcher-32 chunks) still read;
versions 1 (no ``rf``, read as 0) and 2 without digests (a warning says so); before version 5
there is no ``affine`` (read as 0: those runs were FLIP runs).
"""
from __future__ import annotations

import numpy as np

FORMAT = "parmpm-checkpoint"
PART_FORMAT = "parmpm-checkpoint-part"
#: 5: adds particles/affine; 4: rows in rank order with a patch index, parts bound by virtual
#: datasets, digests per segment; 3: per-block SHA-256 of the data; 2: adds particles/rf;
#: 1: rf read as 0
VERSION = 5
#: stored particle fields (``dx`` is MUSL scratch, ``patch`` is derived from ``x``)
FIELDS = ("gid", "mat", "x", "v", "x0", "mass", "vol0", "F", "stress", "r0", "lh0", "damage",
          "rf", "affine", "corners", "plastic")
#: fields a checkpoint holds only when the run carries them (:data:`parmpm.particles.store.OPTIONAL_FIELDS`)
OPTIONAL = ("affine", "corners", "plastic")
#: the width of a plastic state row (:data:`parmpm.materials.plasticity.state.STATE_WIDTH`, which
#: this layer may not import; tests/driver/test_plastic_checkpoint.py holds the two equal)
PLASTIC_WIDTH = 8
#: the stored type of every field (little-endian, as hashed)
DTYPES = {name: np.dtype("<i8") if name in ("gid", "mat") else np.dtype("<f8") for name in FIELDS}
ATTRS = ("scene", "step", "time", "dt", "vmax", "method", "lcr", "ranks", "particles", "dim", "state")
#: the most rows of one digest segment (version 3: the chunk size, every block)
BLOCK_ROWS = 1 << 16
#: HDF5 format bounds: version-2 object headers (checksummed), virtual datasets; HDF5 >= 1.10
LIBVER = ("v110", "v110")


def required_fields(version: int) -> tuple[str, ...]:
    """The particle fields every checkpoint of format ``version`` holds (an optional field is
    there when the run carried it; a missing one reads as 0)."""
    base = tuple(k for k in FIELDS if k not in OPTIONAL)
    return base if version >= 2 else tuple(k for k in base if k != "rf")


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
