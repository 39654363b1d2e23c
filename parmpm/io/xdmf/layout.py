"""What the snapshot files hold, in XDMF's terms: the format's names, each particle field shaped
for XDMF (vectors padded to 3 columns, tensors to 9, domains in VTK node order) and the XML
elements that point at the datasets. The writer that uses them is
:mod:`parmpm.io.xdmf.writer`, the reader :mod:`parmpm.io.xdmf.reader`; the layout itself is
:mod:`parmpm.io.xdmf`'s docstring.
"""

from __future__ import annotations

from xml.etree import ElementTree as ET

import numpy as np

__all__ = ["FORMAT", "FORMAT_VERSION", "PARTS_VERSION", "CELL_TYPES", "BOX_TO_HEXAHEDRON",
           "pad_point_data", "pad_columns", "as_rows", "xdmf_cells", "part_file", "array_spec",
           "data_item", "uniform_grid"]

FORMAT, FORMAT_VERSION = "parmpm snapshots", 1
#: ``format_version`` of a series written in parts (its ``.h5`` holds no particles)
PARTS_VERSION = 2

#: XDMF topology of a domain, by dimension: (type, nodes per cell)
CELL_TYPES = {1: ("Polyline", 2), 2: ("Quadrilateral", 4), 3: ("Hexahedron", 8)}
#: :func:`parmpm.output.domains.domain_corners`' 3D box order (axis 0 fastest) → XDMF/VTK hexahedron
#: order (the bottom face counter-clockwise, then the top face)
BOX_TO_HEXAHEDRON = (0, 1, 3, 2, 4, 5, 7, 6)


def pad_columns(a: np.ndarray, width: int) -> np.ndarray:
    out = np.zeros((a.shape[0], width), dtype=np.float64)
    out[:, : a.shape[1]] = a
    return out


_XDMF_WIDTHS = (3, 6, 9)  # Vector, Tensor6, Tensor: the column counts XDMF names
_ATTRIBUTE_TYPES = {1: "Scalar", 3: "Vector", 6: "Tensor6", 9: "Tensor"}


def as_rows(a: np.ndarray) -> np.ndarray:
    """``a`` as a table of ``len(a)`` rows (``reshape(n, -1)`` fails when a rank holds no
    particles: n = 0)."""
    return a.reshape(a.shape[0], int(np.prod(a.shape[1:], dtype=np.int64)))


def pad_point_data(name: str, data, n: int, dim: int) -> dict[str, np.ndarray]:
    """Shape one particle field for XDMF, as ``{name: array}`` (or several scalar columns).

    ``(N,)`` → scalar; ``(N, 1)`` and ``(N, 1, 1)`` (1D vectors and tensors) → scalar;
    ``(N, dim)`` → ``(N, 3)`` vector and ``(N, dim, dim)`` or ``(N, dim²)`` → ``(N, 9)``
    tensor (zero-padded, row-major 3×3); ``(N, 3)``, ``(N, 6)``, ``(N, 9)`` are kept; any
    other shape is flattened and written as scalar columns ``name_0``, ``name_1``, ... (XDMF has
    no attribute type for them). Booleans become int8, integers stay integers, anything else
    becomes float64.
    """
    a = np.asarray(data)
    if a.shape[:1] != (n,):
        raise ValueError(f"point data {name!r} has shape {a.shape}, expected {n} rows")
    if a.dtype.kind == "b":
        a = a.astype(np.int8)
    elif a.dtype.kind not in "iuf":
        a = a.astype(np.float64)
    a = as_rows(a)
    k = a.shape[1]
    if k == 1:
        return {name: np.ascontiguousarray(a[:, 0])}
    if dim < 3 and k == dim:
        return {name: pad_columns(a, 3)}
    if dim < 3 and k == dim * dim:
        t = np.zeros((n, 3, 3), dtype=np.float64)
        t[:, :dim, :dim] = a.reshape(n, dim, dim)
        return {name: t.reshape(n, 9)}
    if k in _XDMF_WIDTHS:
        return {name: np.ascontiguousarray(a)}
    return {f"{name}_{j}": np.ascontiguousarray(a[:, j]) for j in range(k)}


def xdmf_cells(corners) -> np.ndarray:
    """Domain corners as :func:`parmpm.output.domains.domain_corners` gives them, ``(N, 2^d, d)``, in
    XDMF/VTK node order: unchanged in 1D (a segment) and 2D (already counter-clockwise); the 3D
    box order (axis 0 fastest) reordered to a hexahedron's (:data:`BOX_TO_HEXAHEDRON`)."""
    c = np.asarray(corners, dtype=np.float64)
    return c[:, BOX_TO_HEXAHEDRON, :] if c.shape[1] == 8 else c


def data_item(h5_name: str, path: str, spec) -> ET.Element:
    """A ``DataItem`` pointing at the HDF5 dataset ``path`` of ``h5_name``, whose shape and type
    are ``spec`` (``(shape, dtype)``)."""
    shape, dtype = spec
    dt = np.dtype(dtype)
    kind = {"i": "Int", "u": "UInt"}.get(dt.kind, "Float")
    if dt.itemsize == 1:
        kind = "Char" if dt.kind == "i" else "UChar"
    item = ET.Element("DataItem", DataType=kind, Precision=str(dt.itemsize),
                      Dimensions=" ".join(str(s) for s in shape), Format="HDF")
    item.text = f"{h5_name}:{path}"
    return item


def array_spec(a: np.ndarray) -> tuple[tuple, str]:
    return tuple(int(k) for k in a.shape), a.dtype.str


def uniform_grid(parent, name: str, t: float, rec: dict, geometry: str, topology: str,
             center: str) -> ET.Element:
    """One part's uniform grid of one snapshot: geometry ``geometry`` (a dataset of the step's
    group), cells ``topology`` (a connectivity record), every field of ``rec`` as ``center``
    data (the particles also carry ``x``)."""
    file, group, arrays = rec["file"], rec["group"], rec["arrays"]
    cell, nodes, conn_path, conn_shape = rec["topology"][topology]
    grid = ET.SubElement(parent, "Grid", Name=name, GridType="Uniform")
    ET.SubElement(grid, "Time", Value=repr(float(t)))
    geo = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
    geo.append(data_item(file, f"/{group}/{geometry}", arrays[geometry]))
    top = ET.SubElement(grid, "Topology", TopologyType=cell, NumberOfElements=str(conn_shape[0]),
                        NodesPerElement=str(nodes))
    top.append(data_item(file, conn_path, (conn_shape, "<i8")))
    for key, spec in arrays.items():
        if key == "domains" or (key == "x" and center == "Cell"):
            continue
        kind = _ATTRIBUTE_TYPES[1 if len(spec[0]) == 1 else spec[0][1]]
        attr = ET.SubElement(grid, "Attribute", Name=key, AttributeType=kind, Center=center)
        attr.append(data_item(file, f"/{group}/{key}", spec))
    return grid


def part_file(name: str, k: int) -> str:
    """Part ``k``'s file, relative to the series' folder: ``<name>.parts/part_<k>.h5``."""
    return f"{name}.parts/part_{int(k):05d}.h5"
