"""The discretisation a rank's kernels see: grid, method, ``l_cr`` and the node boxes of its
patches (3-axis padded), and the exterior layer of cells outside the grid's faces."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from decomposition import PatchLayout
from parmpm.core.records import kernel_lcr
from parmpm.transfer.kernels2d.cells import usable_cells


@dataclass
class Discretisation:
    """Everything the kernels need to know about the grid, method and patches (3-axis padded).

    ``origin`` and ``layout`` describe the computational grid: the user's (physical) grid widened
    by ``exterior_lo[k]`` cells below and ``exterior_hi[k]`` cells above each axis (the exterior
    layer, :func:`exterior_cells`). Its physical faces are the global nodes ``face_lo3``,
    ``face_hi3``, where the grid update applies the face conditions; :attr:`cells` and
    :attr:`physical_origin` give the user's grid back. Without a layer both coincide."""

    dim: int
    method: int
    lcr: float | None     # None: no domain scaling (stored as the kernels' NO_SCALING)
    origin: np.ndarray
    h: np.ndarray
    layout: PatchLayout
    exterior_lo: np.ndarray | None = None   # (dim,) cells below each axis' first face
    exterior_hi: np.ndarray | None = None   # (dim,) cells above each axis' last face

    def __post_init__(self):
        self.lcr = kernel_lcr(self.lcr)
        pad = 3 - self.dim
        zeros = np.zeros(self.dim, np.int64)
        self.exterior_lo = zeros if self.exterior_lo is None else np.asarray(self.exterior_lo, np.int64)
        self.exterior_hi = zeros if self.exterior_hi is None else np.asarray(self.exterior_hi, np.int64)
        self.origin3 = np.concatenate([self.origin, np.zeros(pad)])
        self.h3 = np.concatenate([self.h, np.ones(pad)])
        self.inv_h3 = 1.0 / self.h3
        self.nloc = self.layout.local_nodes3
        self.nglob = self.layout.global_nodes3
        # global node index of the physical faces (padded axes: the single node 0)
        self.face_lo3 = np.concatenate([self.exterior_lo, np.zeros(pad, np.int64)])
        self.face_hi3 = self.nglob - 1 - np.concatenate([self.exterior_hi, np.zeros(pad, np.int64)])
        self.set_patches(np.arange(self.layout.n_patches))

    @classmethod
    def from_grid(cls, dim: int, method: int, lcr: float | None, grid, ghost: int,
                  exterior: tuple[np.ndarray, np.ndarray] | None = None) -> Discretisation:
        """The discretisation of a scene's grid (its record, ``scene.spec.grid``, with an
        explicit ``patch_size``) with ``ghost`` ghost cells and an exterior layer of
        ``exterior = (lo, hi)`` cells per axis (None: none): the patch layout covers
        ``cells + lo + hi`` cells from ``origin − lo·Δx``."""
        h = np.asarray(grid.cell_size, float)
        lo, hi = (np.zeros(dim, np.int64),) * 2 if exterior is None else exterior
        cells = np.asarray(grid.cells, np.int64) + lo + hi
        layout = PatchLayout(tuple(int(c) for c in cells), tuple(grid.patch_size), int(ghost))
        return cls(dim, method, lcr, np.asarray(grid.origin, float) - lo * h, h, layout, lo, hi)

    def with_patch_size(self, size: int) -> Discretisation:
        """The same grid cut into patches of ``size`` cells per axis, clipped to the user's cell
        count as ``grid.patch_size`` is: what another patch size would give."""
        psize = tuple(min(int(size), int(n)) for n in self.cells)
        return replace(self, layout=PatchLayout(self.layout.cells, psize, self.layout.ghost))

    @property
    def cells(self) -> np.ndarray:
        """The user's (physical) cell count per axis, without the exterior layer."""
        return np.asarray(self.layout.cells, np.int64) - self.exterior_lo - self.exterior_hi

    @property
    def physical_origin(self) -> np.ndarray:
        """The user's grid origin (the first physical face's position per axis)."""
        return self.origin + self.exterior_lo * self.h

    def set_patches(self, local_ids: np.ndarray) -> None:
        """Per-slot node boxes of this rank's patches (global ids ``local_ids``)."""
        coords = self.layout.patch_coords()[local_ids]
        self.base = self.layout.local_base(coords).astype(np.int64)
        lo, hi = self.layout.owned_box(coords)
        self.own_lo = (lo - self.base).astype(np.int64)
        self.own_hi = (hi - self.base).astype(np.int64)
        self.jlo, self.jhi = usable_cells(self.base, self.nloc, self.nglob)


def exterior_cells(grid, bodies, ghost: int) -> tuple[np.ndarray, np.ndarray]:
    """Cells of the exterior layer below and above each axis of a scene's ``grid`` and
    ``bodies`` (their records, ``scene.spec.grid`` and ``scene.spec.bodies``): ``grid.exterior``
    cells on every face when it is an integer; with ``"auto"``, ``ghost`` cells (the width of the
    ghost layer, i.e. the interpolator's reach: 0 for mpm, whose support never leaves the grid)
    on each face that a body's bounding box comes within one cell of, and none elsewhere, so a
    scene whose bodies start away from the faces runs bit for bit as without a layer."""
    d = len(grid.cells)
    if grid.exterior != "auto":
        n = np.full(d, int(grid.exterior), np.int64)
        return n, n.copy()
    h = np.asarray(grid.cell_size, float)
    glo = np.asarray(grid.origin, float)
    ghi = glo + h * np.asarray(grid.cells)
    lo, hi = np.zeros(d, np.int64), np.zeros(d, np.int64)
    for body in bodies:
        bmin, bmax = body.bounds()
        near = 1.0 - 1e-9  # within one cell: a support at the body's edge can reach the face
        lo[(np.asarray(bmin) - glo) / h < near] = ghost
        hi[(ghi - np.asarray(bmax)) / h < near] = ghost
    return lo, hi
