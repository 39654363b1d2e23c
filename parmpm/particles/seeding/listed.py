"""Seeds given point by point, each with its own volume: a volume mesh's quadrature points
(:func:`parmpm.geometry.mesh.mesh_particles`) or a particle file's rows
(:mod:`parmpm.io.particle_file`), in file order (global ids = that order, on any number of ranks).

A particle's domain is the cube of its own volume: ``vol0`` as given, half-width
``lh0 = ½·vol0^(1/d)`` on every axis and ``r0 = diag(lh0)``. Why a cube and not the element's
shape: a quadrature point's share of an element has no shape of its own, and the GIMP/CPDI
kernels need only a domain of the right volume about the point; the cube keeps their partition
of unity with no knowledge of the mesh. A file's ``F`` is carried (``r0`` stays the reference
domain, as after any step) and the stress follows from it and the material.

Blocks, as every other body's (:class:`parmpm.particles.seeding.Seeds` counts and keeps patch by
patch): :data:`parmpm.particles.seeding.BLOCK` rows at a time.

On several ranks only rank 0 reads the file; each rank's :class:`Share` holds the rows of its own
particles, which rank 0 sends it once the patches are dealt out (:mod:`parmpm.driver.listed_share`).
"""
from __future__ import annotations

import numpy as np

from parmpm.materials.laws import cauchy_stress
from parmpm.particles.seeding.velocity import _initial_affine, _initial_velocity


class Listed:
    """A body's listed seeds: positions ``x`` (n, d), reference volumes ``vol`` (n,), optional
    per-row ``velocity`` (n, d), material ``rows`` (n,) int64 and ``F`` (n, d, d)."""

    def __init__(self, x, vol, edges, velocity=None, rows=None, F=None):
        self.x = np.ascontiguousarray(x, float)
        self.vol = np.ascontiguousarray(vol, float)
        self.velocity, self.rows, self.F = velocity, rows, F
        self.n = int(self.x.shape[0])
        self.firsts = edges(self.n)

    def __len__(self) -> int:
        return self.n

    def block(self, j: int) -> np.ndarray:
        return self.x[self.firsts[j]:self.firsts[j + 1]]

    def local(self, ids) -> np.ndarray:
        """The rows of seeds ``ids`` in these arrays (all of them: the ids themselves)."""
        return np.asarray(ids, np.int64)

    def points(self, ids) -> np.ndarray:
        return self.x[self.local(ids)]

    def material_rows(self, ids, row: int) -> np.ndarray:
        """The material row of every seed ``ids``: the file's, else the body's ``row``."""
        if self.rows is None:
            return np.full(len(ids), row, np.int64)
        return self.rows[self.local(ids)]


class Share(Listed):
    """One rank's rows of a listed body of ``n`` seeds: those of the seeds ``held`` (increasing
    ids within the body), the rest on other ranks. Without rows yet (:meth:`awaiting`) it only
    counts the body's seeds, for the global ids of the bodies after it."""

    def __init__(self, n: int, held, x, vol, velocity=None, rows=None, F=None):
        super().__init__(x, vol, lambda _: np.zeros(1, np.int64), velocity, rows, F)
        self.n = int(n)
        self.held = np.asarray(held, np.int64)

    @classmethod
    def awaiting(cls, n: int, dim: int) -> Share:
        return cls(n, np.zeros(0, np.int64), np.zeros((0, dim)), np.zeros(0))

    def block(self, j: int) -> np.ndarray:
        raise TypeError("a rank's share of a listed body has no blocks: its rows come from rank 0")

    def local(self, ids) -> np.ndarray:
        ids = np.asarray(ids, np.int64)
        at = np.searchsorted(self.held, ids)
        if ids.size and (at.max() >= self.held.size or np.any(self.held[at] != ids)):
            raise ValueError("seeds asked of a rank's share that it does not hold")
        return at


def listed_seeds(body, dim: int, material_rows: dict, edges) -> Listed:
    """The :class:`Listed` seeds of a mesh or particle body (``body.listed``: read once)."""
    data = body.listed(dim)
    rows = None
    if data.material is not None:
        rows = np.full(len(data.material), -1, np.int64)
        for name, row in material_rows.items():  # a loop over the materials, not the rows
            rows[data.material == name] = row
    return Listed(data.x, data.vol, edges, data.velocity, rows, data.F)


def fill(P, s: slice, src: Listed, ids: np.ndarray, body, row: int, params: np.ndarray,
         optional: tuple) -> None:
    """Fields of the rows ``s`` of ``P`` from the seeds ``ids`` of ``src``."""
    d = P.dim
    at = src.local(ids)
    pts = src.x[at]
    P.x[s] = pts
    P.x0[s] = pts
    vol = src.vol[at]
    mats = src.material_rows(ids, row)
    if src.velocity is None:
        P.v[s] = _initial_velocity(d, body, pts)
        if "affine" in optional:
            P.affine[s] = _initial_affine(d, body, pts)
    else:  # the file's velocities: no gradient known (APIC's C starts at zero)
        P.v[s] = src.velocity[at]
    P.vol0[s] = vol
    P.mass[s] = params[mats, 1] * vol
    P.mat[s] = mats
    half = 0.5 * vol ** (1.0 / d)
    P.lh0[s] = half[:, None]
    r0 = np.zeros((len(ids), d, d))
    for k in range(d):
        r0[:, k, k] = half
    P.r0[s] = r0
    if src.F is not None:
        P.F[s] = src.F[at]
        F, stress, damage = P.F[s], P.stress[s], P.damage[s]
        for i in range(len(ids)):  # set-up only
            cauchy_stress(d, params[mats[i]], F[i], damage[i], stress[i])
        P.stress[s] = stress
