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
                                                        dp_return, dp_return_invariants,
                                                        free_volume)
from parmpm.materials.plasticity.j2 import be_energy, j2_return, radial_return
from parmpm.materials.plasticity.closed_form_eigen import sym_eig3_closed
from parmpm.materials.plasticity.near_identity import (RHO_MAX, exp_near_zero,
                                                       log_near_identity)
from parmpm.materials.plasticity.spectral import from_principal
from parmpm.materials.plasticity.state import STATE_EPSP, STATE_WORK, SYM
from parmpm.materials.plasticity.table import (PCOL_A, PCOL_B, PCOL_C, PCOL_C2, PCOL_COHESION,
                                               PCOL_ETA, PCOL_ETA_BAR, PCOL_G, PCOL_HARDENING,
                                               PCOL_K, PCOL_MODEL, PCOL_N, PCOL_PT, PCOL_RATE0,
                                               PCOL_VOLUME_CORRECTION, PCOL_XI, PCOL_ETA_2,
                                               PCOL_I0, PCOL_GRAIN_SCALE)

#: rows per block of :func:`_plastic_loop` (its scratch: 7 × BLOCK doubles, in L1)
BLOCK = 64


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
def _record_return(F3, Finv, b, M, T, s, dl, work):
    """After a return: ``C_p⁻¹ = F⁻¹ b_e F⁻ᵀ`` (``b_e`` in ``b``) into the state row ``s``, with
    the step's ``Δε̄p`` and plastic work; returns ``det F``. Scratch ``Finv``, ``M``, ``T`` (``T``
    may be ``F3``: it is read only by the inverse, which comes first)."""
    J = _det_inverse(F3, Finv)
    _congruence(Finv, b, M, T)
    for q in range(6):
        r, c = SYM[q]
        s[q] = M[r, c]
    s[STATE_EPSP] += dl
    s[STATE_WORK] += work
    return J


@helper_kernel
def _wave_speed(prm, J, bmax):
    """``√(c0² max(1, λ_max(b_e)))`` (``bmax``: ``λ_max(b_e)`` or a bound above it); ``inf``
    once ``det F`` is not positive, which stops the step."""
    if not J > 0.0:
        return math.inf
    return math.sqrt(prm[PCOL_C2] * max(1.0, bmax))


@helper_kernel
def _inertial_scale(prm, dt):
    """μ(I)'s ``a = d √ρ_s / Δt`` (``I = a Δγ / √P``); 0 when it is off or the step is none."""
    if prm[PCOL_I0] > 0.0 and dt > 0.0:
        return prm[PCOL_GRAIN_SCALE] / dt
    return 0.0


@helper_kernel
def trial_be(d, Fi, s):
    """``b_e^tr − I = F C_p⁻¹ Fᵀ − I`` (``F`` embedded in 3×3) as six scalars, and the square of
    its Frobenius norm: the same products, in the same order, as :func:`_congruence`."""
    f00 = Fi[0, 0]
    f01 = f02 = f10 = f12 = f20 = f21 = 0.0
    f11 = f22 = 1.0
    if d > 1:
        f01, f10, f11 = Fi[0, 1], Fi[1, 0], Fi[1, 1]
    if d > 2:
        f02, f12, f20, f21, f22 = Fi[0, 2], Fi[1, 2], Fi[2, 0], Fi[2, 1], Fi[2, 2]
    c00, c11, c22, c01, c02, c12 = s[0], s[1], s[2], s[3], s[4], s[5]
    t00, t10, t20 = (c00 * f00 + c01 * f01 + c02 * f02, c01 * f00 + c11 * f01 + c12 * f02,
                     c02 * f00 + c12 * f01 + c22 * f02)  # T = C Fᵀ, column by column
    t01, t11, t21 = (c00 * f10 + c01 * f11 + c02 * f12, c01 * f10 + c11 * f11 + c12 * f12,
                     c02 * f10 + c12 * f11 + c22 * f12)
    t02, t12, t22 = (c00 * f20 + c01 * f21 + c02 * f22, c01 * f20 + c11 * f21 + c12 * f22,
                     c02 * f20 + c12 * f21 + c22 * f22)
    x00 = f00 * t00 + f01 * t10 + f02 * t20 - 1.0
    x11 = f10 * t01 + f11 * t11 + f12 * t21 - 1.0
    x22 = f20 * t02 + f21 * t12 + f22 * t22 - 1.0
    x01 = f00 * t01 + f01 * t11 + f02 * t21
    x02 = f00 * t02 + f01 * t12 + f02 * t22
    x12 = f10 * t02 + f11 * t12 + f12 * t22
    rho2 = x00 * x00 + x11 * x11 + x22 * x22 + 2.0 * (x01 * x01 + x02 * x02 + x12 * x12)
    return x00, x11, x22, x01, x02, x12, rho2


@helper_kernel
def near_identity_return(d, Fi, s, prm, dt, sig, m3, l00, l11, l22, l01, l02, l12):
    """:func:`plastic_update` of a particle whose ``b_e^tr`` is within :data:`RHO_MAX` of ``I``,
    given ``ln b_e^tr`` (six scalars, :func:`.near_identity.log_near_identity`). Both models'
    returns are isotropic: each leaves the trial log strain's deviator scaled and sets its mean
    stress, ``ε = scale dev ε* + p/(3K) I`` — J2's radial return (:func:`.j2.j2_return`,
    ``p = K ε_v``) and Drucker–Prager's (:func:`.drucker_prager.dp_return_invariants`) — so
    neither needs principal axes. Then, with ``e = |dev ε*|``:

    * the step's plastic strain ``Δε_p = (1 − scale) dev ε* + (ε_v − p/K)/3 I``: its
      equivalent ``√(2/3)(1 − scale) e`` and its work ``τ : Δε_p = p (ε_v − p/K)
      + 2G scale (1 − scale) e²`` (J2: ``(q* − 3GΔε̄p) Δε̄p``, the same number);
    * after a return, ``b_e = exp(2p/(3K)) exp(2 scale dev ε*)`` by
      :func:`.near_identity.exp_near_zero`, and ``C_p⁻¹ = F⁻¹ b_e F⁻ᵀ``;
    * the wave speed from ``λ_max(b_e) ≤ exp(2 (p/(3K) + √(2/3) scale e))`` (a traceless
      symmetric matrix's largest eigenvalue is at most ``√(2/3)`` of its norm), an upper
      bound, equal on uniaxial states.

    Drucker–Prager's volume correction returns from the trace ``ε_v + free``
    (:func:`.drucker_prager.free_volume`); ``Δε_p`` and its work keep the trial's own ``ε_v``."""
    ev = 0.5 * (l00 + l11 + l22)
    m = ev / 3.0
    e00, e11, e22 = 0.5 * l00 - m, 0.5 * l11 - m, 0.5 * l22 - m
    e01, e02, e12 = 0.5 * l01, 0.5 * l02, 0.5 * l12
    ee2 = e00 * e00 + e11 * e11 + e22 * e22 + 2.0 * (e01 * e01 + e02 * e02 + e12 * e12)
    ee = math.sqrt(ee2)
    K, G = prm[PCOL_K], prm[PCOL_G]
    dl = work = 0.0
    if int(prm[PCOL_MODEL]) == J2:  # q* = √(3/2) |dev τ*|
        flowed, dl, scale, work = radial_return(
            2.0 * G * math.sqrt(1.5) * ee, G, int(prm[PCOL_HARDENING]), prm[PCOL_A], prm[PCOL_B],
            prm[PCOL_N], prm[PCOL_C], prm[PCOL_RATE0], s[STATE_EPSP], dt)
        p = K * ev
    else:  # Drucker–Prager
        free = 0.0
        if prm[PCOL_VOLUME_CORRECTION] != 0.0:
            free = free_volume(math.log(det_d(d, Fi)), ev)
        p, scale, _, _, region = dp_return_invariants(
            ev + free, ee2, K, G, prm[PCOL_ETA], prm[PCOL_XI], prm[PCOL_ETA_BAR],
            prm[PCOL_COHESION], prm[PCOL_PT], prm[PCOL_ETA_2], prm[PCOL_I0],
            _inertial_scale(prm, dt))
        flowed = region != ELASTIC or free > 0.0
        if flowed:
            dl = math.sqrt(2.0 / 3.0) * (1.0 - scale) * ee
            work = p * (ev - p / K) + 2.0 * G * scale * (1.0 - scale) * ee2
    mp = p / (3.0 * K)  # the updated mean log strain
    if flowed:
        g = 2.0 * scale  # b_e = exp(2 mp) exp(2 scale dev ε*)
        x00, x11, x22, x01, x02, x12 = exp_near_zero(g * e00, g * e11, g * e22, g * e01,
                                                     g * e02, g * e12)
        v = math.exp(2.0 * mp)
        F3, Finv, C, T, M = m3[0], m3[1], m3[2], m3[3], m3[4]
        C[0, 0], C[1, 1], C[2, 2] = v * x00, v * x11, v * x22
        C[0, 1] = C[1, 0] = v * x01
        C[0, 2] = C[2, 0] = v * x02
        C[1, 2] = C[2, 1] = v * x12
        _embed(d, Fi, F3)
        J = _record_return(F3, Finv, C, M, T, s, dl, work)
    else:
        J = det_d(d, Fi)
    iJ = 1.0 / J
    pj, h = p * iJ, 2.0 * G * scale * iJ
    sig[0, 0] = pj + h * e00
    if d > 1:
        sig[1, 1] = pj + h * e11
        sig[0, 1] = sig[1, 0] = h * e01
    if d > 2:
        sig[2, 2] = pj + h * e22
        sig[0, 2] = sig[2, 0] = h * e02
        sig[1, 2] = sig[2, 1] = h * e12
    return _wave_speed(prm, J, math.exp(2.0 * (mp + math.sqrt(2.0 / 3.0) * scale * ee)))


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
        x, free = w, 0.0  # the trial the return sees; Δε_p = w − e all the same
        if prm[PCOL_VOLUME_CORRECTION] != 0.0:
            x, free = v3[3], free_volume(math.log(det_d(3, F3)), w[0] + w[1] + w[2])
            for A in range(3):
                x[A] = w[A] + free / 3.0
        dg, dgt, region = dp_return(x, K, G, prm[PCOL_ETA], prm[PCOL_XI], prm[PCOL_ETA_BAR],
                                    prm[PCOL_COHESION], prm[PCOL_PT], prm[PCOL_ETA_2],
                                    prm[PCOL_I0], _inertial_scale(prm, dt), e, t)
        work = dp_dissipation(w, e, t)
        dl = dp_equivalent(w, e)
        flowed = region != ELASTIC or free > 0.0
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
        J = _record_return(F3, Finv, C, M, F3, s, dl, work)  # F3: scratch once inverted
    else:
        J = det_d(3, F3)
    iJ = 1.0 / J
    for a in range(d):
        for b in range(d):
            sig[a, b] = tau[a, b] * iJ
    return _wave_speed(prm, J, bmax)


@kernel
def plastic_pass(d, F, mat, table, state, stress, v, dt):
    """:func:`plastic_update` of every plastic particle (rows in any order: each is its own);
    returns their largest ``c_p + |v_p|`` (0 with none, ``inf`` once one is NaN)."""
    return _plastic_loop(d, F, mat, table, state, stress, v, dt, np.empty((6, 3, 3)),
                         np.empty((4, 3)), np.empty((7, BLOCK)))


@loop_kernel
def _plastic_loop(d, F, mat, table, state, stress, v, dt, m3, v3, lg):
    """:func:`plastic_pass`'s loop, reference counting off (:mod:`parmpm.core.jit`: the per-row
    views ``F[i]``, ``state[i]``, ``stress[i]`` cost no atomic pair each), in blocks of
    :data:`BLOCK` rows: every row's ``b_e^tr − I`` and its logarithm first, into the columns of
    ``lg`` (7, BLOCK) — branch-free loops over rows, the logarithm's vectorised across them —
    then each plastic row's return: a row in the series' range finishes from its logarithm
    (:func:`near_identity_return`), any other plastic row takes :func:`plastic_update`. The
    logarithm of a row it does not serve (an elastic material, a strain past :data:`RHO_MAX`,
    NaN) is computed and not read."""
    vmax = 0.0
    n = F.shape[0]
    lim = RHO_MAX * RHO_MAX
    for start in range(0, n, BLOCK):
        rows = min(BLOCK, n - start)
        for k in range(rows):
            x = trial_be(d, F[start + k], state[start + k])
            for q in range(7):
                lg[q, k] = x[q]
        for k in range(rows):
            l00, l11, l22, l01, l02, l12 = log_near_identity(lg[0, k], lg[1, k], lg[2, k],
                                                             lg[3, k], lg[4, k], lg[5, k])
            lg[0, k], lg[1, k], lg[2, k], lg[3, k], lg[4, k], lg[5, k] = (l00, l11, l22, l01,
                                                                          l02, l12)
        for k in range(rows):
            i = start + k
            prm = table[mat[i]]
            if prm[PCOL_MODEL] == 0.0:
                continue
            if lg[6, k] <= lim and (prm[PCOL_MODEL] == J2 or prm[PCOL_MODEL] == DRUCKER_PRAGER):
                c = near_identity_return(d, F[i], state[i], prm, dt, stress[i], m3, lg[0, k],
                                         lg[1, k], lg[2, k], lg[3, k], lg[4, k], lg[5, k])
            else:
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
