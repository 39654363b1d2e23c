"""Volume meshes from files (Gmsh ``.msh``, ``.vtu``/``.vtk``, ``.xdmf``, Abaqus ``.inp``, any
format meshio reads) as nodes and element blocks of the scene's dimension, with their groups.

A body made from a mesh needs only its cells of the scene's dimension: triangles and quads in 2D,
tetrahedra and hexahedra in 3D. Lower-dimensional cells (Gmsh writes boundary lines, points and
faces with the volume) are dropped without a word; anything else is refused with one line naming
the file, what was found and what is accepted. meshio is imported only when a mesh is read.

Groups are Gmsh physical tags (cell data ``gmsh:physical``, their names in ``field_data``) or,
when a file has none, its named cell sets (Abaqus ``*ELSET``, ...), numbered in file order.

A cell is its set of nodes: one listed again (in any node order) is the same cell, seeded once.
Gmsh 2.2 writes a cell once per physical group it belongs to, and meshio reads each line as a
cell, so a square in two groups would otherwise weigh what its cells in both groups weigh; the
copies' groups are merged, the first copy keeps its place, and :attr:`VolumeMesh.repeats` counts
what was dropped (the scene says so in one warning).
"""
from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from parmpm.core.errors import SceneError
from parmpm.core.hash_mix import splitmix64_finish

#: the cell types a body is made of, by the scene's dimension
VOLUME_CELLS = {2: ("triangle", "quad"), 3: ("tetra", "hexahedron")}
#: the nodes of each accepted cell type
NODES = {"triangle": 3, "quad": 4, "tetra": 4, "hexahedron": 8}


class MeshBlock(NamedTuple):
    """Cells of one type: ``cells`` (n, nodes) int64 node indices, ``group`` (n,) int64 the group
    id of each cell (-1: in no group)."""
    cell_type: str
    cells: np.ndarray
    group: np.ndarray


@dataclass(frozen=True)
class VolumeMesh:
    """A mesh's nodes ``points`` (n_nodes, dim) float64, its blocks of cells of the scene's
    dimension (file order) and ``group_names``: name -> group id (empty if the file names none).
    ``repeats``: per cell (counting through the blocks) how many more times the file lists it
    among the selected groups, dropped here; None when no cell is listed twice."""
    points: np.ndarray
    blocks: tuple[MeshBlock, ...]
    group_names: dict = field(default_factory=dict)
    repeats: np.ndarray | None = None

    @property
    def n_cells(self) -> int:
        return sum(len(b.cells) for b in self.blocks)


def _short(text: str, limit: int = 160) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _load(path: Path, where: str):
    """meshio's mesh of ``path``; every way it can fail becomes one line."""
    if not path.exists():
        raise SceneError(f"{where}: no such file; expected a mesh file (Gmsh .msh, .vtu, .xdmf, ...)")
    if path.is_dir():
        raise SceneError(f"{where}: is a directory; expected a mesh file")
    if not path.is_file():  # a FIFO would block open() until something writes to it
        raise SceneError(f"{where}: is not a regular file (a FIFO, device or socket); expected a "
                         "mesh file")
    try:
        with open(path, "rb") as f:
            f.read(1)
    except OSError as exc:
        raise SceneError(f"{where}: cannot be read ({_short(exc.strerror or exc)})") from None
    if path.stat().st_size == 0:
        raise SceneError(f"{where}: the file is empty; expected a mesh")
    import meshio
    said = io.StringIO()  # meshio prints its reasons and warnings, and may call sys.exit
    try:
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            return meshio.read(path)
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - meshio raises anything on a bad file
        lines = [ln.strip().removeprefix("Error: ") for ln in said.getvalue().splitlines() if ln.strip()]
        text = str(exc) if not isinstance(exc, SystemExit) else ""
        reason = " ".join(dict.fromkeys(lines + ([f"{type(exc).__name__}: {text}"] if text else [])))
        raise SceneError(f"{where}: meshio cannot read it ({_short(reason or type(exc).__name__)})") from None


def _points(points: np.ndarray, dim: int, where: str) -> np.ndarray:
    """The nodes as (n, dim) float64: a 2D mesh written with a constant third coordinate loses it."""
    try:
        p = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise SceneError(f"{where}: node coordinates are not numbers") from None
    if p.ndim != 2 or p.shape[0] == 0:
        raise SceneError(f"{where}: the mesh has no nodes")
    bad = np.flatnonzero(~np.all(np.isfinite(p), axis=1))
    if bad.size:
        raise SceneError(f"{where}: node {bad[0]} has coordinates {p[bad[0]].tolist()} "
                         f"({bad.size} such nodes); expected finite numbers")
    if p.shape[1] == dim:
        return p
    if p.shape[1] == 3 and dim == 2:
        z = p[:, 2]
        if np.all(z == z[0]):
            return np.ascontiguousarray(p[:, :2])
        raise SceneError(f"{where}: the scene is 2D but the nodes' z spans [{z.min():g}, {z.max():g}]; "
                         "expected a flat mesh (all z equal)")
    raise SceneError(f"{where}: the nodes have {p.shape[1]} coordinates; expected {dim} for a {dim}D scene")


def _membership(mesh, dim: int, where: str) -> tuple[list, list, dict]:
    """Which groups hold each cell: the group ids, per block a (cells, groups) boolean mask, and
    the names -> id. Groups are Gmsh physical tags (names of dimension ``dim``), else the named
    cell sets in file order (sets may overlap: Abaqus files often have one of every cell)."""
    if "gmsh:physical" in mesh.cell_data:
        tags = [np.asarray(t, dtype=np.int64).reshape(-1) for t in mesh.cell_data["gmsh:physical"]]
        for c, t in zip(mesh.cells, tags):
            if len(t) != len(c.data):
                raise SceneError(f"{where}: {len(t)} physical tags for {len(c.data)} {c.type} cells")
        ids = sorted({int(g) for c, t in zip(mesh.cells, tags) if c.dim == dim for g in t if g >= 0})
        names = {}
        for k, v in mesh.field_data.items():
            v = np.asarray(v).reshape(-1)
            if v.size and (v.size < 2 or int(v[1]) == dim):
                names[str(k)] = int(v[0])
        return ids, [t[:, None] == np.array(ids, dtype=np.int64)[None, :] for t in tags], names
    sets = {str(k): v for k, v in mesh.cell_sets.items() if not str(k).startswith("gmsh:")}
    masks = [np.zeros((len(c.data), len(sets)), dtype=bool) for c in mesh.cells]
    for gid, (name, per_block) in enumerate(sets.items()):
        for b, idx in enumerate(list(per_block)[:len(masks)]):
            idx = np.asarray([] if idx is None else idx, dtype=np.int64).reshape(-1)
            if idx.size and (idx.min() < 0 or idx.max() >= len(masks[b])):
                raise SceneError(f"{where}: cell set '{name}' names cell {idx.max()} of a block "
                                 f"of {len(masks[b])} cells")
            masks[b][idx, gid] = True
    return list(range(len(sets))), masks, {n: i for i, n in enumerate(sets)}


def _selected(groups, names: dict, present: list, where: str) -> list:
    """The group ids that ``groups`` (names or ints) asks for, in its order; an unknown one lists
    the groups there are."""
    available = ", ".join([f"'{n}' ({i})" for n, i in names.items()]
                          + [str(i) for i in present if i not in names.values()]) or "none"
    if isinstance(groups, (str, int)):
        groups = [groups]
    if not isinstance(groups, (list, tuple)) or not groups:
        raise SceneError(f"{where}: groups {groups!r}; expected a non-empty list of group names or "
                         f"ids; available groups: {available}")
    ids = []
    for g in groups:
        if isinstance(g, bool) or not isinstance(g, (str, int)):
            raise SceneError(f"{where}: group {g!r} is neither a name nor an integer; "
                             f"available groups: {available}")
        gid = names.get(g) if isinstance(g, str) else g
        if gid is None or (gid not in present):
            raise SceneError(f"{where}: no group {g!r} among the cells of this dimension; "
                             f"available groups: {available}")
        ids.append(int(gid))
    return ids


def _cell_groups(mask: np.ndarray, ids: list, order: list) -> tuple[np.ndarray, np.ndarray]:
    """Which cells to keep (in a group of ``order``) and each one's group: the first of ``order``
    that holds it (-1: none)."""
    group = np.full(len(mask), -1, dtype=np.int64)
    column = {g: k for k, g in enumerate(ids)}
    for g in reversed(order):
        group[mask[:, column[g]]] = g
    return group >= 0, group


def _check_block(cell_type: str, data, n_points: int, where: str) -> np.ndarray:
    try:
        cells = np.asarray(data, dtype=np.int64)
    except (TypeError, ValueError, OverflowError):
        raise SceneError(f"{where}: the {cell_type} connectivity is not integers") from None
    if cells.ndim != 2 or cells.shape[1] != NODES[cell_type]:
        raise SceneError(f"{where}: {cell_type} cells have shape {cells.shape}; "
                         f"expected (n, {NODES[cell_type]})")
    bad = np.flatnonzero(np.any((cells < 0) | (cells >= n_points), axis=1))
    if bad.size:
        raise SceneError(f"{where}: {cell_type} cell {bad[0]} names nodes {cells[bad[0]].tolist()} "
                         f"but the mesh has nodes 0..{n_points - 1}")
    return cells


def read_volume_mesh(path, dim: int, groups=None) -> VolumeMesh:
    """The cells of dimension ``dim`` of the mesh file ``path``, with their nodes (see the module
    docstring); ``groups`` (names or ids) keeps only the cells of those groups."""
    path = Path(path)
    where = f"mesh '{path}'"
    if dim not in VOLUME_CELLS:
        raise SceneError(f"{where}: dimension {dim!r}; expected 2 or 3")
    mesh = _load(path, where)
    points = _points(mesh.points, dim, where)
    found = [c.type for c in mesh.cells]
    ids, masks, names = _membership(mesh, dim, where)
    held = np.any([m.any(axis=0) for c, m in zip(mesh.cells, masks) if c.dim == dim], axis=0)
    present = [g for g, h in zip(ids, np.atleast_1d(held)) if h] if len(ids) else []
    names = {n: i for n, i in names.items() if i in present}
    wanted = None if groups is None else _selected(groups, names, present, where)
    volume = []
    for c, mask in zip(mesh.cells, masks):
        tdim = c.dim
        if tdim is not None and tdim < dim:
            continue
        if c.type not in VOLUME_CELLS[dim]:
            kind = f"{tdim}D " if tdim is not None else ""
            raise SceneError(f"{where}: has {kind}cells of type '{c.type}'; a {dim}D body accepts only "
                             f"{' and '.join(VOLUME_CELLS[dim])} cells (linear, no mid-side nodes)")
        volume.append((c.type, _check_block(c.type, c.data, len(points), where), mask))
    order = ids if wanted is None else wanted
    column = {g: k for k, g in enumerate(ids)}

    def chosen(mask: np.ndarray) -> np.ndarray:
        """Which cells the groups select (all of them without ``groups``)."""
        if wanted is None:
            return np.ones(len(mask), bool)
        return mask[:, [column[g] for g in wanted]].any(axis=1)

    blocks, repeats = [], []
    for (cell_type, cells, _), (mask, copies) in zip(volume, _merge_repeats(volume, chosen)):
        keep = chosen(mask) if copies is None else copies > 0
        group = _cell_groups(mask, ids, order)[1]
        if keep.any():
            blocks.append(MeshBlock(cell_type, np.ascontiguousarray(cells[keep]),
                                    np.ascontiguousarray(group[keep])))
            repeats.append(np.zeros(int(keep.sum()), np.int64) if copies is None
                           else copies[keep] - 1)
    if not blocks:
        kinds = ", ".join(dict.fromkeys(found)) or "no cells at all"
        picked = "" if groups is None else f" in groups {groups!r}"
        raise SceneError(f"{where}: no {dim}D cells{picked} (found {kinds}); expected "
                         f"{' or '.join(VOLUME_CELLS[dim])} cells")
    dropped = np.concatenate(repeats) if repeats else None
    return VolumeMesh(points, tuple(blocks), names,
                      dropped if dropped is not None and dropped.any() else None)


def _may_repeat(cells: np.ndarray) -> bool:
    """Whether two rows might hold the same nodes: an order-free hash of each row (the sum of its
    nodes' splitmix64), sorted. Equal node sets hash alike, so False is certain; True (a repeat or
    a rare collision) sends the rows to the exact comparison, which costs seconds per million."""
    with np.errstate(over="ignore"):
        z = cells.astype(np.uint64) + np.uint64(0x9E3779B97F4A7C15)
        h = np.sort(splitmix64_finish(z).sum(axis=1))
    return bool(np.any(h[1:] == h[:-1]))


def _merge_repeats(volume: list, chosen) -> list:
    """Per block ``(cell_type, cells, mask)``: its group mask and, where a cell of that type is
    listed more than once, ``copies`` (n,): for a cell's first listing, how many of its listings
    ``chosen`` selects (0 for the later listings, which are dropped); None for a block of a type
    listed once each (left as read). A cell's mask is the union of its listings' masks."""
    out = [(mask, None) for _, _, mask in volume]
    for cell_type in dict.fromkeys(t for t, _, _ in volume):
        ks = [k for k, (t, _, _) in enumerate(volume) if t == cell_type]
        cells = np.concatenate([volume[k][1] for k in ks])
        if not _may_repeat(cells):
            continue
        _, first, inverse = np.unique(np.sort(cells, axis=1), axis=0, return_index=True,
                                      return_inverse=True)
        if len(first) == len(cells):
            continue
        inverse = inverse.reshape(-1)
        mask = np.concatenate([volume[k][2] for k in ks])
        merged = np.zeros((len(first), mask.shape[1]), bool)
        np.logical_or.at(merged, inverse, mask)
        count = np.bincount(inverse, weights=chosen(mask), minlength=len(first)).astype(np.int64)
        copies = np.zeros(len(cells), np.int64)
        copies[first] = count
        at = np.cumsum([0] + [len(volume[k][1]) for k in ks])
        for j, k in enumerate(ks):
            rows = slice(at[j], at[j + 1])
            out[k] = (merged[inverse[rows]], copies[rows])
    return out


__all__ = ["MeshBlock", "VolumeMesh", "read_volume_mesh", "VOLUME_CELLS"]
