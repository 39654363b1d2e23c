"""A cylinder or a tube seeded as its cross-section's rings extruded in layers, so that its
outer (and inner) particles follow the curved surface (the 3D
:mod:`parmpm.particles.seeding.polar`).

The cross-section, a disk of radius ``R`` or an annulus from ``r_in`` to ``R``, is cut into
:class:`~parmpm.particles.seeding.polar.Rings` cells for a spacing ``s``; the length ``L`` into
``n_z = max(1, round(L/s))`` equal layers of height ``Δz = L/n_z``. Each ring cell and layer is
one cell, one particle at its centroid — the ring cell's centroid at mid-layer — with the
cell's exact volume

    V = A · Δz,   A = ½ Δθ (r₂² − r₁²)

(the particles' masses add up to ``ρ π (R² − r_in²) L`` to round-off). The axis may point
anywhere: the cross-section lies in the plane of ``(e₁, e₂)``, an orthonormal frame with
``e₁ × e₂ = a`` the axis (for a coordinate axis the next two in cyclic order: the frame of axis
"z" is ``x, y``, of "x" ``y, z``, of "y" ``z, x``).

The CPDI domain (``r0``) is the box along the cell's radial, tangential and axial directions,
``(Δr/2) e_r``, ``(r_m Δθ/2) e_θ`` and ``(Δz/2) a`` (right-handed; ``8 det r0 = V``); the GIMP
half-widths (``lh0``) the cube of volume ``V``, axis-aligned.

Ids run over the cross-section's cells fastest, then the layers; points come by global id,
elementwise, so every block and every rank makes the same bits.
"""
from __future__ import annotations

import math

import numpy as np

from parmpm.particles.seeding.polar import Rings


def frame(axis) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(e₁, e₂, a)``, orthonormal and right-handed, ``a`` along ``axis``: for a coordinate
    axis the next two coordinate axes in cyclic order (exact zeros), else ``e₁`` the coordinate
    axis least along ``a`` made normal to it (Gram-Schmidt) and ``e₂ = a × e₁``."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    nonzero = np.flatnonzero(a)
    if nonzero.size == 1 and abs(a[nonzero[0]]) == 1.0:
        k = int(nonzero[0])
        e1, e2 = np.eye(3)[(k + 1) % 3], np.eye(3)[(k + 2) % 3]
        return (e1, e2, a) if a[k] > 0 else (e2, e1, a)
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    e1 = helper - np.dot(helper, a) * a
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(a, e1), a


class Tube:
    """The extruded-ring seeding of a cylinder (``inner`` = 0) or tube of ``radius`` and
    ``length`` along ``axis`` about its mid-point ``center``, for a particle spacing about
    ``size``; made by id, one block at a time (:class:`parmpm.particles.seeding.Seeds`).
    ``edges``: the block starts of ``n`` ids."""

    def __init__(self, center, axis, radius: float, length: float, size: float, edges,
                 inner: float = 0.0):
        self.center = np.asarray(center, float)
        self.length = float(length)
        if not (math.isfinite(self.length) and self.length > 0.0):
            raise ValueError(f"expected a finite length > 0, got {length!r}")
        self.section = Rings(np.zeros(2), radius, size, lambda n: np.array([0, n], np.int64),
                             inner)
        self.radius, self.inner = self.section.radius, self.section.inner
        self.e1, self.e2, self.axis = frame(axis)
        self.layers = max(1, int(round(self.length / size)))
        self.dz = self.length / self.layers
        self.per_layer = len(self.section)
        self.n = self.per_layer * self.layers
        self.firsts = edges(self.n)

    def __len__(self) -> int:
        return self.n

    def _split(self, ids):
        """Per id: its cross-section cell and its layer's mid-height from the mid-point."""
        ids = np.asarray(ids, np.int64)
        layer = ids // self.per_layer
        return ids - layer * self.per_layer, (layer + 0.5) * self.dz - 0.5 * self.length

    def _place(self, u: np.ndarray, v: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``u e₁ + v e₂ + w a`` per row, elementwise (the same bits for any subset)."""
        return u[:, None] * self.e1 + v[:, None] * self.e2 + w[:, None] * self.axis

    def points(self, ids) -> np.ndarray:
        cell, z = self._split(ids)
        rc, theta = self.section.centroids(cell)
        return self.center + self._place(rc * np.cos(theta), rc * np.sin(theta), z)

    def block(self, j: int) -> np.ndarray:
        return self.points(np.arange(self.firsts[j], self.firsts[j + 1]))

    def domains(self, ids) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per id: the cell's volume (the particle's), GIMP half-widths (n, 3) and CPDI
        half-vectors ``r0`` (n, 3, 3; columns radial, tangential, axial)."""
        cell, _ = self._split(ids)
        area, radial, tangential, theta = self.section.sections(cell)
        vol = area * self.dz
        lh0 = np.repeat(0.5 * np.cbrt(vol)[:, None], 3, axis=1)
        c, s, zero = np.cos(theta), np.sin(theta), np.zeros_like(theta)
        r0 = np.empty((vol.size, 3, 3))
        r0[:, :, 0] = self._place(radial * c, radial * s, zero)
        r0[:, :, 1] = self._place(-tangential * s, tangential * c, zero)
        r0[:, :, 2] = self._place(zero, zero, np.full_like(theta, 0.5 * self.dz))
        return vol, lh0, r0

    def mean_spacing(self) -> np.ndarray:
        """The side of the cube whose volume is a mean cell's (every axis)."""
        volume = math.pi * (self.radius ** 2 - self.inner ** 2) * self.length
        return np.full(3, (volume / self.n) ** (1.0 / 3.0))
