"""The energy in the body, and a watch that stops a run which blows up.

An explicit MPM step beyond its stability limit (CFL too large for the update order, a stiff
material on a coarse step) does not always end in NaN: the vibrating bar under USL at CFL 0.99
gains fifteen times its energy and runs on. The cheap invariant that catches it is the energy
balance of an elastic body under gravity,

    K + Ψ = K₀ + Ψ₀ + W_g,      W_g = Σ_p m_p g · (x_p − X_p),

with ``K = Σ ½ m |v|²`` and ``Ψ = Σ V₀ (1 − D) ψ(F)`` (:func:`parmpm.materials.stored_energy`).
Damping, fixed supports and the dissipation of MPM's grid projections only take energy out, so
the residual ``R = K + Ψ − (K₀ + Ψ₀ + W_g)`` of a sound run stays at or below zero. A ramped
gravity makes ``W_g`` (evaluated with today's g) an overestimate of the work done, which only
lowers ``R``. The watch stops the run when ``R`` exceeds ``limit`` times the largest energy the
body has held or been given, ``S = max(K₀ + Ψ₀ + W_g)`` over the samples so far. Runs driven by a
body force that does work (the manufactured solution) are not watched.

Totals are per-patch partial sums added in patch order (:func:`decomposition.ordered_sum`), so
the decision is the same on any number of ranks.
"""
from __future__ import annotations

import numpy as np

from decomposition import ordered_sum
from parmpm.jit import kernel
from parmpm.materials.laws import stored_energy
from parmpm.metrics.sums import patch_sums

#: steps between two samples of the watch: a blow-up grows geometrically, so a sample every few
#: steps catches it early, at a cost of one particle pass per ENERGY_EVERY steps
ENERGY_EVERY = 10


@kernel
def energy_terms(d, mass, vol0, v, x, x0, F, mat, damage, params, g):
    """Per particle: (kinetic energy, stored elastic energy, work of gravity ``m g·(x − X)``)."""
    n = mass.shape[0]
    out = np.zeros((n, 3))
    for i in range(n):
        ke = 0.0
        w = 0.0
        for a in range(d):
            ke += v[i, a] * v[i, a]
            w += g[a] * (x[i, a] - x0[i, a])
        out[i, 0] = 0.5 * mass[i] * ke
        out[i, 1] = vol0[i] * stored_energy(d, params[mat[i]], F[i], damage[i])
        out[i, 2] = mass[i] * w
    return out


def energy_totals(comm, patch_ids, P, params, g) -> np.ndarray:
    """(K, Ψ, W_g) over all ranks (collective), the same on any number of ranks."""
    terms = energy_terms(P.dim, P.mass, P.vol0, P.v, P.x, P.x0, P.F, P.mat, P.damage, params,
                         np.ascontiguousarray(g[:P.dim], dtype=np.float64))
    return ordered_sum(comm, patch_ids, patch_sums(P.start, terms))


class EnergyWatch:
    """Residual of the energy balance over a run; :meth:`sample` says when it has blown up."""

    def __init__(self, limit: float | None):
        self.limit = limit
        self.initial = None       # K₀ + Ψ₀
        self.scale = 0.0          # max(K₀ + Ψ₀ + W_g) so far
        self.growth = 0.0         # max R / S so far
        self.last = None          # (K, Ψ, W_g) of the last sample

    def state(self) -> dict:
        return {"initial": self.initial, "scale": self.scale, "growth": self.growth}

    def restore(self, state: dict | None) -> None:
        if state:
            self.initial, self.scale = state["initial"], state["scale"]
            self.growth = state["growth"]

    def sample(self, totals: np.ndarray) -> float | None:
        """Record (K, Ψ, W_g); return R/S when it exceeds the limit, else None."""
        k, psi, work = (float(v) for v in totals)
        self.last = (k, psi, work)
        if self.initial is None:
            self.initial = k + psi
        given = self.initial + work
        self.scale = max(self.scale, given, self.initial)
        if not self.scale > 0.0:
            return None
        growth = (k + psi - given) / self.scale
        if not np.isfinite(growth):
            growth = np.inf
        self.growth = max(self.growth, growth)
        if self.limit is not None and growth > self.limit:
            return growth
        return None

    def report(self) -> dict:
        """The watch's figures for ``summary.json``."""
        out = {"limit": self.limit, "max_growth": self.growth, "initial": self.initial}
        if self.last is not None:
            k, psi, work = self.last
            out.update(kinetic=k, elastic=psi, gravity_work=work,
                       residual=k + psi - ((self.initial or 0.0) + work))
        return out
