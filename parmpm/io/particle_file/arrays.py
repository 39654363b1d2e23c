"""Particles as named arrays: a numpy ``.npz`` archive, or an HDF5 file with datasets at its
root. The names: ``x`` (N, dim) and ``volume`` (N,), required; ``v`` (N, dim), ``material``
(N,) strings and ``F`` (N, dim, dim), optional. Numbers may be any integer or float type (read
as float64); strings where numbers belong, numbers where names belong, other names and other
shapes are one-line errors naming the array. Errors count rows from 0, as numpy does.
"""
from __future__ import annotations

import zipfile

import numpy as np

import parmpm.io.particle_file.data as data
from parmpm.io.particle_file.data import fail, finish, suggest

#: array name → the field of :class:`ParticleData` it fills
FIELDS = {"x": "x", "volume": "volume", "v": "velocity", "material": "material", "F": "F"}


def _shape(name: str, n: int, dim: int) -> tuple:
    return {"x": (n, dim), "volume": (n,), "v": (n, dim), "material": (n,), "F": (n, dim, dim)}[name]


def _show(shape: tuple) -> str:
    return "(" + ", ".join(str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"


def check_layout(label: str, kind: str, shapes: dict[str, tuple], dtypes: dict, dim: int) -> int:
    """Names, types and shapes of the arrays, before any is read; the number of particles."""
    for name in shapes:
        if name not in FIELDS:
            fail(label, f"unknown {kind} '{name}'; {suggest(name, list(FIELDS))}")
    for name in ("x", "volume"):
        if name not in shapes:
            fail(label, f"no {kind} '{name}'; a particle file needs 'x' (N, {dim}) and "
                        "'volume' (N,)")
    for name, dt in dtypes.items():
        text = name == "material"
        if text and dt.kind not in "USO":
            fail(label, f"{kind} '{name}' holds numbers (dtype {dt}); expected material names "
                        "(strings)")
        if not text and dt.kind not in "iuf":
            what = "strings" if dt.kind in "USO" else f"dtype {dt}"
            fail(label, f"{kind} '{name}' holds {what} (dtype {dt}); expected numbers")
    x = shapes["x"]
    if len(x) != 2 or x[1] != dim:
        per = f"{x[1]} coordinates per particle" if len(x) == 2 else f"{len(x)}-dimensional"
        fail(label, f"{kind} 'x' has shape {_show(x)} ({per}); this scene is {dim}D: "
                    f"expected (N, {dim})")
    n = int(x[0])
    data.check_count(label, n, f"{kind} 'x'")
    for name, shape in shapes.items():
        want = _shape(name, n, dim)
        if tuple(shape) != want:
            fail(label, f"{kind} '{name}' has shape {_show(tuple(shape))}; expected "
                        f"{_show(want)} ({n} particles, as 'x', in {dim}D)")
    return n


def _as_field(name: str, a: np.ndarray) -> np.ndarray:
    if name != "material":
        return a.astype(np.float64)
    if a.dtype.kind == "S":
        return np.char.decode(a, "utf-8")
    return np.asarray(a, dtype=str)


def read_npz(label: str, path, dim: int):
    """The particles of a ``.npz`` archive (``np.savez``)."""
    arrays = {}
    try:
        with np.load(path, allow_pickle=False) as z:
            for name in z.files:
                try:
                    arrays[name] = z[name]
                except ValueError as exc:
                    if "allow_pickle" not in str(exc):
                        raise
                    fail(label, f"array '{name}' is an object array (pickled); expected numbers, "
                                "or str names (np.array(names, dtype=str))")
    except (zipfile.BadZipFile, ValueError, EOFError, OSError) as exc:
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        fail(label, f"is not a readable .npz archive ({why}); expected np.savez output")
    check_layout(label, "array", {k: a.shape for k, a in arrays.items()},
                 {k: a.dtype for k, a in arrays.items()}, dim)
    fields = {FIELDS[k]: _as_field(k, a) for k, a in arrays.items()}
    names = {FIELDS[k]: f"array '{k}'" for k in FIELDS}
    return finish(label, label, fields, lambda i: f"row {i}", names)


def read_root(label: str, f, dim: int):
    """The particles of an open HDF5 file whose root holds the arrays as datasets."""
    import h5py

    shapes, dtypes = {}, {}
    for name, obj in f.items():
        if not isinstance(obj, h5py.Dataset):
            fail(label, f"'{name}' at the root is a group; expected the datasets "
                        f"{', '.join(FIELDS)} at the root (or a parmpm snapshot or checkpoint)")
        shapes[name], dtypes[name] = obj.shape, obj.dtype
        if h5py.check_string_dtype(obj.dtype) is not None:
            dtypes[name] = np.dtype("U1")
    check_layout(label, "dataset", shapes, dtypes, dim)
    fields = {}
    for name in shapes:
        ds = f[name]
        a = ds.asstr()[()] if h5py.check_string_dtype(ds.dtype) is not None else ds[()]
        fields[FIELDS[name]] = _as_field(name, np.asarray(a))
    names = {FIELDS[k]: f"dataset '{k}'" for k in FIELDS}
    return finish(label, label, fields, lambda i: f"row {i}", names)
