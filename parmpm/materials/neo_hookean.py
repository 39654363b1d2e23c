"""Compressible neo-Hookean: ``σ = [μ(b − I) + λ ln J · I] / J``, ``b = F Fᵀ``, ``J = det F``.

The form most MPM codes use (e.g. Sadeghirad et al. 2011, Uintah's CompNeoHook); plane strain in
2D (``F_zz = 1``), uniaxial strain in 1D (``σ = [μ(λ² − 1) + λ_L ln λ]/λ``). Stored energy
``ψ = μ/2 (tr b − d) − μ ln J + λ/2 (ln J)²``. CFL speed in the current configuration:
``ρ0 c² = μ(b_max + 1) + λ max(1, 1 − ln J)`` (:mod:`parmpm.materials.laws` explains the bound).
Damage keeps the pressure term ``p_v = λ ln J / J`` in compression (:mod:`parmpm.materials.damage`).

Forms: :func:`neo_hookean_stress` on the leading d×d block of 3×3 arrays (the generic kernels)
and :func:`neo_hookean_2d` / :func:`neo_hookean_3d` on scalar entries (the specialised kernels,
which take ``ln J`` and ``1/J`` once and multiply where the generic form divides by ``J``).
"""
import math

from parmpm.core.jit import helper_kernel
from parmpm.materials.kinematics import det_d


@helper_kernel
def neo_hookean_stress(d, F, lam, mu, out):
    J = det_d(d, F)
    p = lam * math.log(J) if J > 0.0 else -math.inf
    for a in range(d):
        for b in range(d):
            bab = 0.0
            for k in range(d):
                bab += F[a, k] * F[b, k]
            if a == b:
                out[a, b] = (mu * (bab - 1.0) + p) / J
            else:
                out[a, b] = mu * bab / J


@helper_kernel
def neo_hookean_energy(d, F, lam, mu):
    """Stored energy per unit reference volume, whose Kirchhoff stress is ``J σ`` above (the
    out-of-plane stretch is 1 in 2D and 1D)."""
    J = det_d(d, F)
    if not J > 0.0:
        return math.inf
    trb = 0.0
    for a in range(d):
        for k in range(d):
            trb += F[a, k] * F[a, k]
    lnJ = math.log(J)
    return 0.5 * mu * (trb - d) - mu * lnJ + 0.5 * lam * lnJ * lnJ


@helper_kernel
def neo_hookean_rho_c2(lam, mu, bmax, lnJ):
    """``ρ0 c²`` of the CFL speed from the Gershgorin bound ``bmax`` of ``b`` and ``ln J``."""
    return mu * (bmax + 1.0) + lam * max(1.0, 1.0 - lnJ)


@helper_kernel
def neo_hookean_pressure(lam, J):
    """``p_v = λ ln J / J`` (−∞ for ``J ≤ 0``)."""
    if J > 0.0:
        return lam * math.log(J) / J
    return -math.inf


@helper_kernel
def _p_c2(lam, mu, inv_rho, J, bmax):
    """``λ ln J`` and the squared CFL speed ``c²`` (−∞ and ∞ for ``J ≤ 0``), ``ln J`` taken
    once."""
    if J > 0.0:
        lnJ = math.log(J)
        return lam * lnJ, neo_hookean_rho_c2(lam, mu, bmax, lnJ) * inv_rho
    return -math.inf, math.inf


@helper_kernel
def neo_hookean_2d(lam, mu, inv_rho, J, b00, b01, b11, bmax):
    """``(σ_xx, σ_xy, σ_yy, c², (p, J))`` from ``J`` and ``b``: the squared CFL speed, and the
    pressure term ``p_v = p / J`` as a pair (:func:`parmpm.materials.damage.pressure_term`)."""
    p, c2 = _p_c2(lam, mu, inv_rho, J, bmax)
    iJ = 1.0 / J
    return (mu * (b00 - 1.0) + p) * iJ, mu * b01 * iJ, (mu * (b11 - 1.0) + p) * iJ, c2, (p, J)


@helper_kernel
def neo_hookean_3d(lam, mu, inv_rho, J, b00, b01, b02, b11, b12, b22, bmax):
    """``(σ_xx, σ_xy, σ_xz, σ_yy, σ_yz, σ_zz, c², (p, J))`` from ``J`` and ``b`` (``c²`` and the
    pressure term as in :func:`neo_hookean_2d`)."""
    p, c2 = _p_c2(lam, mu, inv_rho, J, bmax)
    iJ = 1.0 / J
    return ((mu * (b00 - 1.0) + p) * iJ, mu * b01 * iJ, mu * b02 * iJ,
            (mu * (b11 - 1.0) + p) * iJ, mu * b12 * iJ, (mu * (b22 - 1.0) + p) * iJ, c2, (p, J))
