"""A data file of checkpoint rows opened for reading (a part, or a one-writer checkpoint): the
file opened, its datasets and tables checked against the schema, and :class:`RowFile`, which
reads rows by whole segments and checks each against its digest. Every problem is one line
naming the file (``where``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from parmpm.core.errors import ParmpmError
from parmpm.io.checkpoint.digests import block_digest
from parmpm.io.checkpoint.format import DTYPES, OPTIONAL, PLASTIC_WIDTH


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


def first_line(exc: BaseException) -> str:
    return (str(exc).splitlines() or ["unreadable"])[0]


def open_h5(path: Path, where: str):
    import h5py

    if not path.is_file():
        raise ParmpmError(f"{where}: no such file")
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        raise ParmpmError(f"{where}: not a readable HDF5 file (truncated or damaged?): "
                          f"{first_line(exc)}") from None
    except Exception as exc:  # noqa: BLE001 - h5py reports a damaged superblock in many ways
        raise ParmpmError(f"{where}: not a readable HDF5 file (damaged?): "
                          f"{type(exc).__name__}") from None


def check_fields(f, where: str, n: int, d: int, names) -> dict:
    """``particles/<field>`` of ``f``: every field of ``names`` there, and the optional ones
    it holds, of shape (n, ...) and its type."""
    tails = {"x": (d,), "v": (d,), "x0": (d,), "lh0": (d,), "F": (d, d), "stress": (d, d),
             "r0": (d, d), "rf": (d, d), "affine": (d, d), "corners": (1 << d, d),
             "plastic": (PLASTIC_WIDTH,)}
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


def read_tables(f, where: str, names, shapes: dict) -> dict:
    """The datasets ``names`` of ``f``, read whole; each that ``shapes`` names must have that
    (shape, dtype)."""
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


def segment_tables(f, where: str, n: int, fields) -> tuple[np.ndarray, dict]:
    """A version-4 data file's segment offsets and digest tables (not yet checksummed)."""
    seg = f.get("segments")
    if seg is None or seg.ndim != 1 or seg.dtype != np.int64:
        raise ParmpmError(f"{where}: damaged: segments is {'nothing' if seg is None else seg.shape}")
    bounds = seg[()]
    if bounds.size < 1 or bounds[0] != 0 or bounds[-1] != n or np.any(np.diff(bounds) <= 0):
        raise ParmpmError(f"{where}: damaged: segments do not rise from 0 to {n}")
    shapes = {f"digests/{k}": ((bounds.size - 1, 32), np.dtype(np.uint8)) for k in fields}
    return bounds, read_tables(f, where, shapes, shapes)
