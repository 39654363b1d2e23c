"""The plastic pass: every plastic particle's stress, state and wave speed from its new ``F``,
after G2P's deformation update (which gives a plastic material zero stress and speed:
:data:`parmpm.materials.PLASTIC_MODELS`), and the sums the energy account and the snapshots read.

Each particle carries a state row (:mod:`.state`: the store's optional ``plastic`` field).
``C_p⁻¹`` needs only the current ``F`` (Simo 1992): the trial
elastic left Cauchy–Green tensor is ``b_e^tr = F C_p⁻¹ Fᵀ`` — the return maps' ``ΔF b_e ΔFᵀ``
with ``ΔF = F`` and ``b_e = C_p⁻¹`` — and after the return ``C_p⁻¹ = F⁻¹ b_e F⁻ᵀ``. So G2P's
fused ``F`` update stays as it is, and the pass reads nothing of the step before.

Plane strain and 1D embed ``F`` in 3×3 (``F_zz = 1``; 1D ``F_yy = F_zz = 1``): the out-of-plane
elastic and plastic stretches are the model's own. The Cauchy stress is ``τ / det F``; the wave
speed ``√(c0² max(1, λ_max(b_e)))``, ``c0² = (K + 4G/3)/ρ0``, the small-strain P-wave speed scaled
as linear elasticity scales its own (:mod:`parmpm.materials.laws`).
"""
import math

import numpy as np

from parmpm.core.jit import helper_kernel, kernel, loop_kernel
from parmpm.materials import DRUCKER_PRAGER, J2
from parmpm.materials.kinematics import det_d
from parmpm.materials.plasticity.drucker_prager import (ELASTIC, dp_dissipation, dp_equivalent,
                                                        dp_return)
from parmpm.materials.plasticity.j2 import be_energy, j2_return
from parmpm.materials.plasticity.closed_form_eigen import sym_eig3_closed
from parmpm.materials.plasticity.spectral import from_principal
from parmpm.materials.plasticity.state import STATE_EPSP, STATE_WORK, SYM
from parmpm.materials.plasticity.table import (PCOL_A, PCOL_B, PCOL_C, PCOL_C2, PCOL_COHESION,
                                               PCOL_ETA, PCOL_ETA_BAR, PCOL_G, PCOL_HARDENING,
                                               PCOL_K, PCOL_MODEL, PCOL_N, PCOL_PT, PCOL_RATE0,
                                               PCOL_XI)

@helper_kernel
def _embed(d, Fi, F3):
    """``F3`` (3, 3): ``Fi``'s leading d×d block, the identity elsewhere."""
    for a in range(3):
        for b in range(3):
            F3[a, b] = Fi[a, b] if a < d and b < d else (1.0 if a == b else 0.0)


@helper_kernel
def _det_inverse(F3, Finv):
    """``det F3``, its inverse written into ``Finv``."""
    a, b, c = F3[0, 0], F3[0, 1], F3[0, 2]
    e, f, g = F3[1, 0], F3[1, 1], F3[1, 2]
    h, k, m = F3[2, 0], F3[2, 1], F3[2, 2]
    c00, c01, c02 = f * m - g * k, c * k - b * m, b * g - c * f
    J = a * c00 + b * (g * h - e * m) + c * (e * k - f * h)
    iJ = 1.0 / J
    Finv[0, 0], Finv[0, 1], Finv[0, 2] = c00 * iJ, c01 * iJ, c02 * iJ
    Finv[1, 0], Finv[1, 1], Finv[1, 2] = (g * h - e * m) * iJ, (a * m - c * h) * iJ, (c * e - a * g) * iJ
    Finv[2, 0], Finv[2, 1], Finv[2, 2] = (e * k - f * h) * iJ, (b * h - a * k) * iJ, (a * f - b * e) * iJ
    return J


@helper_kernel
def _congruence(A, S, out, T):
    """``out = A S Aᵀ`` for a symmetric ``S`` (3, 3), through ``T = S Aᵀ`` (scratch): 45
    multiplications, not 108."""
    for k in range(3):
        for j in range(3):
            T[k, j] = S[k, 0] * A[j, 0] + S[k, 1] * A[j, 1] + S[k, 2] * A[j, 2]
    for i in range(3):
        for j in range(i, 3):
            x = A[i, 0] * T[0, j] + A[i, 1] * T[1, j] + A[i, 2] * T[2, j]
            out[i, j] = x
            out[j, i] = x


@helper_kernel
def _unpack(s, A):
    for q in range(6):
        r, c = SYM[q]
        A[r, c] = s[q]
        A[c, r] = s[q]


@helper_kernel
def plastic_update(d, Fi, s, prm, dt, sig, m3, v3):
    """Particle with deformation gradient ``Fi`` (d×d) and state row ``s``: the return map of
    its model, ``s`` updated in place, its Cauchy stress written into ``sig`` (leading d×d);
    returns its wave speed. Scratch ``m3`` (6, 3, 3), ``v3`` (4, 3).

    The steps of :func:`parmpm.materials.plasticity.j2.j2_update` (and ``dp_update``) with the
    trial tensor from ``C_p⁻¹``; a step without plastic flow leaves ``C_p⁻¹`` as it is (exactly:
    ``F⁻¹ b_e^tr F⁻ᵀ = C_p⁻¹``), so it skips the new ``b_e`` and the inverse of ``F``."""
    F3, Finv, C, tau, M, V = m3[0], m3[1], m3[2], m3[3], m3[4], m3[5]
    w, e, t = v3[0], v3[1], v3[2]
    _embed(d, Fi, F3)
    _unpack(s, C)
    _congruence(F3, C, M, tau)  # b_e^tr = F C_p⁻¹ Fᵀ (tau: scratch until the stress)
    sym_eig3_closed(M, w, V)
    bmax = w[2]  # ascending: λ_max(b_e^tr)
    for A in range(3):
        w[A] = 0.5 * math.log(w[A]) if w[A] > 0.0 else math.nan
    K, G = prm[PCOL_K], prm[PCOL_G]
    model = int(prm[PCOL_MODEL])
    if model == J2:
        for A in range(3):
            e[A] = w[A]
        dl, work = j2_return(e, K, G, int(prm[PCOL_HARDENING]), prm[PCOL_A], prm[PCOL_B],
                             prm[PCOL_N], prm[PCOL_C], prm[PCOL_RATE0], s[STATE_EPSP], dt, t)
        flowed = dl > 0.0
    elif model == DRUCKER_PRAGER:
        dg, dgt, region = dp_return(w, K, G, prm[PCOL_ETA], prm[PCOL_XI], prm[PCOL_ETA_BAR],
                                    prm[PCOL_COHESION], prm[PCOL_PT], e, t)
        work = dp_dissipation(w, e, t)
        dl = dp_equivalent(w, e)
        flowed = region != ELASTIC
    else:
        dl, work, flowed = math.nan, math.nan, True
        for A in range(3):
            e[A], t[A] = math.nan, math.nan
    from_principal(t, V, tau)
    if flowed:  # b_e = Σ exp(2 ε_A) n_A n_Aᵀ, C_p⁻¹ = F⁻¹ b_e F⁻ᵀ
        for A in range(3):
            w[A] = math.exp(2.0 * e[A])
        bmax = max(w[0], w[1], w[2])
        from_principal(w, V, C)
        J = _det_inverse(F3, Finv)
        _congruence(Finv, C, M, F3)  # F3 is not read again
        for q in range(6):
            r, c = SYM[q]
            s[q] = M[r, c]
        s[STATE_EPSP] += dl
        s[STATE_WORK] += work
    else:
        J = det_d(3, F3)
    iJ = 1.0 / J
    for a in range(d):
        for b in range(d):
            sig[a, b] = tau[a, b] * iJ
    if not J > 0.0:
        return math.inf
    return math.sqrt(prm[PCOL_C2] * max(1.0, bmax))


@kernel
def plastic_pass(d, F, mat, table, state, stress, v, dt):
    """:func:`plastic_update` of every plastic particle (rows in any order: each is its own);
    returns their largest ``c_p + |v_p|`` (0 with none, ``inf`` once one is NaN)."""
    return _plastic_loop(d, F, mat, table, state, stress, v, dt, np.empty((6, 3, 3)),
                         np.empty((4, 3)))


@loop_kernel
def _plastic_loop(d, F, mat, table, state, stress, v, dt, m3, v3):
    """:func:`plastic_pass`'s loop, reference counting off (:mod:`parmpm.core.jit`: the per-row
    views ``F[i]``, ``state[i]``, ``stress[i]`` cost no atomic pair each)."""
    vmax = 0.0
    for i in range(F.shape[0]):
        prm = table[mat[i]]
        if prm[PCOL_MODEL] == 0.0:
            continue
        c = plastic_update(d, F[i], state[i], prm, dt, stress[i], m3, v3)
        sp = 0.0
        for a in range(d):
            sp += v[i, a] * v[i, a]
        s = c + math.sqrt(sp)
        if not (s <= vmax):
            vmax = s if s == s else math.inf
    return vmax


@helper_kernel
def stored_plastic(d, Fi, s, prm, m3, v3):
    """Hencky energy per unit reference volume of the particle's ``b_e = F C_p⁻¹ Fᵀ``."""
    F3, C, be, V = m3[0], m3[1], m3[2], m3[5]
    _embed(d, Fi, F3)
    _unpack(s, C)
    for a in range(3):
        for b in range(3):
            x = 0.0
            for k in range(3):
                for m in range(3):
                    x += F3[a, k] * C[k, m] * F3[b, m]
            be[a, b] = x
    return be_energy(be, prm[PCOL_K], prm[PCOL_G], V, v3[0])


@kernel
def plastic_energy_sums(d, start, order, vol0, F, mat, table, state):
    """Per patch slot, over its particles ``order[start[p]:start[p + 1]]`` in that order: the
    plastic particles' (stored Hencky energy, plastic work done so far), ``V₀``-weighted."""
    out = np.zeros((start.size - 1, 2))
    _energy_loop(d, start, order, vol0, F, mat, table, state, out, np.empty((6, 3, 3)),
                 np.empty((4, 3)))
    return out


@loop_kernel
def _energy_loop(d, start, order, vol0, F, mat, table, state, out, m3, v3):
    for p in range(start.size - 1):
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):
            i = order[kk]
            prm = table[mat[i]]
            if prm[PCOL_MODEL] == 0.0:
                continue
            out[p, 0] += vol0[i] * stored_plastic(d, F[i], state[i], prm, m3, v3)
            out[p, 1] += vol0[i] * state[i, STATE_WORK]
