"""Exact solutions used to verify parmpm (pure numpy).

Notation as in ``docs/verification.md``: reference coordinate ``X`` measured from the support
(``X = 0`` fixed, ``X = L`` free), stretch ``λ = ∂x/∂X``, nominal (first Piola–Kirchhoff)
stress ``P``, wave speed ``c = sqrt(E/ρ)``, ``β_n = (2n − 1)π/(2L)``, ``ω_n = c β_n``.

* Axial vibrating bar (Sulsky, Zhou & Schreyer 1995; Bardenhagen 2002): small strain, fixed-free,
  initial velocity ``v(X, 0) = v0 sin(β_n X)``.
* Hanging (self-weighted) bar: the static state is exact for *any* 1D law because the weight
  below ``X`` does not depend on the deformation, ``P(λ(X)) = ρ g (L − X)``; the sudden-gravity
  dynamic response is the small-strain d'Alembert solution.
* Axis-aligned manufactured solution (Wallstedt & Guilkey 2008; Kamojjala et al. 2015): a
  prescribed large-deformation motion and the neo-Hookean body force that drives it.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import numpy as np

from parmpm.core.errors import SceneError

logger = logging.getLogger(__name__)

__all__ = [
    "mode_constants",
    "vibrating_bar_com_velocity",
    "vibrating_bar_fields",
    "lame_parameters",
    "nominal_stress_1d",
    "hanging_bar_static",
    "hanging_bar_static_displacement",
    "hanging_bar_dynamic_tip",
    "hanging_bar_dynamic_series",
    "manufactured_phases",
    "manufactured_motion",
    "manufactured_body_force",
]


# --------------------------------------------------------------------------------------------
# Axial vibrating bar
# --------------------------------------------------------------------------------------------
def mode_constants(L: float, E: float, rho: float, mode: int = 1) -> tuple[float, float, float]:
    """Return ``(β_n, ω_n, c)`` of a fixed-free bar.

    ``β_n = (2n − 1)π/(2L)``, ``c = sqrt(E/ρ)``, ``ω_n = c β_n`` (docs/verification.md §1).
    """
    if mode < 1:
        raise ValueError(f"mode must be >= 1, got {mode}")
    beta = (2 * mode - 1) * math.pi / (2.0 * L)
    c = math.sqrt(E / rho)
    return beta, c * beta, c


def vibrating_bar_com_velocity(t, v0: float, L: float, E: float, rho: float, mode: int = 1):
    """Centre-of-mass velocity of the vibrating bar: ``v̄(t) = v0/(β_n L) · cos(ω_n t)``.

    From ``v = v0 cos(ω_n t) sin(β_n X)`` averaged over ``[0, L]``:
    ``(1/L)∫ sin(β_n X) dX = (1 − cos(β_n L))/(β_n L) = 1/(β_n L)`` since ``cos(β_n L) = 0``
    (Bardenhagen 2002, docs/verification.md §1). ``t`` may be a scalar or an array.
    """
    beta, omega, _ = mode_constants(L, E, rho, mode)
    return v0 / (beta * L) * np.cos(omega * np.asarray(t, dtype=float))


def vibrating_bar_fields(X, t, v0: float, L: float, E: float, rho: float, mode: int = 1):
    """Displacement, velocity and stress of the vibrating bar (docs/verification.md §1).

    ``u = (v0/ω_n) sin(ω_n t) sin(β_n X)``, ``v = v0 cos(ω_n t) sin(β_n X)``,
    ``σ = ρ c v0 sin(ω_n t) cos(β_n X)`` (``σ = E ∂u/∂X`` with ``E β_n/ω_n = ρ c``).
    ``X`` and ``t`` broadcast against each other. Returns ``(u, v, sigma)``.
    """
    beta, omega, c = mode_constants(L, E, rho, mode)
    X = np.asarray(X, dtype=float)
    t = np.asarray(t, dtype=float)
    u = (v0 / omega) * np.sin(omega * t) * np.sin(beta * X)
    v = v0 * np.cos(omega * t) * np.sin(beta * X)
    sigma = rho * c * v0 * np.sin(omega * t) * np.cos(beta * X)
    return u, v, sigma


# --------------------------------------------------------------------------------------------
# 1D material laws (uniaxial strain, F = λ)
# --------------------------------------------------------------------------------------------
def lame_parameters(E: float, nu: float) -> tuple[float, float]:
    """``λ_L = Eν/((1+ν)(1−2ν))``, ``μ = E/(2(1+ν))``."""
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def nominal_stress_1d(model: str, E: float, nu: float) -> Callable[[np.ndarray], np.ndarray]:
    """Return ``P(λ)``, the nominal stress of parmpm's material ``model`` in 1D (uniaxial strain).

    In 1D ``F = λ``, ``J = λ`` and ``P = J σ F^-T = σ``, so the nominal stress equals the Cauchy
    stress of the 3D law evaluated at ``F = diag(λ, 1, 1)``:

    * ``"linear_elastic"`` (small strain): ``P = (λ_L + 2μ)(λ − 1)``;
    * ``"neo_hookean"``: ``P = [μ(λ² − 1) + λ_L ln λ] / λ`` (with ν = 0: ``(E/2)(λ − 1/λ)``).

    Unknown models raise :class:`~parmpm.core.errors.SceneError`.
    """
    lam, mu = lame_parameters(E, nu)
    key = model.lower().replace("-", "_")
    if key in ("linear_elastic", "linear", "linearelastic"):
        modulus = lam + 2.0 * mu

        def stress(stretch):
            return modulus * (np.asarray(stretch, dtype=float) - 1.0)

    elif key in ("neo_hookean", "neohookean"):

        def stress(stretch):
            s = np.asarray(stretch, dtype=float)
            return (mu * (s * s - 1.0) + lam * np.log(s)) / s

    else:
        raise SceneError(f"no exact 1D law for material model {model!r}")
    stress.__doc__ = f"Nominal stress P(λ) of {key} with E={E}, nu={nu}."
    return stress


# --------------------------------------------------------------------------------------------
# Hanging bar
# --------------------------------------------------------------------------------------------
def _solve_monotone(stress_of_stretch, target: np.ndarray, iters: int = 200) -> np.ndarray:
    """Solve ``P(λ) = target`` elementwise for monotone increasing ``P`` by bisection.

    The bracket starts at ``[1, 2]`` (or ``[1/2, 1]`` for negative targets) and is widened by
    doubling (halving) until it holds the root; bisection then runs to machine precision.
    """

    vectorised = [True]

    def P(s):
        if vectorised[0]:
            try:
                out = np.asarray(stress_of_stretch(s), dtype=float)
                if out.shape == s.shape:
                    return out
            except (TypeError, ValueError):
                pass
            vectorised[0] = False  # a scalar-only callable: evaluate point by point
        return np.array([float(stress_of_stretch(float(si))) for si in s.ravel()]).reshape(s.shape)

    lo = np.ones_like(target)
    hi = np.ones_like(target)
    up = target >= P(lo)
    hi[up] = 2.0
    lo[~up] = 0.5
    for _ in range(200):
        bad_hi = up & (P(hi) < target)
        bad_lo = ~up & (P(lo) > target)
        if not (bad_hi.any() or bad_lo.any()):
            break
        lo[bad_hi] = hi[bad_hi]
        hi[bad_hi] *= 2.0
        hi[bad_lo] = lo[bad_lo]
        lo[bad_lo] *= 0.5
    else:
        raise ValueError("could not bracket the stretch: is P(λ) monotone increasing and unbounded?")
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        below = P(mid) < target
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
        if np.all(hi - lo <= 4.0 * np.finfo(float).eps * hi):
            break
    return 0.5 * (lo + hi)


def _cumulative_simpson(f: np.ndarray, h: float) -> np.ndarray:
    """Cumulative integral ``∫_0^{X_i} f dX`` on a uniform grid, fourth-order accurate.

    Each interval ``[j, j+1]`` is integrated exactly for the quadratic through three neighbouring
    points: ``h/12 (5 f_j + 8 f_{j+1} − f_{j+2})`` for even ``j`` and
    ``h/12 (−f_{j−1} + 8 f_j + 5 f_{j+1})`` for odd ``j`` (and the last interval), so every pair
    of intervals adds up to composite Simpson ``h/3 (f_0 + 4 f_1 + f_2)``.
    """
    n = f.size
    out = np.zeros(n)
    if n < 3:
        if n == 2:
            out[1] = 0.5 * h * (f[0] + f[1])
        return out
    seg = np.empty(n - 1)
    j = np.arange(n - 1)
    fwd = (j % 2 == 0) & (j + 2 <= n - 1)
    jf = j[fwd]
    seg[fwd] = h / 12.0 * (5.0 * f[jf] + 8.0 * f[jf + 1] - f[jf + 2])
    jb = j[~fwd]
    seg[~fwd] = h / 12.0 * (-f[jb - 1] + 8.0 * f[jb] + 5.0 * f[jb + 1])
    out[1:] = np.cumsum(seg)
    return out


def hanging_bar_static(L: float, rho: float, g: float, stress_of_stretch, n: int = 2001) -> dict:
    """Static hanging bar for any 1D law ``P(λ)`` (monotone increasing, vectorised or scalar).

    The weight below ``X`` does not depend on the deformation, so ``P(λ(X)) = ρ g (L − X)``
    exactly (docs/verification.md §2); it is solved pointwise by bisection, and the deformed position
    ``x(X) = ∫_0^X λ dX'`` by fourth-order cumulative Simpson on ``n`` uniform points (the
    elongation integrates ``λ − 1`` to avoid cancellation; 2001 points give ~1e-13 relative
    error for smooth laws).

    Returns a dict with ``elongation`` (``x(L) − L``), ``top_stretch`` (``λ(0)``, at the
    support) and arrays ``X``, ``stretch``, ``x``.
    """
    n = max(int(n), 3)
    X = np.linspace(0.0, L, n)
    target = rho * g * (L - X)
    stretch = _solve_monotone(stress_of_stretch, target)
    disp = _cumulative_simpson(stretch - 1.0, L / (n - 1))
    return {
        "elongation": float(disp[-1]),
        "top_stretch": float(stretch[0]),
        "X": X,
        "stretch": stretch,
        "x": X + disp,
    }


def hanging_bar_static_displacement(X, L: float, rho: float, g: float, stress_of_stretch, n: int = 2001):
    """Exact static displacement ``u(X) = ∫_0^X (λ(X') − 1) dX'`` at arbitrary points ``X``.

    Same equilibrium as :func:`hanging_bar_static` (``P(λ) = ρ g (L − X')``), integrated by
    composite Simpson on ``n`` points of ``[0, X]`` for each requested ``X`` (no interpolation,
    so accurate to ~1e-13 relative for smooth laws). ``X`` is measured from the support.
    """
    X = np.asarray(X, dtype=float)
    n = max(int(n) | 1, 3)  # odd: the last point closes a Simpson pair
    s = np.linspace(0.0, 1.0, n)
    grid = X.reshape(-1, 1) * s  # (M, n)
    stretch = _solve_monotone(stress_of_stretch, (rho * g * (L - grid)).ravel()).reshape(grid.shape)
    w = np.ones(n)
    w[1:-1:2], w[2:-1:2] = 4.0, 2.0
    u = (stretch - 1.0) @ w * (X.reshape(-1) / (3.0 * (n - 1)))
    return u.reshape(X.shape)


def hanging_bar_dynamic_tip(t, L: float, rho: float, g: float, E: float):
    """Tip displacement (positive along gravity) of a bar with gravity switched on at ``t = 0``.

    Small-strain d'Alembert solution (docs/verification.md §2), with ``c = sqrt(E/ρ)``, ``T = 4L/c``
    and ``τ = t mod T`` folded to ``[0, T/2]`` (the motion is even and ``T``-periodic):
    ``u = g τ²/2`` for ``τ ≤ L/c``; ``u = g L²/c² − (g/2)(2L/c − τ)²`` for ``L/c ≤ τ ≤ 2L/c``.
    The peak ``g L²/c²`` at ``t = 2L/c`` is twice the static tip displacement ``g L²/(2c²)``.
    ``t`` may be a scalar or an array.
    """
    c = math.sqrt(E / rho)
    T = 4.0 * L / c
    tau = np.mod(np.asarray(t, dtype=float), T)
    tau = np.where(tau > 0.5 * T, T - tau, tau)
    t1 = L / c
    early = 0.5 * g * tau**2
    late = g * L**2 / c**2 - 0.5 * g * (2.0 * t1 - tau) ** 2
    return np.where(tau <= t1, early, late)


def hanging_bar_dynamic_series(X, t, L: float, rho: float, g: float, E: float, n_modes: int = 2000):
    """Mode series of the sudden-gravity hanging bar (positive along gravity).

    ``u(X,t) = (g/c²)(L X − X²/2) − Σ_n 2g/(c² L β_n³) sin(β_n X) cos(ω_n t)``
    (docs/verification.md §2); truncation error at the tip ~ ``g L²/c² / n_modes²``.
    """
    c = math.sqrt(E / rho)
    X = np.asarray(X, dtype=float)[..., None]
    t = np.asarray(t, dtype=float)[..., None]
    nn = np.arange(1, n_modes + 1)
    beta = (2 * nn - 1) * np.pi / (2.0 * L)
    omega = c * beta
    static = (g / c**2) * (L * X[..., 0] - 0.5 * X[..., 0] ** 2)
    series = np.sum(2.0 * g / (c**2 * L * beta**3) * np.sin(beta * X) * np.cos(omega * t), axis=-1)
    return static - series


# --------------------------------------------------------------------------------------------
# Axis-aligned manufactured solution
# --------------------------------------------------------------------------------------------
def manufactured_phases(dim: int) -> np.ndarray:
    """Phase of each axis: 0, 2π/3, 4π/3 (docs/verification.md §3)."""
    return 2.0 * np.pi * np.arange(dim) / 3.0


def manufactured_motion(X, t: float, A: float, c: float):
    """Exact displacement, velocity and (diagonal) deformation gradient of the axis-aligned
    manufactured solution (Wallstedt & Guilkey 2008; Kamojjala et al. 2015)::

        U_k = A sin(π X_k) sin(cπt + φ_k),   V_k = A cπ sin(π X_k) cos(cπt + φ_k),
        F_kk = 1 + Aπ cos(π X_k) sin(cπt + φ_k)

    ``X`` (N, d) reference positions. Returns ``(u, v, F_diag)``, each (N, d).
    """
    X = np.atleast_2d(np.asarray(X, dtype=float))
    ph = c * math.pi * t + manufactured_phases(X.shape[1])
    s = np.sin(math.pi * X)
    u = A * s * np.sin(ph)
    v = A * c * math.pi * s * np.cos(ph)
    Fd = 1.0 + A * math.pi * np.cos(math.pi * X) * np.sin(ph)
    return u, v, Fd


def manufactured_body_force(X, t: float, A: float, c: float, lam: float, mu: float, rho: float):
    """Body force (per unit mass) that makes :func:`manufactured_motion` solve the neo-Hookean
    momentum equation ``ρ0 ∂²U/∂t² = ∇·P + ρ0 b`` (docs/verification.md §3)::

        b_k = π² U_k [ μ/ρ0 − c² − (λ (ln J − 1) − μ) / (ρ0 F_kk²) ],   J = Π F_kk

    Derivation: with ``P_kk = μ(F_kk − 1/F_kk) + λ ln J / F_kk`` and ``∂ ln J/∂X_k = ∂_k F_kk / F_kk``,
    ``∂P_kk/∂X_k = ∂_k F_kk [μ(1 + F_kk⁻²) + λ(1 − ln J) F_kk⁻²]`` and ``∂_k F_kk = −π² U_k``.
    """
    u, _, Fd = manufactured_motion(X, t, A, c)
    lnJ = np.sum(np.log(Fd), axis=1, keepdims=True)
    return math.pi**2 * u * (mu / rho - c * c - (lam * (lnJ - 1.0) - mu) / (rho * Fd**2))
