"""A sphere seeded in shells, so that its outer particles follow the surface (the 3D
:mod:`parmpm.particles.seeding.polar`).

A sphere masked out of the grid's lattice has flats and steps as a lattice disk has, and rolls
over them as a polyhedron. Here the sphere is cut into ``n = round(R/s)`` shells of width
``Δr = R/n``. Shell ``j`` (radii ``r₁ = jΔr`` to ``r₂ = (j+1)Δr``, mid radius ``r_m``) is cut into
``b_j = round(π(j + ½))`` bands of equal polar angle ``Δθ = π/b_j``, and each band (``θ₁`` to
``θ₂``) into ``m = max(1, round(2π r_m sin θ_mid / Δr))`` equal sectors ``Δφ = 2π/m``, so every
cell is about ``Δr`` on each side. One particle per cell, at the cell's centroid, with the cell's
exact volume

    V = (r₂³ − r₁³)/3 · (cos θ₁ − cos θ₂) · Δφ,

and centroid, from ``∫ r³ dr``, ``∫ sin²θ dθ``, ``∫ sinθ cosθ dθ`` and the sector's
``∫ (cos φ, sin φ) dφ``: the particles' masses add up to ``ρ (4/3) π R³`` to round-off and their
first moment puts the centre of mass at the centre.

The CPDI domain (``r0``) is the parallelepiped along the cell's radial, polar and azimuthal
directions at its centroid, ``(Δr/2) e_r``, ``(r_m Δθ/2) e_θ`` and ``(r_m sin θ_c Δφ/2) e_φ``,
the two tangential half-vectors scaled by one factor so that its volume is ``V``; the GIMP
half-widths (``lh0``) are the cube of volume ``V``, axis-aligned.

Points come by global id, elementwise (band and sector from the band offsets), so every block and
every rank makes the same bits.
"""
from __future__ import annotations

import math

import numpy as np


class Shells:
    """The shell seeding of a sphere of ``radius`` about ``center`` for a particle spacing
    about ``size``; made by id, one block at a time (:class:`parmpm.particles.seeding.Seeds`)."""

    def __init__(self, center, radius: float, size: float, edges):
        self.center = np.asarray(center, float)
        self.radius = float(radius)
        n = max(1, int(round(self.radius / size)))
        self.dr = self.radius / n
        shell, theta1, theta2, sectors = [], [], [], []
        for j in range(n):
            bands = max(1, int(round(math.pi * (j + 0.5))))
            edges_theta = np.linspace(0.0, math.pi, bands + 1)
            mid = 0.5 * (edges_theta[:-1] + edges_theta[1:])
            m = np.maximum(1, np.round(2.0 * math.pi * (j + 0.5) * np.sin(mid))).astype(np.int64)
            shell.append(np.full(bands, j, np.int64))
            theta1.append(edges_theta[:-1])
            theta2.append(edges_theta[1:])
            sectors.append(m)
        self.band_shell = np.concatenate(shell)
        self.band_theta = np.stack([np.concatenate(theta1), np.concatenate(theta2)], axis=1)
        self.band_sectors = np.concatenate(sectors)
        self.band_first = np.concatenate([[0], np.cumsum(self.band_sectors)]).astype(np.int64)
        self.n = int(self.band_first[-1])
        self.firsts = edges(self.n)

    def __len__(self) -> int:
        return self.n

    def _cells(self, ids):
        """Per id: radii (r₁, r₂), polar angles (θ₁, θ₂), azimuths (φ₁, φ₂)."""
        ids = np.asarray(ids, np.int64)
        band = np.searchsorted(self.band_first, ids, side="right") - 1
        k = ids - self.band_first[band]
        j = self.band_shell[band]
        dphi = 2.0 * math.pi / self.band_sectors[band]
        return (j * self.dr, (j + 1) * self.dr, self.band_theta[band, 0],
                self.band_theta[band, 1], k * dphi, (k + 1) * dphi)

    def _volume_and_centroid(self, ids):
        r1, r2, t1, t2, p1, p2 = self._cells(ids)
        radial3 = (r2 ** 3 - r1 ** 3) / 3.0
        radial4 = (r2 ** 4 - r1 ** 4) / 4.0
        polar1 = np.cos(t1) - np.cos(t2)                                   # ∫ sinθ dθ
        polar2 = 0.5 * (t2 - t1) - 0.25 * (np.sin(2.0 * t2) - np.sin(2.0 * t1))  # ∫ sin²θ
        polar3 = 0.5 * (np.sin(t2) ** 2 - np.sin(t1) ** 2)                # ∫ sinθ cosθ dθ
        vol = radial3 * polar1 * (p2 - p1)
        rel = np.stack([radial4 * polar2 * (np.sin(p2) - np.sin(p1)),
                        radial4 * polar2 * (np.cos(p1) - np.cos(p2)),
                        radial4 * polar3 * (p2 - p1)], axis=1) / vol[:, None]
        return vol, rel, (r1, r2, t1, t2, p1, p2)

    def points(self, ids) -> np.ndarray:
        return self.center + self._volume_and_centroid(ids)[1]

    def block(self, j: int) -> np.ndarray:
        return self.points(np.arange(self.firsts[j], self.firsts[j + 1]))

    def domains(self, ids) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per id: the cell's volume (the particle's), GIMP half-widths (n, 3) and CPDI
        half-vectors ``r0`` (n, 3, 3; columns radial, polar, azimuthal)."""
        vol, rel, (r1, r2, t1, t2, p1, p2) = self._volume_and_centroid(ids)
        lh0 = np.repeat(0.5 * np.cbrt(vol)[:, None], 3, axis=1)
        dist = np.linalg.norm(rel, axis=1)
        theta = np.arccos(np.clip(rel[:, 2] / dist, -1.0, 1.0))
        phi = np.arctan2(rel[:, 1], rel[:, 0])
        rm = 0.5 * (r1 + r2)
        radial = 0.5 * (r2 - r1)
        polar = 0.5 * rm * (t2 - t1)
        azimuthal = 0.5 * rm * np.maximum(np.sin(theta), 0.0) * (p2 - p1)
        # one factor on both tangential half-vectors: 8 · radial · polar · azimuthal = V
        azimuthal = np.maximum(azimuthal, 1e-3 * polar)
        scale = np.sqrt(vol / (8.0 * radial * polar * azimuthal))
        st, ct, sp, cp = np.sin(theta), np.cos(theta), np.sin(phi), np.cos(phi)
        e_r = np.stack([st * cp, st * sp, ct], axis=1)
        e_t = np.stack([ct * cp, ct * sp, -st], axis=1)
        e_p = np.stack([-sp, cp, np.zeros_like(sp)], axis=1)
        r0 = np.empty((vol.size, 3, 3))
        r0[:, :, 0] = radial[:, None] * e_r
        r0[:, :, 1] = (scale * polar)[:, None] * e_t
        r0[:, :, 2] = (scale * azimuthal)[:, None] * e_p
        return vol, lh0, r0

    def mean_spacing(self) -> np.ndarray:
        """The side of the cube whose volume is a mean cell's (every axis)."""
        return np.full(3, (4.0 / 3.0 * math.pi * self.radius ** 3 / self.n) ** (1.0 / 3.0))
