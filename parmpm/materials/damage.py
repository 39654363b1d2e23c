"""Scalar damage driven by the largest principal stretch, degrading the stress in tension.

A material with a ``[materials.NAME.damage]`` table carries a damage ``D ∈ [0, 1]`` per particle
(``Particles.damage``), updated after every deformation update from the largest principal
stretch ``λ = √(max eig b)``, ``b = F Fᵀ`` (in 1D ``|F|``), with onset ``λ0`` and fracture
stretch ``λf``:

* linear softening:       ``g(λ) = (λ − λ0)/(λf − λ0)``, clipped to [0, 1] (``D = 1`` at ``λf``);
* exponential softening:  ``g(λ) = 1 − exp(−(λ − λ0)/(λf − λ0))`` for ``λ > λ0`` (``D → 1``;
  ``λf − λ0`` is the stretch scale over which ``1 − D`` falls by ``e``);

and ``D ← max(D, g(λ))``: damage never heals. The stress is then

    σ = (1 − D) σ_e + D · min(p_v, 0) · I,

with ``p_v`` the pressure term of the elastic law, a function of the volume change alone:
``λ_L ln J / J`` (neo-Hookean), ``λ_L tr ε`` (linear elastic). A damaged particle loses its
strength in shear and in tension but keeps resisting compression of its volume, so a fully
damaged particle (``D = 1``) carries ``p_v I`` while ``J < 1`` and nothing while ``J ≥ 1``.
Why ``p_v`` and not the mean stress ``tr σ_e / d``: a strongly sheared particle can have a
tensile mean stress while it loses volume (the ``μ(b − I)/J`` term); with the mean stress as the
switch nothing stops such a broken particle from collapsing to ``J → 0`` (seen in the tension
bar with ``freeze = "never"``: non-finite stress after failure). With ``D = 0`` nothing is
touched, so undamaged runs are bit for bit those of the same material without the table. The CFL
wave speed stays the undamaged one (conservative).

Parameter-table columns (:data:`parmpm.materials.PARAM`): ``damage`` (the softening code,
:data:`parmpm.materials.SOFTENING`; 0 none), ``damage_onset`` (λ0), ``damage_fracture`` (λf), ``damage_freeze`` (the ``D`` at
which a CPDI domain stops following the material's stretch; see :mod:`parmpm.shapes`).
"""
import math

from parmpm.core.jit import helper_kernel
from parmpm.materials.kinematics import left_cauchy_green_2d, left_cauchy_green_3d
from parmpm.materials import (COL_DAMAGE, COL_FRACTURE, COL_ONSET, EXPONENTIAL, LINEAR, NO_DAMAGE,
                              SOFTENING)


@helper_kernel
def softening(code, onset, fracture, lam):
    """``g(λ)`` of the module docstring (0 below the onset)."""
    if not lam > onset:  # NaN stretch: no damage from it (the CFL check stops such a run)
        return 0.0
    x = (lam - onset) / (fracture - onset)
    if code == LINEAR:
        return min(1.0, x)
    return 1.0 - math.exp(-x)


@helper_kernel
def largest_eigenvalue_sym3(a00, a01, a02, a11, a12, a22):
    """Largest eigenvalue of a symmetric 3×3 matrix (closed form, trigonometric; exact for
    repeated eigenvalues)."""
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    q = (a00 + a11 + a22) / 3.0
    if p1 == 0.0:
        return max(a00, a11, a22)
    p2 = (a00 - q) ** 2 + (a11 - q) ** 2 + (a22 - q) ** 2 + 2.0 * p1
    p = math.sqrt(p2 / 6.0)
    b00, b11, b22 = (a00 - q) / p, (a11 - q) / p, (a22 - q) / p
    b01, b02, b12 = a01 / p, a02 / p, a12 / p
    r = 0.5 * (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02)
               + b02 * (b01 * b12 - b11 * b02))
    r = min(1.0, max(-1.0, r))
    return q + 2.0 * p * math.cos(math.acos(r) / 3.0)


@helper_kernel
def max_stretch_2d(f00, f01, f10, f11):
    """Largest principal stretch ``√(max eig F Fᵀ)`` in 2D."""
    b00, b01, b11 = left_cauchy_green_2d(f00, f01, f10, f11)
    h = 0.5 * (b00 - b11)
    return math.sqrt(0.5 * (b00 + b11) + math.sqrt(h * h + b01 * b01))


@helper_kernel
def max_stretch_3d(f00, f01, f02, f10, f11, f12, f20, f21, f22):
    """Largest principal stretch ``√(max eig F Fᵀ)`` in 3D."""
    b00, b01, b02, b11, b12, b22 = left_cauchy_green_3d(f00, f01, f02, f10, f11, f12, f20, f21, f22)
    return math.sqrt(largest_eigenvalue_sym3(b00, b01, b02, b11, b12, b22))


@helper_kernel
def max_stretch(d, F):
    """Largest principal stretch of the leading d×d block of ``F``."""
    if d == 1:
        return abs(F[0, 0])
    if d == 2:
        return max_stretch_2d(F[0, 0], F[0, 1], F[1, 0], F[1, 1])
    return max_stretch_3d(F[0, 0], F[0, 1], F[0, 2], F[1, 0], F[1, 1], F[1, 2],
                          F[2, 0], F[2, 1], F[2, 2])


@helper_kernel
def damage_update(d, prm, F, D):
    """``max(D, g(λ(F)))`` for a material row ``prm``; ``D`` itself without a damage model."""
    code = int(prm[COL_DAMAGE])
    if code == NO_DAMAGE:
        return D
    return max(D, softening(code, prm[COL_ONSET], prm[COL_FRACTURE], max_stretch(d, F)))


@helper_kernel
def degrade(d, D, pv, out):
    """The damaged stress in place (leading d×d of ``out``), ``pv`` the law's pressure term;
    nothing at ``D = 0``."""
    if not D > 0.0:
        return
    keep = 1.0 - D
    for a in range(d):
        for b in range(d):
            out[a, b] *= keep
    if pv < 0.0:  # volumetric compression: resisted whatever the damage
        for a in range(d):
            out[a, a] += D * pv


@helper_kernel
def pressure_term(pt):
    """The law's pressure term ``p_v`` from the pair ``pt = (p_n, p_d)`` a scalar law returns:
    ``p_n / p_d`` (``−∞`` unless ``p_d > 0``). Divided only where a damaged particle needs it:
    the division the laws made for every particle was not free even where nothing read it."""
    pn, pd = pt
    return pn / pd if pd > 0.0 else -math.inf


@helper_kernel
def degrade_2d(D, pt, s00, s01, s11):
    """:func:`degrade` in 2D on the three stress components (returned); ``pt``: the law's
    pressure term as a pair (:func:`pressure_term`)."""
    if not D > 0.0:
        return s00, s01, s11
    pv = pressure_term(pt)
    keep = 1.0 - D
    s00, s01, s11 = keep * s00, keep * s01, keep * s11
    if pv < 0.0:
        s00 += D * pv
        s11 += D * pv
    return s00, s01, s11


@helper_kernel
def degrade_3d(D, pt, s00, s01, s02, s11, s12, s22):
    """:func:`degrade` in 3D on the six stress components (returned); ``pt`` as in
    :func:`degrade_2d`."""
    if not D > 0.0:
        return s00, s01, s02, s11, s12, s22
    pv = pressure_term(pt)
    k = 1.0 - D
    s00, s01, s02, s11, s12, s22 = k * s00, k * s01, k * s02, k * s11, k * s12, k * s22
    if pv < 0.0:
        s00 += D * pv
        s11 += D * pv
        s22 += D * pv
    return s00, s01, s02, s11, s12, s22


@helper_kernel
def damage_scalar(params, row, D, lam):
    """``max(D, g(λ))`` for material ``row`` of the parameter table (the specialised kernels,
    which compute ``λ`` from the entries of ``F``); ``D`` without a damage model."""
    code = int(params[row, COL_DAMAGE])
    if code == NO_DAMAGE:
        return D
    return max(D, softening(code, params[row, COL_ONSET], params[row, COL_FRACTURE], lam))


__all__ = ["NO_DAMAGE", "LINEAR", "EXPONENTIAL", "SOFTENING", "damage_update", "damage_scalar",
           "degrade", "degrade_2d", "degrade_3d", "max_stretch", "pressure_term", "softening"]
