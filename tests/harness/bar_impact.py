"""An independent model for the plastic runs' tests: a bar of finite-strain J2 (Hencky,
perfectly plastic) in uniaxial strain strikes a rigid wall. The exact solution is two shocks
from the wall — an elastic precursor to the yield stretch, then a plastic shock to rest — whose
states follow from the Lagrangian jump conditions ``ρ0 U² = ΔP/Δλ`` and ``|Δv| = U |Δλ|``
(nominal stress P, stretch λ, shock speed U): written here from the law's uniaxial-strain form,
not from the code under test. In uniaxial strain the nominal axial stress equals the Cauchy one
(the cross-section does not change), so ``-P`` behind the plastic shock is the wall's pressure.
"""
import math


def uniaxial_strain_impact(E: float, nu: float, rho: float, sy: float, v0: float):
    """``(P1, U1, λ1, P2, U2, λ2)``: the precursor's and the plastic shock's states (tension
    positive; ``P2`` is the stress at the wall) for impact speed ``v0`` > the precursor's."""
    K, G = E / (3 * (1 - 2 * nu)), E / (2 * (1 + nu))
    M = K + 4 * G / 3

    def elastic(lam):  # τ = M ln λ, P = τ/λ
        return M * math.log(lam) / lam

    def plastic(lam):  # yielded: τ11 − τ22 = −σ_y, mean stress K ln λ (plastic flow isochoric)
        return (K * math.log(lam) - 2 * sy / 3) / lam

    lam1 = math.exp(-sy / (2 * G))  # 2G |ln λ| = σ_y
    P1 = elastic(lam1)
    U1 = math.sqrt(P1 / (lam1 - 1) / rho)
    dv1 = U1 * (1 - lam1)
    if not dv1 < v0:
        raise ValueError(f"v0 = {v0} m/s does not yield (the precursor stops {dv1:.4g} m/s)")

    def speed(lam2):
        return math.sqrt((plastic(lam2) - P1) / (lam2 - lam1) / rho)

    lo, hi = 0.3, lam1 * (1 - 1e-15)
    for _ in range(200):  # dv1 + U2 (λ1 − λ2) = v0, increasing as λ2 falls
        mid = 0.5 * (lo + hi)
        if dv1 + speed(mid) * (lam1 - mid) > v0:
            lo = mid
        else:
            hi = mid
    lam2 = 0.5 * (lo + hi)
    return P1, U1, lam1, plastic(lam2), speed(lam2), lam2
