"""Compressible neo-Hookean: ``σ = [μ(b − I) + λ ln J · I] / J``, ``b = F Fᵀ``, ``J = det F``.

The form most MPM codes use (e.g. Sadeghirad et al. 2011, Uintah's CompNeoHook); plane strain in
2D (``F_zz = 1``), uniaxial strain in 1D (``σ = [μ(λ² − 1) + λ_L ln λ]/λ``).
"""
import math

from parmpm.jit import helper_kernel


@helper_kernel
def det_d(d, F):
    if d == 1:
        return F[0, 0]
    if d == 2:
        return F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    return (F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
            - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
            + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]))


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
    """Stored energy per unit reference volume, ``ψ = μ/2 (tr b − d) − μ ln J + λ/2 (ln J)²``,
    whose Kirchhoff stress is ``J σ`` above (the out-of-plane stretch is 1 in 2D and 1D)."""
    J = det_d(d, F)
    if not J > 0.0:
        return math.inf
    trb = 0.0
    for a in range(d):
        for k in range(d):
            trb += F[a, k] * F[a, k]
    lnJ = math.log(J)
    return 0.5 * mu * (trb - d) - mu * lnJ + 0.5 * lam * lnJ * lnJ
