"""3D stress and wave speed of one particle, from the nine entries of ``F`` and its material's row
of the parameter table.

The same models as :mod:`parmpm.materials` — neo-Hookean ``σ = [μ(b − I) + λ ln J I]/J`` with
``b = F Fᵀ``, ``J = det F``; small strain ``σ = λ tr ε I + 2με`` with ``ε = sym(F) − I`` — and the
same CFL speed as :func:`parmpm.materials.wave_speed`:
``c² = [μ(b_max + 1) + λ max(1, 1 − ln J)]/ρ0`` (neo-Hookean) or ``c0² max(1, b_max)`` (linear),
``b_max = max_a Σ_b |b_ab|`` (Gershgorin), ``c = ∞`` when ``J ≤ 0``. ``ln J`` and ``1/J`` are computed
once and ``1/ρ0`` is read from the table (``params[row, 7]``). Returns
``(σ_xx, σ_xy, σ_xz, σ_yy, σ_yz, σ_zz, c, p_v)``, ``p_v`` the law's pressure term that damage
keeps in compression (:func:`parmpm.materials.damage.pressure_term`). :func:`update_F_stress` is
the end of every G2P deformation update: ``F ← (I + Δt L) F``, then the stress.
"""
import math

from parmpm.jit import inline_kernel, kernel
from parmpm.materials import LINEAR_ELASTIC
from parmpm.materials.damage import COL_MODEL, damage_scalar, degrade_3d, max_stretch_3d


@inline_kernel
def stress_and_speed(params, row, f00, f01, f02, f10, f11, f12, f20, f21, f22):
    J = (f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20)
         + f02 * (f10 * f21 - f11 * f20))
    b00 = f00 * f00 + f01 * f01 + f02 * f02
    b01 = f00 * f10 + f01 * f11 + f02 * f12
    b02 = f00 * f20 + f01 * f21 + f02 * f22
    b11 = f10 * f10 + f11 * f11 + f12 * f12
    b12 = f10 * f20 + f11 * f21 + f12 * f22
    b22 = f20 * f20 + f21 * f21 + f22 * f22
    a01, a02, a12 = abs(b01), abs(b02), abs(b12)
    bmax = max(abs(b00) + a01 + a02, a01 + abs(b11) + a12, a02 + a12 + abs(b22))
    lam, mu = params[row, 4], params[row, 5]
    if int(params[row, 0]) == LINEAR_ELASTIC:
        e00, e11, e22 = f00 - 1.0, f11 - 1.0, f22 - 1.0
        tr = e00 + e11 + e22
        c = math.sqrt(params[row, 6] * max(1.0, bmax)) if J > 0.0 else math.inf
        m2 = 2.0 * mu
        return (m2 * e00 + lam * tr, m2 * (0.5 * (f01 + f10)), m2 * (0.5 * (f02 + f20)),
                m2 * e11 + lam * tr, m2 * (0.5 * (f12 + f21)), m2 * e22 + lam * tr, c, lam * tr)
    if J > 0.0:
        lnJ = math.log(J)
        p = lam * lnJ
        c = math.sqrt((mu * (bmax + 1.0) + lam * max(1.0, 1.0 - lnJ)) * params[row, 7])
    else:
        p = -math.inf
        c = math.inf
    iJ = 1.0 / J
    pv = p / J if J > 0.0 else -math.inf
    return ((mu * (b00 - 1.0) + p) * iJ, mu * b01 * iJ, mu * b02 * iJ,
            (mu * (b11 - 1.0) + p) * iJ, mu * b12 * iJ, (mu * (b22 - 1.0) + p) * iJ, c, pv)


@inline_kernel
def store_stress(stress, i, s00, s01, s02, s11, s12, s22):
    """Write the symmetric stress ``σ`` of particle ``i``."""
    stress[i, 0, 0], stress[i, 0, 1], stress[i, 0, 2] = s00, s01, s02
    stress[i, 1, 0], stress[i, 1, 1], stress[i, 1, 2] = s01, s11, s12
    stress[i, 2, 0], stress[i, 2, 1], stress[i, 2, 2] = s02, s12, s22


@inline_kernel
def update_F_stress(vmax, i, l00, l01, l02, l10, l11, l12, l20, l21, l22,
                    f00, f01, f02, f10, f11, f12, f20, f21, f22, v, F, stress, mat, params,
                    damage):
    """The end of a G2P deformation update of particle ``i``: ``F ← (I + ΔtL) F`` (``l = ΔtL``,
    ``f = F``), its damage and (degraded) stress (:mod:`parmpm.materials.damage`), and the
    running largest ``c_p + |v_p|`` (``inf`` once one is NaN)."""
    n00 = f00 + (l00 * f00 + l01 * f10 + l02 * f20)
    n01 = f01 + (l00 * f01 + l01 * f11 + l02 * f21)
    n02 = f02 + (l00 * f02 + l01 * f12 + l02 * f22)
    n10 = f10 + (l10 * f00 + l11 * f10 + l12 * f20)
    n11 = f11 + (l10 * f01 + l11 * f11 + l12 * f21)
    n12 = f12 + (l10 * f02 + l11 * f12 + l12 * f22)
    n20 = f20 + (l20 * f00 + l21 * f10 + l22 * f20)
    n21 = f21 + (l20 * f01 + l21 * f11 + l22 * f21)
    n22 = f22 + (l20 * f02 + l21 * f12 + l22 * f22)
    F[i, 0, 0], F[i, 0, 1], F[i, 0, 2] = n00, n01, n02
    F[i, 1, 0], F[i, 1, 1], F[i, 1, 2] = n10, n11, n12
    F[i, 2, 0], F[i, 2, 1], F[i, 2, 2] = n20, n21, n22
    s00, s01, s02, s11, s12, s22, c, pv = stress_and_speed(params, mat[i], n00, n01, n02, n10,
                                                           n11, n12, n20, n21, n22)
    row = mat[i]
    if params[row, COL_MODEL] != 0.0:  # damage: touch nothing else without a model
        D = damage_scalar(params, row, damage[i],
                          max_stretch_3d(n00, n01, n02, n10, n11, n12, n20, n21, n22))
        damage[i] = D
        s00, s01, s02, s11, s12, s22 = degrade_3d(D, pv, s00, s01, s02, s11, s12, s22)
    store_stress(stress, i, s00, s01, s02, s11, s12, s22)
    s = c + math.sqrt(v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1] + v[i, 2] * v[i, 2])
    if not (s <= vmax):
        return s if s == s else math.inf
    return vmax


@kernel
def stress_pass(F, mat, params, stress):
    """The stress update of every particle on its own (what G2P does after ``F``): for
    ``parmpm bench``'s "stress" line, which G2P's fused loop cannot time separately."""
    vmax = 0.0
    for i in range(F.shape[0]):
        s00, s01, s02, s11, s12, s22, c, _ = stress_and_speed(
            params, mat[i], F[i, 0, 0], F[i, 0, 1], F[i, 0, 2], F[i, 1, 0], F[i, 1, 1],
            F[i, 1, 2], F[i, 2, 0], F[i, 2, 1], F[i, 2, 2])
        store_stress(stress, i, s00, s01, s02, s11, s12, s22)
        vmax = max(vmax, c)
    return vmax
