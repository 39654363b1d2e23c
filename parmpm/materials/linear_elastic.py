"""Small-strain isotropic linear elasticity: ``σ = λ tr(ε) I + 2μ ε``, ``ε = sym(F) − I``.

Total (not incremental) small strain, so the stress is a pure function of ``F``: no drift, and a
restart needs no extra state. Valid for small strains and rotations only (the vibrating bar).
In 2D this is plane strain, in 1D uniaxial strain (``σ = (λ+2μ) ε``).
"""
from parmpm.jit import helper_kernel


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
    """Stored energy per unit volume, ``ψ = λ/2 (tr ε)² + μ ε:ε``."""
    tr = 0.0
    ee = 0.0
    for a in range(d):
        tr += F[a, a] - 1.0
        for b in range(d):
            eps = 0.5 * (F[a, b] + F[b, a]) - (1.0 if a == b else 0.0)
            ee += eps * eps
    return 0.5 * lam * tr * tr + mu * ee
