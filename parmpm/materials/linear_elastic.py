"""Small-strain isotropic linear elasticity: ``σ = λ tr(ε) I + 2μ ε``, ``ε = sym(F) − I``.

Total (not incremental) small strain, so the stress is a pure function of ``F``: no drift, and a
restart needs no extra state. Valid for small strains and rotations only (the vibrating bar).
In 2D this is plane strain, in 1D uniaxial strain (``σ = (λ+2μ) ε``). Stored energy
``ψ = λ/2 (tr ε)² + μ ε:ε``; CFL speed ``c² = c0² max(1, b_max)`` with ``c0² = (λ + 2μ)/ρ0``;
damage keeps ``p_v = λ tr ε`` in compression.

Forms: :func:`linear_elastic_stress` on the leading d×d block of 3×3 arrays (the generic
kernels), :func:`linear_elastic_2d` / :func:`linear_elastic_3d` on scalar entries.
"""
import math

from parmpm.core.jit import helper_kernel


@helper_kernel
def linear_elastic_stress(d, F, lam, mu, out):
    tr = 0.0
    for a in range(d):
        tr += F[a, a] - 1.0
    for a in range(d):
        for b in range(d):
            eps = 0.5 * (F[a, b] + F[b, a]) - (1.0 if a == b else 0.0)
            out[a, b] = 2.0 * mu * eps + (lam * tr if a == b else 0.0)


@helper_kernel
def linear_elastic_energy(d, F, lam, mu):
    tr = 0.0
    ee = 0.0
    for a in range(d):
        tr += F[a, a] - 1.0
        for b in range(d):
            eps = 0.5 * (F[a, b] + F[b, a]) - (1.0 if a == b else 0.0)
            ee += eps * eps
    return 0.5 * lam * tr * tr + mu * ee


@helper_kernel
def linear_elastic_speed2(c2, bmax):
    """Squared CFL speed from ``c0²`` and the Gershgorin bound ``bmax`` of ``b``."""
    return c2 * max(1.0, bmax)


@helper_kernel
def linear_elastic_speed(c2, bmax):
    """CFL speed from ``c0²`` and the Gershgorin bound ``bmax`` of ``b``."""
    return math.sqrt(linear_elastic_speed2(c2, bmax))


@helper_kernel
def linear_elastic_2d(lam, mu, c2, J, f00, f01, f10, f11, bmax):
    """``(σ_xx, σ_xy, σ_yy, c², (p_v, 1))``: the squared CFL speed, and the pressure term as a
    pair (:func:`parmpm.materials.damage.pressure_term`; ``x / 1`` is ``x``)."""
    e00, e11 = f00 - 1.0, f11 - 1.0
    e01 = 0.5 * (f01 + f10)
    tr = e00 + e11
    cc = linear_elastic_speed2(c2, bmax) if J > 0.0 else math.inf
    return (2.0 * mu * e00 + lam * tr, 2.0 * mu * e01, 2.0 * mu * e11 + lam * tr, cc,
            (lam * tr, 1.0))


@helper_kernel
def linear_elastic_3d(lam, mu, c2, J, f00, f01, f02, f10, f11, f12, f20, f21, f22, bmax):
    """``(σ_xx, σ_xy, σ_xz, σ_yy, σ_yz, σ_zz, c², (p_v, 1))`` (as :func:`linear_elastic_2d`)."""
    e00, e11, e22 = f00 - 1.0, f11 - 1.0, f22 - 1.0
    tr = e00 + e11 + e22
    cc = linear_elastic_speed2(c2, bmax) if J > 0.0 else math.inf
    m2 = 2.0 * mu
    return (m2 * e00 + lam * tr, m2 * (0.5 * (f01 + f10)), m2 * (0.5 * (f02 + f20)),
            m2 * e11 + lam * tr, m2 * (0.5 * (f12 + f21)), m2 * e22 + lam * tr, cc,
            (lam * tr, 1.0))
