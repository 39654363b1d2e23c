"""A disk seeded in rings, so that its outer particles follow the circle.

A disk masked out of the grid's lattice has flats and steps: where the circle is tangent to a
lattice row a run of particles lies on one straight line (half a width of about
``√(R·s)`` for a spacing ``s``), and a disk rolls or slides over those corners as a polygon —
on a flat body in contact the error of the acceleration grew when the grid was refined. Here the
disk is cut into ``n = round(R/s)`` rings of width ``Δr = R/n``; ring ``j`` (radii
``r₁ = jΔr`` to ``r₂ = (j+1)Δr``) into ``m_j = round(2π(j + ½))`` equal sectors, so every cell
is about ``Δr × Δr`` (the centre ring has 3). One particle per cell, at the cell's centroid

    r_c = ⅔ (r₂³ − r₁³)/(r₂² − r₁²) · sin(Δθ/2)/(Δθ/2),   θ_c = (k + ½) Δθ,   Δθ = 2π/m_j,

with the cell's exact area ``A = ½ Δθ (r₂² − r₁²)`` as its volume: the particles' masses add up
to ``ρ π R²`` (to round-off) and their first moment puts the centre of mass at the centre.
Every particle of the outer ring lies at the same distance from the centre.

The CPDI domain (``r0``, two half-vectors) is the parallelogram along the cell's radial and
tangential directions, ``(Δr/2) e_r`` and ``(r_mid Δθ/2) e_θ`` (``r_mid`` the mid radius), of
area ``A``; the GIMP half-widths (``lh0``) are the square of area ``A``, axis-aligned (GIMP's
domains cannot turn; :mod:`parmpm.particles.seeding.listed` does the same for mesh points).

Points come by global id, elementwise (the ring and sector from the ring offsets), so every block
and every rank makes the same bits.
"""
from __future__ import annotations

import math

import numpy as np


class Rings:
    """The ring seeding of a disk of ``radius`` about ``center`` for a particle spacing about
    ``size``; made by id, one block at a time (:class:`parmpm.particles.seeding.Seeds`)."""

    def __init__(self, center, radius: float, size: float, edges):
        self.center = np.asarray(center, float)
        self.radius = float(radius)
        n = max(1, int(round(self.radius / size)))
        self.dr = self.radius / n
        self.per_ring = np.array([int(round(2.0 * math.pi * (j + 0.5))) for j in range(n)],
                                 np.int64)
        self.ring_first = np.concatenate([[0], np.cumsum(self.per_ring)]).astype(np.int64)
        self.n = int(self.ring_first[-1])
        self.firsts = edges(self.n)

    def __len__(self) -> int:
        return self.n

    def _cells(self, ids):
        """Per id: inner and outer radius, sector angle, centre angle."""
        ids = np.asarray(ids, np.int64)
        ring = np.searchsorted(self.ring_first, ids, side="right") - 1
        k = ids - self.ring_first[ring]
        dtheta = 2.0 * math.pi / self.per_ring[ring]
        return ring * self.dr, (ring + 1) * self.dr, dtheta, (k + 0.5) * dtheta

    def points(self, ids) -> np.ndarray:
        r1, r2, dtheta, theta = self._cells(ids)
        half = 0.5 * dtheta
        rc = (2.0 / 3.0) * (r2 ** 3 - r1 ** 3) / (r2 ** 2 - r1 ** 2) * np.sin(half) / half
        return self.center + np.stack([rc * np.cos(theta), rc * np.sin(theta)], axis=1)

    def block(self, j: int) -> np.ndarray:
        return self.points(np.arange(self.firsts[j], self.firsts[j + 1]))

    def domains(self, ids) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per id: the cell's area (the particle's volume), GIMP half-widths (n, 2) and CPDI
        half-vectors ``r0`` (n, 2, 2; columns radial, tangential)."""
        r1, r2, dtheta, theta = self._cells(ids)
        area = 0.5 * dtheta * (r2 ** 2 - r1 ** 2)
        lh0 = np.repeat(0.5 * np.sqrt(area)[:, None], 2, axis=1)
        radial, tangential = 0.5 * (r2 - r1), 0.25 * (r1 + r2) * dtheta
        c, s = np.cos(theta), np.sin(theta)
        r0 = np.empty((area.size, 2, 2))
        r0[:, 0, 0], r0[:, 1, 0] = radial * c, radial * s
        r0[:, 0, 1], r0[:, 1, 1] = -tangential * s, tangential * c
        return area, lh0, r0

    def mean_spacing(self) -> np.ndarray:
        """The side of the square whose area is a mean cell's (both axes)."""
        return np.full(2, math.sqrt(math.pi * self.radius ** 2 / self.n))
