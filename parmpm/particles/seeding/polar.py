"""A disk or an annulus seeded in rings, so that its outer particles follow the circle.

A disk masked out of the grid's lattice has flats and steps: where the circle is tangent to a
lattice row a run of particles lies on one straight line (half a width of about
``√(R·s)`` for a spacing ``s``), and a disk rolls or slides over those corners as a polygon —
on a flat body in contact the error of the acceleration grew when the grid was refined. Here the
annulus from ``r_in`` to ``R`` (a disk: ``r_in = 0``) is cut into
``n = max(1, round((R − r_in)/s))`` rings of width ``Δr = (R − r_in)/n``; ring ``j`` (radii
``r₁ = r_in + jΔr`` to ``r₂ = r_in + (j+1)Δr``, mid radius ``r_m``) into
``m_j = max(3, round(2π r_m/Δr))`` equal sectors, so every cell is about ``Δr × Δr`` (a disk's
``m_j = round(2π(j + ½))``, the centre ring 3). One particle per cell, at the cell's centroid

    r_c = ⅔ (r₂³ − r₁³)/(r₂² − r₁²) · sin(Δθ/2)/(Δθ/2),  θ_c = (k + ½) Δθ,  Δθ = 2π/m_j,

with the cell's exact area ``A = ½ Δθ (r₂² − r₁²)`` as its volume: the particles' masses add
up to ``ρ π (R² − r_in²)`` (to round-off) and their first moment puts the centre of mass at the
centre. Every particle of the outer ring (and of the inner one) lies at the same distance from
the centre.

The CPDI domain (``r0``, two half-vectors) is the parallelogram along the cell's radial and
tangential directions, ``(Δr/2) e_r`` and ``(r_m Δθ/2) e_θ``, of area ``A``; the GIMP
half-widths (``lh0``) are the square of area ``A``, axis-aligned (GIMP's domains cannot turn;
:mod:`parmpm.particles.seeding.listed` does the same for mesh points). A cylinder or tube is
these cells extruded in layers (:mod:`parmpm.particles.seeding.cylindrical`).

Points come by global id, elementwise (the ring and sector from the ring offsets), so every block
and every rank makes the same bits.
"""
from __future__ import annotations

import math

import numpy as np


def check_radii(radius: float, inner: float) -> None:
    """A finite ``radius`` > 0 and ``0 ≤ inner < radius``, or a ValueError saying which."""
    if not (math.isfinite(radius) and radius > 0.0):
        raise ValueError(f"expected a finite radius > 0, got {radius!r}")
    if not (math.isfinite(inner) and 0.0 <= inner < radius):
        raise ValueError(f"expected an inner radius from 0 to below the radius {radius!r}, "
                         f"got {inner!r}")


class Rings:
    """The ring seeding of a disk (``inner`` = 0) or annulus of ``radius`` about ``center``
    for a particle spacing about ``size``; made by id, one block at a time
    (:class:`parmpm.particles.seeding.Seeds`). ``edges``: the block starts of ``n`` ids."""

    def __init__(self, center, radius: float, size: float, edges, inner: float = 0.0):
        self.center = np.asarray(center, float)
        self.radius, self.inner = float(radius), float(inner)
        check_radii(self.radius, self.inner)
        n = max(1, int(round((self.radius - self.inner) / size)))
        self.dr = (self.radius - self.inner) / n
        start = self.inner / self.dr  # r_m/Δr = start + j + ½ (a disk's: j + ½, the same bits)
        self.per_ring = np.array([max(3, int(round(2.0 * math.pi * (start + j + 0.5))))
                                  for j in range(n)], np.int64)
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
        r1 = self.inner + ring * self.dr
        return r1, self.inner + (ring + 1) * self.dr, dtheta, (k + 0.5) * dtheta

    def centroids(self, ids) -> tuple[np.ndarray, np.ndarray]:
        """Per id: the cell centroid's distance from the centre and its angle."""
        r1, r2, dtheta, theta = self._cells(ids)
        half = 0.5 * dtheta
        rc = (2.0 / 3.0) * (r2 ** 3 - r1 ** 3) / (r2 ** 2 - r1 ** 2) * np.sin(half) / half
        return rc, theta

    def points(self, ids) -> np.ndarray:
        rc, theta = self.centroids(ids)
        return self.center + np.stack([rc * np.cos(theta), rc * np.sin(theta)], axis=1)

    def block(self, j: int) -> np.ndarray:
        return self.points(np.arange(self.firsts[j], self.firsts[j + 1]))

    def sections(self, ids) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per id: the cell's area, its radial and tangential half-widths ``Δr/2`` and
        ``r_m Δθ/2`` (their product times 4 is the area), and its centre angle."""
        r1, r2, dtheta, theta = self._cells(ids)
        area = 0.5 * dtheta * (r2 ** 2 - r1 ** 2)
        return area, 0.5 * (r2 - r1), 0.25 * (r1 + r2) * dtheta, theta

    def domains(self, ids) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per id: the cell's area (the particle's volume), GIMP half-widths (n, 2) and CPDI
        half-vectors ``r0`` (n, 2, 2; columns radial, tangential)."""
        area, radial, tangential, theta = self.sections(ids)
        lh0 = np.repeat(0.5 * np.sqrt(area)[:, None], 2, axis=1)
        c, s = np.cos(theta), np.sin(theta)
        r0 = np.empty((area.size, 2, 2))
        r0[:, 0, 0], r0[:, 1, 0] = radial * c, radial * s
        r0[:, 0, 1], r0[:, 1, 1] = -tangential * s, tangential * c
        return area, lh0, r0

    def mean_spacing(self) -> np.ndarray:
        """The side of the square whose area is a mean cell's (both axes)."""
        return np.full(2, math.sqrt(math.pi * (self.radius ** 2 - self.inner ** 2) / self.n))
