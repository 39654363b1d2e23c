"""Plane-strain stress and wave speed of one particle, from the four entries of ``F`` and its
material's row of the parameter table.

The same models as :mod:`parmpm.materials` (neo-Hookean ``σ = [μ(b − I) + λ ln J I]/J``; small
strain ``σ = λ tr ε I + 2με``) and the same CFL speed as :func:`parmpm.materials.wave_speed`, with
``ln J`` and ``1/J`` computed once. Returns ``(σ_xx, σ_xy, σ_yy, c, p_v)``, ``p_v`` the law's
pressure term that damage keeps in compression (:func:`parmpm.materials.damage.pressure_term`).
"""
import math

from parmpm.jit import inline_kernel, kernel
from parmpm.materials import LINEAR_ELASTIC
from parmpm.materials.damage import COL_MODEL, damage_scalar, degrade_2d, max_stretch_2d


@inline_kernel
def stress_and_speed(params, row, f00, f01, f10, f11):
    J = f00 * f11 - f01 * f10
    b00 = f00 * f00 + f01 * f01
    b01 = f00 * f10 + f01 * f11
    b11 = f10 * f10 + f11 * f11
    bmax = max(abs(b00) + abs(b01), abs(b01) + abs(b11))
    lam, mu = params[row, 4], params[row, 5]
    if int(params[row, 0]) == LINEAR_ELASTIC:
        e00, e11 = f00 - 1.0, f11 - 1.0
        e01 = 0.5 * (f01 + f10)
        tr = e00 + e11
        c = math.sqrt(params[row, 6] * max(1.0, bmax)) if J > 0.0 else math.inf
        return 2.0 * mu * e00 + lam * tr, 2.0 * mu * e01, 2.0 * mu * e11 + lam * tr, c, lam * tr
    if J > 0.0:
        lnJ = math.log(J)
        p = lam * lnJ
        c = math.sqrt((mu * (bmax + 1.0) + lam * max(1.0, 1.0 - lnJ)) * params[row, 7])
    else:
        p = -math.inf
        c = math.inf
    iJ = 1.0 / J
    pv = p / J if J > 0.0 else -math.inf
    return (mu * (b00 - 1.0) + p) * iJ, mu * b01 * iJ, (mu * (b11 - 1.0) + p) * iJ, c, pv


@inline_kernel
def stress_damage_speed(params, row, damage, i, f00, f01, f10, f11):
    """:func:`stress_and_speed`, with particle ``i``'s damage updated from ``F`` and its stress
    degraded (:mod:`parmpm.materials.damage`) when its material has a damage model; without
    one ``damage`` is not touched (so undamaged runs are bit for bit those without the model)."""
    s00, s01, s11, c, pv = stress_and_speed(params, row, f00, f01, f10, f11)
    if params[row, COL_MODEL] != 0.0:
        D = damage_scalar(params, row, damage[i], max_stretch_2d(f00, f01, f10, f11))
        damage[i] = D
        s00, s01, s11 = degrade_2d(D, pv, s00, s01, s11)
    return s00, s01, s11, c


@inline_kernel
def update_F_stress(vmax, i, l00, l01, l10, l11, f00, f01, f10, f11, v, F, stress, mat, params,
                    damage):
    """The end of a G2P deformation update of particle ``i``: ``F ← (I + ΔtL) F`` (``l = ΔtL``,
    ``f = F``), its damage and (degraded) stress, and the running largest ``c_p + |v_p|``
    (``inf`` once one is NaN)."""
    n00 = f00 + (l00 * f00 + l01 * f10)
    n01 = f01 + (l00 * f01 + l01 * f11)
    n10 = f10 + (l10 * f00 + l11 * f10)
    n11 = f11 + (l10 * f01 + l11 * f11)
    F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1] = n00, n01, n10, n11
    s00, s01, s11, c = stress_damage_speed(params, mat[i], damage, i, n00, n01, n10, n11)
    stress[i, 0, 0], stress[i, 0, 1], stress[i, 1, 0], stress[i, 1, 1] = s00, s01, s01, s11
    s = c + math.sqrt(v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1])
    if not (s <= vmax):
        return s if s == s else math.inf
    return vmax


@kernel
def stress_pass(F, mat, params, stress):
    """The stress update of every particle on its own (what G2P does after ``F``): for
    ``parmpm bench``'s "stress" line, which G2P's fused loop cannot time separately."""
    vmax = 0.0
    for i in range(F.shape[0]):
        s00, s01, s11, c, _ = stress_and_speed(params, mat[i], F[i, 0, 0], F[i, 0, 1], F[i, 1, 0],
                                            F[i, 1, 1])
        stress[i, 0, 0], stress[i, 0, 1], stress[i, 1, 0], stress[i, 1, 1] = s00, s01, s01, s11
        vmax = max(vmax, c)
    return vmax
