"""A run's snapshots back into numpy, from the ``.h5`` that :class:`parmpm.io.SnapshotWriter`
writes (the layout is in :mod:`parmpm.io.xdmf`)::

    from parmpm.io import load_snapshots
    s = load_snapshots("parmpm-out/hanging_bar/hanging_bar.xdmf")   # or the .h5
    s.times, s["x"][-1]          # (K,) times; the last snapshot's positions, (N, dim)

``s[name][k]`` is field ``name`` at snapshot ``k`` (read from the file when asked) in the
particle's own shape: vectors ``(N, dim)``, tensors ``(N, dim, dim)``, scalars ``(N,)``,
``domains`` ``(N, 2^dim, dim)`` (corners in VTK/XDMF order), the padding to 3 columns undone;
``np.stack(list(s[name]))`` is the whole series. ``s.steps``, ``s.fields``, ``s.units``,
``s.descriptions``, ``s.at(k)`` (every field of snapshot ``k``), ``s.history`` (the run's history
table, if the run wrote one there) and ``s.to_meshio(k)`` (a ``meshio.Mesh`` of one snapshot, to
write any format meshio knows: ``s.to_meshio(-1).write("last.vtu")``).

A series written in parts (``<name>.h5`` with a ``parts`` attribute: its steps and history, the
particles in ``<name>.parts/part_<k>.h5``) reads the same: every read opens each part and merges
the rows by ``gid``, so arrays are in global-id order whatever the number of ranks that wrote.
"""
from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from parmpm.core.errors import ParmpmError
from parmpm.io.xdmf.layout import CELL_TYPES, FORMAT

__all__ = ["load_snapshots", "Snapshots", "FieldSeries"]

#: meshio's names of the domain cells, by dimension
_MESHIO_CELLS = {1: "line", 2: "quad", 3: "hexahedron"}


def natural_shape(a: np.ndarray, shape) -> np.ndarray:
    """Undo the writer's padding (:func:`parmpm.io.xdmf.layout.pad_point_data`): ``a`` as stored,
    ``shape`` the per-particle shape it was given (the dataset's ``shape`` attribute)."""
    shape = tuple(int(s) for s in shape)
    if a.shape[1:] == shape:
        return a
    size = math.prod(shape)
    if a.ndim == 1:  # 1D vectors and tensors are stored as scalars
        return a.reshape(a.shape[0], *shape)
    if a.shape[1] == 9 and size in (1, 4):  # a tensor padded to 3×3 (flattened or not)
        d = math.isqrt(size)
        return a.reshape(-1, 3, 3)[:, :d, :d].reshape(a.shape[0], *shape)
    if len(shape) == 2 and a.shape[1] == 3:  # points of cells: (N·c, 3) → (N, c, dim)
        return a.reshape(-1, shape[0], 3)[..., : shape[1]]
    return a[:, :size].reshape(a.shape[0], *shape)  # a vector padded to 3 columns


class FieldSeries(Sequence):
    """One field over the snapshots: ``series[k]`` reads snapshot ``k`` (negative ``k`` counts
    from the end; a slice gives a list)."""

    def __init__(self, snapshots: Snapshots, name: str):
        self._s, self.name = snapshots, name

    def __len__(self) -> int:
        return len(self._s)

    def __getitem__(self, k):
        if isinstance(k, slice):
            return [self[j] for j in range(len(self))[k]]
        return self._s._read(self._s._group(k), self.name)


class Snapshots:
    """The snapshots of one series (see the module doc); made by :func:`load_snapshots`."""

    def __init__(self, path: Path):
        import h5py

        self.path = Path(path)
        try:
            with h5py.File(self.path, "r") as f:
                if f.attrs.get("format") != FORMAT:
                    raise ParmpmError(f"'{self.path}' is no parmpm snapshot file")
                self.dim = int(f.attrs["dim"])
                info = json.loads(f.attrs.get("fields", "{}"))
                groups = [(int(g.attrs["index"]), name, float(g.attrs["time"]), int(g.attrs["step"]))
                          for name, g in f.items() if name.startswith("step_")]
                groups.sort()
                self._parts = json.loads(f.attrs["parts"]) if "parts" in f.attrs else None
                if self._parts is None:
                    names = list(f[groups[0][1]]) if groups else []
                self.history = ({c: ds[()] for c, ds in f["history"].items()}
                                if "history" in f else None)
            if self._parts is not None:
                names = []
                if groups:
                    with self._open(self._parts[0]) as f:
                        names = list(f[groups[0][1]])
        except OSError as exc:
            raise ParmpmError(f"cannot read snapshots '{self.path}': {exc}") from None
        self._groups = [g[1] for g in groups]
        self.times = np.array([g[2] for g in groups], dtype=np.float64)
        self.steps = np.array([g[3] for g in groups], dtype=np.int64)
        self.fields = tuple(names)
        self.units = {n: info.get(n, {}).get("units", "") for n in names}
        self.descriptions = {n: info.get(n, {}).get("description", "") for n in names}

    def __len__(self) -> int:
        return len(self._groups)

    def __contains__(self, name: str) -> bool:
        return name in self.fields

    def __getitem__(self, name: str) -> FieldSeries:
        if name not in self.fields:
            raise KeyError(f"{name!r}: the snapshots hold {', '.join(self.fields)}")
        return FieldSeries(self, name)

    def __repr__(self) -> str:
        return f"Snapshots('{self.path}': {len(self)} snapshots; {', '.join(self.fields)})"

    def _group(self, k: int) -> str:
        return self._groups[range(len(self))[k]]

    def _read(self, group: str, name: str, raw: bool = False) -> np.ndarray:
        return self._read_all(group, [name], raw)[name]

    def _open(self, part: str):
        import h5py

        path = self.path.parent / part
        try:
            return h5py.File(path, "r")
        except OSError as exc:
            raise ParmpmError(f"cannot read snapshots '{path}': {exc}") from None

    def _read_all(self, group: str, names, raw: bool = False) -> dict[str, np.ndarray]:
        if self._parts is None:
            with self._open(self.path.name) as f:
                return _read_group(f[group], names, raw)
        pieces, gids = [], []
        for part in self._parts:
            with self._open(part) as f:
                pieces.append(_read_group(f[group], names, raw))
                gids.append(f[group]["gid"][()])
        order = np.argsort(np.concatenate(gids), kind="stable")
        out = {}
        for name in names:
            a = np.concatenate([p[name] for p in pieces])
            if a.shape[0] != order.size:  # raw corners: (N·c, 3) rows, c per particle
                a = a.reshape(order.size, -1, *a.shape[1:])[order].reshape(a.shape)
            else:
                a = a[order]
            out[name] = a
        return out

    def at(self, k: int) -> dict[str, np.ndarray]:
        """Every field of snapshot ``k``."""
        return self._read_all(self._group(k), self.fields)

    def to_meshio(self, k: int, domains: bool = False):
        """Snapshot ``k`` as a ``meshio.Mesh``: the particles (vertex cells, the fields as point
        data) or, with ``domains``, the domains (cells, the fields as cell data)."""
        import meshio

        group = self._group(k)
        data = self._read_all(group, [n for n in self.fields if n != "domains"], raw=True)
        x = data.pop("x")
        n = x.shape[0]
        if not domains:
            return meshio.Mesh(x, [("vertex", np.arange(n).reshape(n, 1))], point_data=data)
        if "domains" not in self.fields:
            raise KeyError("these snapshots hold no domains (output.domains = false)")
        nodes = CELL_TYPES[self.dim][1]
        points = self._read(group, "domains", raw=True)
        cells = [(_MESHIO_CELLS[self.dim], np.arange(n * nodes).reshape(n, nodes))]
        return meshio.Mesh(points, cells, cell_data={c: [a] for c, a in data.items()})


def _read_group(group, names, raw: bool) -> dict[str, np.ndarray]:
    out = {}
    for name in names:
        ds = group[name]
        a = ds[()]
        out[name] = a if raw else natural_shape(a, ds.attrs.get("shape", a.shape[1:]))
    return out


def load_snapshots(path) -> Snapshots:
    """The snapshots of ``<name>.xdmf`` or ``<name>.h5`` (the ``.h5`` is read)."""
    return Snapshots(Path(path).with_suffix(".h5"))
