"""Hencky elasticity in principal axes: the isotropic law that turns the return maps of the
infinitesimal theory into finite-strain ones (Simo 1992). With ``ε_A`` the principal logarithmic
elastic strains, ``ψ = ½ K (Σ ε_A)² + G Σ (ε_A − ε_v/3)²`` and the principal Kirchhoff stresses
``τ_A = ∂ψ/∂ε_A = K ε_v + 2G (ε_A − ε_v/3)``, ``ε_v = Σ ε_A`` (= ln J_e).
"""
from parmpm.core.jit import helper_kernel


@helper_kernel
def kirchhoff_principal(eps, K, G, tau):
    """Principal Kirchhoff stresses ``tau`` (3,) of principal log strains ``eps`` (3,)."""
    ev = eps[0] + eps[1] + eps[2]
    for a in range(3):
        tau[a] = K * ev + 2.0 * G * (eps[a] - ev / 3.0)


@helper_kernel
def hencky_energy(eps, K, G):
    """Stored energy per unit reference volume of principal log strains ``eps`` (3,)."""
    ev = eps[0] + eps[1] + eps[2]
    dev = 0.0
    for a in range(3):
        e = eps[a] - ev / 3.0
        dev += e * e
    return 0.5 * K * ev * ev + G * dev
