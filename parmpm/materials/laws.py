"""The one switch over the registered elastic laws, in each form a kernel calls.

* :func:`cauchy_stress`, :func:`stored_energy`, :func:`wave_speed`: one particle, leading d×d
  block of 3×3 arrays (the generic kernels, the energy watch, the manufactured forcing);
* :func:`stress_speed_2d`, :func:`stress_speed_3d`: scalar entries of ``F`` (the specialised
  kernels), returning the stress components, the squared CFL speed ``c²`` (its square root is
  taken only where it can change the step's largest speed: :mod:`parmpm.transfer.running_speed`)
  and the law's pressure term ``p_v``.

CFL speed in the current configuration: a stretched body carries waves faster across a fixed
grid. In 1D neo-Hookean the spatial speed is ``c² = λ² ∂P/∂λ / ρ0 = [μ(λ² + 1) + λ_L(1 − ln λ)]/ρ0``,
which at large stretch far exceeds the reference ``(λ_L + 2μ)/ρ0``; we use
``[μ(b_max + 1) + λ_L·max(1, 1 − ln J)]/ρ0`` with ``b_max`` the Gershgorin bound of the largest
eigenvalue of ``b = F Fᵀ`` (exact in 1D, the P-wave speed at ``F = I``); linear elasticity scales
``c0²`` by ``max(1, b_max)``. ``c = ∞`` when ``J ≤ 0``.

Every registered law (:data:`parmpm.materials.LAWS`) has a branch in each function; a law code
without one gives NaN stress and an infinite speed (the run's finite check stops it), and
importing this module fails while a registered law is missing from :data:`DISPATCHED`.
"""
import math

from parmpm.core.jit import helper_kernel
from parmpm.materials.kinematics import (det_2d, det_3d, det_d, gershgorin_2d, gershgorin_3d,
                               gershgorin_bound, left_cauchy_green_2d, left_cauchy_green_3d)
from parmpm.materials import (COL_C2, COL_DENSITY, COL_INV_DENSITY, COL_LAM, COL_LAW, COL_MU, LAWS,
                              LINEAR_ELASTIC, NEO_HOOKEAN)
from parmpm.materials.damage import degrade
from parmpm.materials.linear_elastic import (linear_elastic_2d, linear_elastic_3d,
                                             linear_elastic_energy, linear_elastic_speed,
                                             linear_elastic_stress)
from parmpm.materials.neo_hookean import (neo_hookean_2d, neo_hookean_3d, neo_hookean_energy,
                                          neo_hookean_pressure, neo_hookean_rho_c2,
                                          neo_hookean_stress)

#: the law codes every function below has a branch for
DISPATCHED = (LINEAR_ELASTIC, NEO_HOOKEAN)
_missing = sorted(name for name, law in LAWS.items() if law.code not in DISPATCHED)
if _missing:
    raise ImportError(f"parmpm.materials.laws: no kernel branch for the registered law(s) "
                      f"{', '.join(_missing)}; add them to every function of this module")

NAN = math.nan


@helper_kernel
def cauchy_stress(d, params, F, damage, out):
    """Cauchy stress of one particle from its deformation gradient (leading d×d of 3×3 arrays),
    degraded by its damage (:mod:`parmpm.materials.damage`)."""
    law = int(params[COL_LAW])
    lam, mu = params[COL_LAM], params[COL_MU]
    if law == LINEAR_ELASTIC:
        linear_elastic_stress(d, F, lam, mu, out)
    elif law == NEO_HOOKEAN:
        neo_hookean_stress(d, F, lam, mu, out)
    else:
        for a in range(d):
            for b in range(d):
                out[a, b] = NAN
    if damage > 0.0:
        if law == LINEAR_ELASTIC:
            tr = 0.0
            for a in range(d):
                tr += F[a, a] - 1.0
            pv = lam * tr
        else:
            pv = neo_hookean_pressure(lam, det_d(d, F))
        degrade(d, damage, pv, out)


@helper_kernel
def stored_energy(d, params, F, damage):
    """Elastic energy per unit reference volume of one particle, ``(1 − D) ψ(F)``.

    The damaged law keeps a compressive pressure on broken particles, whose energy this leaves
    out: an underestimate, which is the safe side for the run's blow-up watch
    (:mod:`parmpm.output.energy`)."""
    law = int(params[COL_LAW])
    if law == LINEAR_ELASTIC:
        psi = linear_elastic_energy(d, F, params[COL_LAM], params[COL_MU])
    elif law == NEO_HOOKEAN:
        psi = neo_hookean_energy(d, F, params[COL_LAM], params[COL_MU])
    else:
        psi = NAN
    return (1.0 - damage) * psi


@helper_kernel
def wave_speed(d, params, F):
    """Largest wave speed in the current configuration (module docstring), for the CFL step."""
    bmax = gershgorin_bound(d, F)
    J = det_d(d, F)
    if not J > 0.0:
        return math.inf
    law = int(params[COL_LAW])
    if law == LINEAR_ELASTIC:
        return linear_elastic_speed(params[COL_C2], bmax)
    if law == NEO_HOOKEAN:
        return math.sqrt(neo_hookean_rho_c2(params[COL_LAM], params[COL_MU], bmax, math.log(J))
                         / params[COL_DENSITY])
    return math.inf


@helper_kernel
def stress_speed_2d(params, row, f00, f01, f10, f11):
    """Plane-strain ``(σ_xx, σ_xy, σ_yy, c², (p_n, p_d))`` of material ``row`` from the entries of
    ``F`` (the pressure term as a pair: :func:`parmpm.materials.damage.pressure_term`)."""
    J = det_2d(f00, f01, f10, f11)
    b00, b01, b11 = left_cauchy_green_2d(f00, f01, f10, f11)
    bmax = gershgorin_2d(b00, b01, b11)
    lam, mu = params[row, COL_LAM], params[row, COL_MU]
    law = int(params[row, COL_LAW])
    if law == LINEAR_ELASTIC:
        return linear_elastic_2d(lam, mu, params[row, COL_C2], J, f00, f01, f10, f11, bmax)
    if law == NEO_HOOKEAN:
        return neo_hookean_2d(lam, mu, params[row, COL_INV_DENSITY], J, b00, b01, b11, bmax)
    return NAN, NAN, NAN, math.inf, (NAN, 1.0)


@helper_kernel
def stress_speed_3d(params, row, f00, f01, f02, f10, f11, f12, f20, f21, f22):
    """``(σ_xx, σ_xy, σ_xz, σ_yy, σ_yz, σ_zz, c², (p_n, p_d))`` of material ``row`` from the
    entries of ``F``."""
    J = det_3d(f00, f01, f02, f10, f11, f12, f20, f21, f22)
    b00, b01, b02, b11, b12, b22 = left_cauchy_green_3d(f00, f01, f02, f10, f11, f12, f20, f21,
                                                        f22)
    bmax = gershgorin_3d(b00, b01, b02, b11, b12, b22)
    lam, mu = params[row, COL_LAM], params[row, COL_MU]
    law = int(params[row, COL_LAW])
    if law == LINEAR_ELASTIC:
        return linear_elastic_3d(lam, mu, params[row, COL_C2], J, f00, f01, f02, f10, f11, f12,
                                 f20, f21, f22, bmax)
    if law == NEO_HOOKEAN:
        return neo_hookean_3d(lam, mu, params[row, COL_INV_DENSITY], J, b00, b01, b02, b11, b12,
                              b22, bmax)
    return NAN, NAN, NAN, NAN, NAN, NAN, math.inf, (NAN, 1.0)
