"""The checksums that make a damaged checkpoint fail instead of reading back wrong rows.

A file's rows are cut into *segments* (``segments``: offsets; version 4: each patch's rows, cut
at ``block_rows``; versions 1–3: fixed blocks of ``block_rows``) and ``digests/<field>`` holds
one SHA-256 (FIPS 180-4) per segment, of the field's name, the segment's index and its rows'
bytes (little-endian, C order). A read takes the whole segments it touches and checks them; a
restart asks for whole patches, so it reads nothing more. HDF5's own checksums (Fletcher-32 of
chunks, in version 3) do not cover the index that locates the data: a flipped bit there read
whole fields back as zeros without an error. The digest tables, the segment offsets, the patch
index and the part table are checked on open against ``data_digest``; every root attribute,
``data_digest`` included, is covered by ``digest``; the top-level file records each part's
``digest``. So a damaged file reads back exactly what was written or fails with one line naming
it.
"""
from __future__ import annotations

import hashlib
import json

import numpy as np

from parmpm.io.checkpoint.format import DTYPES


def attrs_digest(attrs: dict) -> str:
    """SHA-256 of the root attributes (HDF5 checksums data chunks, not attributes)."""
    text = json.dumps({k: (v.item() if hasattr(v, "item") else v) for k, v in sorted(attrs.items())},
                      sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def segment_hash(name: str, k: int):
    """The running SHA-256 of segment ``k`` of field ``name``, its name and index fed (so a
    segment read from the wrong place fails); its rows' bytes follow."""
    return hashlib.sha256(f"{name}:{k}:".encode())


def block_digest(name: str, k: int, rows: np.ndarray) -> bytes:
    """SHA-256 of segment ``k`` of field ``name``: its name and index, then its rows' bytes."""
    h = segment_hash(name, k)
    h.update(np.ascontiguousarray(rows, dtype=DTYPES[name]).data)
    return h.digest()


def tables_digest(tables: dict[str, np.ndarray]) -> str:
    """Version 3's ``data_digest``: SHA-256 of the digest tables."""
    h = hashlib.sha256()
    for name in sorted(tables):
        h.update(f"{name}:{tables[name].shape[0]}:".encode())
        h.update(np.ascontiguousarray(tables[name], dtype=np.uint8).data)
    return h.hexdigest()


def arrays_digest(arrays: dict[str, np.ndarray]) -> str:
    """Version 4's ``data_digest``: SHA-256 of named tables (their names, types, shapes, bytes)."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}:{a.dtype.str}:{a.shape}:".encode())
        h.update(a.data)
    return h.hexdigest()
