"""Finite-strain von Mises (J2) plasticity with isotropic hardening: the return map in principal
axes of the trial elastic left Cauchy–Green tensor (Simo 1992; de Souza Neto, Perić & Owen
2008, ch. 14).

Per step, with ``ΔF = F_{n+1} F_n⁻¹`` and the plastic flow frozen, ``b_e^tr = ΔF b_e,n ΔFᵀ``; its
principal log strains ``ε_A^tr = ½ ln λ_A`` give the trial Kirchhoff stresses (Hencky,
:mod:`.hencky`), and the exponential backward-Euler integration of the flow rule
``−½ L_v b_e = ε̄̇p N b_e``, ``N = ∂q/∂τ = (3/2) s/q``, becomes the small-strain radial return on
those log strains, in the same principal axes (isotropy makes ``τ`` and ``b_e`` coaxial):

    q^tr − 3G Δε̄p = σ_y(ε̄p,n + Δε̄p, Δε̄p/Δt),   ε_A = ε_A^tr − Δε̄p (3/2) s_A^tr / q^tr.

``Δε̄p`` is closed-form for linear hardening and found by Newton's method, safeguarded by
bisection on ``[0, q^tr/3G]``, otherwise. The step's plastic work ``τ_{n+1} : Δε^p = q_{n+1} Δε̄p``
(= ``σ_y Δε̄p``) is returned for the energy ledger. docs/concepts/plasticity.md derives it.

Everything works on 3×3 arrays in every dimension (plane strain: ``ΔF_zz = 1`` and ``b_e``
block-diagonal; 1D: diagonal) and allocates nothing: the caller hands in scratch arrays.
"""
import math

from parmpm.core.jit import helper_kernel
from parmpm.materials.plasticity.hardening import LINEAR, yield_stress
from parmpm.materials.plasticity.hencky import hencky_energy, kirchhoff_principal
from parmpm.materials.plasticity.spectral import from_principal, sym_eig3, trial_log_strains

#: Newton iterations at most (a bisection step is taken whenever Newton leaves the bracket)
MAX_ITER = 100
#: relative residual of the consistency condition, ``|r| ≤ RTOL q^tr``
RTOL = 1.0e-13


@helper_kernel
def plastic_increment(code, a, b, n, c, rate0, G, q_tr, epsp, dt):
    """``Δε̄p`` solving ``q^tr − 3G Δε̄p − σ_y(ε̄p + Δε̄p, Δε̄p/Δt) = 0`` for a trial state
    outside the yield surface (``dt ≤ 0``: rate 0)."""
    if code == LINEAR:
        return (q_tr - a - b * epsp) / (3.0 * G + b)
    lo, hi = 0.0, q_tr / (3.0 * G)  # r(0) > 0, r(hi) = −σ_y ≤ 0
    x = 0.0
    for _ in range(MAX_ITER):
        rate = x / dt if dt > 0.0 else 0.0
        sy, h, hr = yield_stress(code, a, b, n, c, rate0, epsp + x, rate)
        r = q_tr - 3.0 * G * x - sy
        if abs(r) <= RTOL * q_tr:
            return x
        if r > 0.0:
            lo = x
        else:
            hi = x
        slope = 3.0 * G + h + (hr / dt if dt > 0.0 else 0.0)
        x = x + r / slope
        if not (lo < x < hi):
            x = 0.5 * (lo + hi)
        if hi - lo <= 1.0e-16 * hi:
            return x
    return x


@helper_kernel
def radial_return(q_tr, G, code, a, b, n, c, rate0, epsp, dt):
    """J2's return on the trial equivalent stress ``q_tr`` alone (isotropy: it scales the trial
    deviator and leaves the mean stress): ``(flowed, Δε̄p, shrink, work)``, the plastic strain
    increment, the factor the trial deviator is scaled by and the step's plastic work
    ``q_{n+1} Δε̄p`` per unit reference volume; ``(False, 0, 1, 0)`` inside the yield surface and
    for a NaN trial state (which stays NaN in the stresses that use it)."""
    sy, _, _ = yield_stress(code, a, b, n, c, rate0, epsp, 0.0)
    if not q_tr > sy:
        return False, 0.0, 1.0, 0.0
    dl = plastic_increment(code, a, b, n, c, rate0, G, q_tr, epsp, dt)
    return True, dl, 1.0 - 3.0 * G * dl / q_tr, (q_tr - 3.0 * G * dl) * dl


@helper_kernel
def j2_return(eps, K, G, code, a, b, n, c, rate0, epsp, dt, tau):
    """Radial return in principal space, in place: ``eps`` (3,) the trial principal log strains
    on entry, the updated elastic ones on exit; ``tau`` (3,) the principal Kirchhoff stresses.
    Returns ``(Δε̄p, q_{n+1} Δε̄p)``: the plastic strain increment and the step's plastic work
    per unit reference volume."""
    kirchhoff_principal(eps, K, G, tau)
    p = (tau[0] + tau[1] + tau[2]) / 3.0
    ss = 0.0
    for A in range(3):
        ss += (tau[A] - p) * (tau[A] - p)
    q_tr = math.sqrt(1.5 * ss)
    flowed, dl, shrink, work = radial_return(q_tr, G, code, a, b, n, c, rate0, epsp, dt)
    if not flowed:
        return 0.0, 0.0
    for A in range(3):
        s_tr = tau[A] - p
        eps[A] -= 1.5 * dl * s_tr / q_tr
        tau[A] = p + shrink * s_tr
    return dl, work


@helper_kernel
def j2_update(dF, be, epsp, K, G, code, a, b, n, c, rate0, dt, tau, M, V, w, t):
    """One particle's step: ``b_e`` (3, 3) updated in place by the increment ``dF`` (3, 3),
    Kirchhoff stress ``tau`` (3, 3) written (Cauchy is ``tau / det F`` of the total ``F``).
    Scratch: ``M``, ``V`` (3, 3), ``w``, ``t`` (3,). Hardening ``code`` and constants
    ``(a, b, n, c, rate0)`` as in :mod:`.hardening`; ``dt`` the step (Johnson–Cook's rate
    ``Δε̄p/dt``). Returns ``(ε̄p_{n+1}, plastic work of the step per unit reference volume)``."""
    trial_log_strains(dF, be, M, V, w)  # b_e^tr = ΔF b_e ΔFᵀ: axes, ½ ln λ
    dl, work = j2_return(w, K, G, code, a, b, n, c, rate0, epsp, dt, t)
    from_principal(t, V, tau)
    for A in range(3):
        w[A] = math.exp(2.0 * w[A])
    from_principal(w, V, be)
    return epsp + dl, work


@helper_kernel
def be_energy(be, K, G, V, w):
    """Stored Hencky energy per unit reference volume of an elastic left Cauchy–Green tensor
    ``be`` (3, 3); scratch ``V`` (3, 3), ``w`` (3,)."""
    sym_eig3(be, w, V)
    for A in range(3):
        w[A] = 0.5 * math.log(w[A]) if w[A] > 0.0 else math.nan
    return hencky_energy(w, K, G)
