"""Pure index arithmetic of a patch layout (no MPI, no physics).

The global grid has ``cells[a]`` cells and ``cells[a] + 1`` nodes along each real axis. The cell
space is cut into equal patches of ``patch_size`` cells; the last patch along an axis may be
partial. Every node has exactly one owner: patch ``k`` along an axis owns nodes
``[k·P, (k+1)·P)``, and the last patch also owns the far boundary node ``cells``. Each patch holds
its nodes in a local box widened by ``ghost`` cells on each side, i.e. global nodes
``[k·P − g, (k+1)·P + g]`` — ``P + 2g + 1`` nodes per axis for every patch, so all patches share
one array shape. Axes beyond ``dim`` are padded to a single node (no ghosts) so kernels can be
written once for three axes.

Flat local node index: ``i0 + L0·(i1 + L1·i2)`` (axis 0 fastest); flat global node index likewise
with the global node counts. The box formulas themselves are :mod:`decomposition.boxes`'; a layout
holds their parameters.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from decomposition import boxes


@dataclass(frozen=True)
class PatchLayout:
    """Equal patches with ghost layers over a global cell box (dense: every patch exists)."""

    cells: tuple[int, ...]
    patch_size: tuple[int, ...]
    ghost: int
    dim: int = field(init=False)

    def __post_init__(self):
        cells = tuple(int(c) for c in self.cells)
        psize = tuple(min(int(p), c) for p, c in zip(self.patch_size, cells))
        if len(cells) != len(psize) or not 1 <= len(cells) <= 3:
            raise ValueError(f"cells {cells} and patch_size {psize} must have 1..3 equal lengths")
        if min(cells) < 1 or min(psize) < 1 or self.ghost < 0:
            raise ValueError("cells and patch_size must be positive, ghost non-negative")
        object.__setattr__(self, "cells", cells)
        object.__setattr__(self, "patch_size", psize)
        object.__setattr__(self, "dim", len(cells))

    # --- three-axis padded views (kernels use these) ---------------------------------------
    @property
    def cells3(self) -> np.ndarray:
        return np.array(list(self.cells) + [0] * (3 - self.dim), dtype=np.int64)

    @property
    def psize3(self) -> np.ndarray:
        return np.array(list(self.patch_size) + [1] * (3 - self.dim), dtype=np.int64)

    @property
    def ghost3(self) -> np.ndarray:
        return np.array([self.ghost] * self.dim + [0] * (3 - self.dim), dtype=np.int64)

    @property
    def patches_per_axis(self) -> np.ndarray:
        """Patch count per axis (padded axes: 1)."""
        c, p = self.cells3, self.psize3
        return np.where(np.arange(3) < self.dim, -(-c // p), 1).astype(np.int64)

    @property
    def n_patches(self) -> int:
        return int(np.prod(self.patches_per_axis))

    @property
    def global_nodes3(self) -> np.ndarray:
        """Global node count per axis (padded axes: 1)."""
        return self.cells3 + 1

    @property
    def local_nodes3(self) -> np.ndarray:
        """Local (ghost-inclusive) node count per axis: ``P + 2g + 1`` (padded axes: 1)."""
        return np.where(np.arange(3) < self.dim, self.psize3 + 2 * self.ghost3 + 1, 1).astype(np.int64)

    @property
    def n_local_nodes(self) -> int:
        return int(np.prod(self.local_nodes3))

    # --- per-patch boxes ---------------------------------------------------------------------
    def patch_coords(self) -> np.ndarray:
        """(n_patches, 3) patch grid coordinates in flat order (axis 0 fastest)."""
        n = self.patches_per_axis
        k2, k1, k0 = np.meshgrid(np.arange(n[2]), np.arange(n[1]), np.arange(n[0]), indexing="ij")
        return np.stack([k0.ravel(), k1.ravel(), k2.ravel()], axis=1).astype(np.int64)

    def patch_id(self, coords):
        """Flat id of the patch at ``(..., 3)`` coordinates (an int for one patch)."""
        ids = boxes.flat_patch_id(np.asarray(coords, dtype=np.int64), self.patches_per_axis)
        return int(ids) if np.ndim(ids) == 0 else ids

    def local_base(self, coords=None) -> np.ndarray:
        """Global node index of local node 0 (``k·P − g``) of the patches at ``(..., 3)``
        ``coords`` (default: every patch, in flat order)."""
        coords = self.patch_coords() if coords is None else np.asarray(coords, dtype=np.int64)
        return boxes.ghost_base(coords, self.psize3, self.ghost3)

    def owned_box(self, coords) -> tuple[np.ndarray, np.ndarray]:
        """Global node box [lo, hi) owned by the patches at ``(..., 3)`` ``coords``."""
        return boxes.owned_box(np.asarray(coords, dtype=np.int64), self.psize3,
                               self.patches_per_axis, self.global_nodes3)

    def local_box(self, coords) -> tuple[np.ndarray, np.ndarray]:
        """Global node box [lo, hi) held locally (owned + ghosts) by the patches at ``coords``."""
        lo = self.local_base(coords)
        return lo, lo + self.local_nodes3

    def patch_cells(self, coords) -> tuple[np.ndarray, np.ndarray]:
        """Cells ``[lo, hi)`` of the patches at ``(..., 3)`` ``coords`` (the points they own)."""
        return boxes.patch_cells(np.asarray(coords, dtype=np.int64), self.psize3, self.cells3)

    def locator(self) -> tuple[np.ndarray, np.ndarray]:
        """``(loc, inv_psize)`` for :func:`decomposition.boxes.patch_of_point_2d` and kin: rows
        cells, patch size and patches per axis (3-axis padded), and 1 / patch size."""
        return (np.array([self.cells3, self.psize3, self.patches_per_axis], np.int64),
                1.0 / self.psize3)

    def neighbour_offsets(self) -> list[tuple[int, int, int]]:
        """Offsets of every patch whose local box can overlap a patch's owned box, in the fixed
        lexicographic order that fixes the summation order of ghost contributions."""
        reach = [-(-(self.ghost + 1) // int(p)) if a < self.dim else 0
                 for a, p in enumerate(self.psize3)]
        ranges = [range(-r, r + 1) for r in reach]
        return [o for o in itertools.product(*ranges) if any(o)]
