"""Disk space for checkpoints: the size a file will have, bounded from above, compared with the
free space before a file is created (and before each block), so that a full disk is one line
(``disk full writing '<path>': N MB needed, M MB free``) and never a half-written file; and the
one line for any other OSError (h5py's messages span lines).

:func:`free_bytes` is looked up through this module by every caller, so a test can stand in a
nearly full disk for one rank.
"""
from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

import numpy as np

from parmpm.io.checkpoint.format import BLOCK_ROWS, DTYPES

#: what HDF5 adds beyond the data (object headers, heaps), bounded from above
_OVERHEAD = 256 * 1024
_PER_SEGMENT = 8  # a segment offset
_NO_SPACE = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


def free_bytes(folder: Path) -> int:
    """The bytes free for an unprivileged writer in ``folder``'s filesystem."""
    return int(shutil.disk_usage(folder).free)


def os_problem(path: Path, exc: OSError) -> str:
    """One line for an OSError met writing ``path`` (h5py's messages span lines)."""
    if exc.errno in _NO_SPACE:
        try:
            free = f": {free_bytes(path.parent) / 1e6:.1f} MB free"
        except OSError:
            free = ""
        return f"disk full writing '{path}' ({os.strerror(exc.errno)}){free}"
    what = os.strerror(exc.errno) if exc.errno else (str(exc).splitlines() or ["I/O error"])[0]
    return f"cannot write checkpoint '{path}': {what}"


def row_bytes(like: dict[str, np.ndarray]) -> int:
    """The stored bytes of one row of the fields of ``like`` (arrays of the fields' shapes)."""
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
