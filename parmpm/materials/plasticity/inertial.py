"""The μ(I) rheology on Drucker–Prager's cone: a friction that grows with the inertial number
(GDR MiDi 2004; Jop, Forterre & Pouliquen 2006, *Nature* 441, 727–730), in the form
Dunatunga & Kamrin (2015, *J. Fluid Mech.* 779, 483–513) put into MPM.

Jop et al. write the flowing grains' stress as ``|τ| = μ(I) P`` with ``|τ| = √J2`` (so ``μ`` is
the cone's slope ``η``), the shear rate ``γ̇ = √(½ γ̇_ij γ̇_ij)`` (``γ̇_ij = 2 D_ij``) and

    ``I = γ̇ d / √(P / ρ_s)``,   ``η(I) = η_s + (η_2 − η_s) I / (I_0 + I)``,

``d`` the grain diameter, ``ρ_s`` the grains' density, ``I_0`` a constant. ``η_s`` and ``η_2``
are the cone slopes of the friction angles φ and φ_2 under the material's Mohr–Coulomb matching.
In the return map the shear rate is the plastic one: the cone multiplier ``Δγ`` over the step,
since ``|dev Δε_p| = Δγ/√2`` and so ``γ̇_p = Δγ/Δt``. The return solves, on the cone,

    ``g(Δγ) = q* − G Δγ + η(I(Δγ)) p(Δγ) − ξ c = 0``,   ``p = p* − K η̄ Δγ``,

an implicit (backward Euler) rate law: stable for any step. ``g`` falls monotonically while
``p < 0`` (each term falls), from ``f* > 0`` at 0 to ``(η(I) − η_s) p ≤ 0`` at the static
multiplier, so the root is unique and bracketed; a safeguarded Newton iteration finds it.
docs/concepts/drucker-prager.md ("Rate dependence: μ(I)").
"""
import math

from parmpm.core.jit import helper_kernel

#: the Newton iteration stops when a step moves Δγ by less than this fraction of the bracket
RELATIVE_TOLERANCE = 1e-15
MAX_ITERATIONS = 100


@helper_kernel
def inertial_slope(eta, eta2, i0, inertial):
    """``η(I) = η_s + (η_2 − η_s) I / (I_0 + I)``: the cone's slope at inertial number ``I``
    (written ``1 / (1 + I_0/I)``: ``η_2`` at ``I = ∞``, ``η_s`` at 0)."""
    return eta + (eta2 - eta) / (1.0 + i0 / inertial)


@helper_kernel
def _residual(x, q_tr, p_tr, K, G, eta, xi, eta_bar, c, eta2, i0, a):
    """``(g, g')`` at ``Δγ = x`` (``p < 0`` throughout the bracket). An overflowing ``I`` gives
    ``η_2`` and a NaN slope, which sends the iteration to bisection."""
    p = p_tr - K * eta_bar * x
    big_p = -p
    root = math.sqrt(big_p)
    inertial = a * x / root
    h = inertial_slope(eta, eta2, i0, inertial)
    g = q_tr - G * x + h * p - xi * c
    di = (a / root) * (1.0 + K * eta_bar * x / (2.0 * big_p))  # dI/dΔγ (P grows with Δγ)
    dh = (eta2 - eta) * i0 / ((i0 + inertial) * (i0 + inertial))
    return g, -G + dh * di * p - h * K * eta_bar


@helper_kernel
def inertial_cone(q_tr, p_tr, K, G, eta, xi, eta_bar, c, eta2, i0, a, dg_static):
    """The cone multiplier ``Δγ`` of the rate-dependent return, in ``[0, dg_static]`` (the
    rate-independent one: ``η(I) ≥ η_s`` only shortens the return). ``a = d √ρ_s / Δt``, so that
    ``I = a Δγ / √P``. Needs ``p* < 0`` (compression: the inertial number needs a pressure)."""
    lo, hi = 0.0, dg_static
    x = dg_static
    for _ in range(MAX_ITERATIONS):
        g, dg = _residual(x, q_tr, p_tr, K, G, eta, xi, eta_bar, c, eta2, i0, a)
        if g == 0.0:
            return x
        if g > 0.0:
            lo = x
        else:
            hi = x
        step = g / dg if dg < 0.0 else math.inf
        nx = x - step
        if not lo < nx < hi:  # Newton leaves the bracket: bisect
            nx = 0.5 * (lo + hi)
        if abs(nx - x) <= RELATIVE_TOLERANCE * dg_static:
            return nx
        x = nx
    return x
