"""The step's grid phase on this rank: the constraints it applies, the mirror-face fold before the
ghost accumulation, and the nodal update from the summed mass, momentum and force.

Set up once from the scene's boundary (faces, node regions) and the smallest particle mass; the
grid fields it reads and writes are the stepper's :class:`~parmpm.step.grid_buffers.GridBuffers`.
"""
from __future__ import annotations

import math

import numpy as np

from decomposition import allreduce_max
from parmpm.core.records import AXES, Constraints, OwnedNodes
from parmpm.grid.symmetry import (fold_moments, fold_sums, mirror_faces, reflect_beyond,
                                  row_signs)
from parmpm.grid.update import grid_update, region_node_ranges


class GridPhase:
    """``bc`` (3, 2) face conditions, ``regions``/``region_normal`` the held node regions,
    ``damping``, ``mass_eps`` (nodes lighter than it are void), ``mls`` (momentum rows that
    already hold ``Δt f``)."""

    def __init__(self, disc, bc: np.ndarray, regions: np.ndarray, region_normal, damping: float,
                 mls: bool, comm, particle_mass: np.ndarray):
        self.disc, self.bc, self.regions, self.damping, self.mls = disc, bc, regions, damping, mls
        self.region_normal = (np.full(regions.shape[0], -1, np.int64) if region_normal is None
                              else np.asarray(region_normal, np.int64))
        self.region_ranges = region_node_ranges(regions, disc.origin3, disc.h3, disc.dim)
        #: mirror (symmetry or clamped) faces (3, 2) when there are any (:mod:`parmpm.grid.symmetry`),
        #: else None
        sym = mirror_faces(bc)
        self.symmetry = sym if sym.any() else None
        self._signs = row_signs(disc.dim, bc)
        mmin = float(particle_mass.min(initial=np.inf))
        mmin = float(allreduce_max(comm, np.array([-mmin]))[0])
        self.mass_eps = 1e-12 * (-mmin if math.isfinite(mmin) else 1.0)
        self._mass = np.zeros((0, 1, 0))  # contact's moments fold: the unfolded mass

    def records(self) -> tuple[OwnedNodes, Constraints]:
        """The grid update's records: the owned nodes of every patch slot, the constraints."""
        D = self.disc
        nodes = OwnedNodes(D.own_lo, D.own_hi, D.base, D.nloc, D.face_lo3, D.face_hi3)
        constraints = Constraints(self.bc, self.regions, self.region_normal, self.region_ranges,
                                  D.origin3, D.h3)
        return nodes, constraints

    def update(self, grid, dt: float, gravity: np.ndarray, momentum_only: bool,
               nodes: OwnedNodes | None = None) -> None:
        """Nodal velocities (and increments) from the summed blocks of ``grid``, at ``nodes``
        (default: every owned node; a contact field's: where it can have mass)."""
        owned, constraints = self.records()
        nodes = owned if nodes is None else nodes
        grid_update(AXES[self.disc.dim], nodes, constraints, dt, gravity, self.damping, self.mass_eps,
                    grid.gsum_block, grid.gnew_block, momentum_only, self.mls)

    def fold(self, grid, rows: int, momentum_only: bool) -> None:
        """Mirror faces: fold the mirror images into this rank's partial sums (the ``rows`` P2G
        filled, or the momentum alone in a MUSL re-map) before the ghost accumulation."""
        if self.symmetry is None:
            return
        D = self.disc
        d = D.dim
        fold_sums(d, D.nloc, D.base, D.face_lo3, D.face_hi3, self.symmetry, self._signs,
                  1 if momentum_only else 0, 1 + d if momentum_only else rows, grid.gsum_block)

    def fold_moments(self, moments, grid) -> None:
        """Mirror faces: fold the images' first moments into contact's ``moments`` (a field's,
        rows 1..d) from ``grid``'s mass row, before :meth:`fold` folds that mass."""
        if self.symmetry is None:
            return
        D = self.disc
        m = grid.gsum_block[:, :1]
        if self._mass.shape != m.shape:  # kept: a copy per step would be garbage
            self._mass = np.zeros(m.shape)
        np.copyto(self._mass, m)
        fold_moments(D.dim, D.nloc, D.base, D.face_lo3, D.face_hi3, self.symmetry, D.origin3, D.h3,
                     self._mass, moments.gsum_block)

    def reflect_beyond(self, grid) -> None:
        """Mirror faces: the nodes beyond take the reflection of their twins' updated velocities
        (``grid``'s v, Δv rows) again, after contact's correction."""
        if self.symmetry is None:
            return
        D = self.disc
        d = D.dim
        signs = self._signs[:, :, 1:]  # the velocity rows reflect as the momentum rows do
        reflect_beyond(d, D.nloc, D.base, D.face_lo3, D.face_hi3, self.symmetry, signs,
                       grid.gnew_block)
