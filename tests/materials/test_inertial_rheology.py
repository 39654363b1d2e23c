"""μ(I) on Drucker–Prager's cone (:mod:`parmpm.materials.plasticity.inertial`; Jop, Forterre &
Pouliquen 2006): the cone's slope ``η(I) = η_s + (η_2 − η_s) I/(I_0 + I)``, ``I = γ̇_p d /
√(P/ρ_s)``.

Checked against results written here, not the kernel's own:

* one return (no dilatancy): the multiplier is the root of a quadratic, solved in closed form
  here; with dilatancy, the root of the return's scalar equation found by bisection here;
* the limits: ``I_0 → ∞`` or ``η_2 = η_s`` give the rate-independent cone, a step that shrinks to
  nothing (``a → ∞``) the cone of ``η_2``;
* steady simple shear under a held volume, through the plastic pass (3D, both its series and its
  eigen path): ``√J2 / P`` equals Jop et al.'s ``μ(I)`` at the measured plastic shear rate, to
  round-off, and that rate is the imposed one; a sweep over four decades of ``I`` follows the
  curve, and the rate-independent material stays at ``η_s``;
* the energy: every step's plastic work ≥ 0.
"""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from parmpm.materials.plasticity.drucker_prager import CONE, dp_return
from parmpm.materials.plasticity.state import STATE_EPSP, STATE_WORK, initial_state
from parmpm.materials.plasticity.table import (PCOL_ETA, PCOL_ETA_2, PCOL_G, PCOL_GRAIN_SCALE,
                                               PCOL_I0, plastic_table)
from parmpm.materials.plasticity.update import plastic_pass

NONE = dict(hardening_exponent=None, strength_coefficient=None, rate_coefficient=None,
            reference_rate=None, yield_stress=None, hardening=None, hardening_modulus=None,
            matching=None, tension_cutoff=None, volume_correction=False, grain_density=2700.0)
#: Bui et al. (2008)'s rods with a rate-dependent friction: φ_2 and I_0 of the order Jop et al.
#: measured on glass beads, d of the rods
RODS = SimpleNamespace(**NONE, model="drucker_prager", youngs_modulus=8.4e5, poisson_ratio=0.3,
                       density=2650.0, friction_angle=19.8, dilatancy_angle=0.0, cohesion=0.0,
                       friction_angle_2=31.7, inertial_number_0=0.279, grain_diameter=1.25e-3)


def plane_strain_eta(phi_deg):
    """The plane-strain matching's cone slope, written out here: ``3 tan φ / √(9 + 12 tan²φ)``."""
    t = math.tan(math.radians(phi_deg))
    return 3.0 * t / math.sqrt(9.0 + 12.0 * t * t)


def table_of(**changes):
    return plastic_table({"m": SimpleNamespace(**{**vars(RODS), **changes})}, ["m"])


def mu_of_i(inertial, m=RODS):
    """Jop et al.'s μ(I) with the matched slopes."""
    es, e2 = plane_strain_eta(m.friction_angle), plane_strain_eta(m.friction_angle_2)
    return es + (e2 - es) * inertial / (m.inertial_number_0 + inertial)


def invariants(tau):
    """``(q = √J2, P = −tr τ/3)`` of principal (3,) or full (3, 3) stresses."""
    tau = np.asarray(tau, float)
    vals = np.linalg.eigvalsh(tau) if tau.ndim == 2 else tau
    p = vals.mean()
    return math.sqrt(0.5 * ((vals - p) ** 2).sum()), -p


def test_the_table_holds_the_matched_slopes_and_the_grain_scale():
    row = table_of()[0]
    assert row[PCOL_ETA] == pytest.approx(plane_strain_eta(19.8), rel=1e-14)
    assert row[PCOL_ETA_2] == pytest.approx(plane_strain_eta(31.7), rel=1e-14)
    assert row[PCOL_I0] == 0.279
    assert row[PCOL_GRAIN_SCALE] == pytest.approx(1.25e-3 * math.sqrt(2700.0), rel=1e-15)
    assert table_of(grain_density=None)[0][PCOL_GRAIN_SCALE] == pytest.approx(
        1.25e-3 * math.sqrt(2650.0), rel=1e-15)
    off = table_of(friction_angle_2=None)[0]
    assert off[PCOL_I0] == off[PCOL_ETA_2] == off[PCOL_GRAIN_SCALE] == 0.0


def one_return(eps_tr, eta, eta2, eta_bar, i0, a, K=7e5, G=3.2e5):
    eps, tau = np.zeros(3), np.zeros(3)
    dg, dgt, region = dp_return(np.asarray(eps_tr, float), K, G, eta, 1.0, eta_bar, 0.0, 0.0,
                                eta2, i0, a, eps, tau)
    return dg, dgt, region, eps, tau


#: compressed trial states with deviators of every direction and size (principal log strains)
TRIALS = [(-0.010, -0.002, 0.004), (-0.003, -0.001, 0.002), (-0.05, 0.01, 0.02),
          (-0.2, -0.05, -0.01), (-1e-5, -1e-6, 3e-6), (0.004, -0.006, -0.01)]


@pytest.mark.parametrize("eps_tr", TRIALS)
@pytest.mark.parametrize("a", [1e-3, 1.0, 30.0, 1e4])
def test_one_return_is_the_root_of_the_quadratic(eps_tr, a):
    """ψ = 0: ``P`` stays at the trial's, so ``q* − GΔγ − P (η_s + Δη aΔγ/(√P I_0 + aΔγ)) = 0``
    times ``(√P I_0 + aΔγ)`` is a quadratic in Δγ; its root in [0, static] is the return's."""
    K, G, eta, eta2, i0 = 7e5, 3.2e5, 0.33, 0.55, 0.279
    ev = sum(eps_tr)
    dev = np.asarray(eps_tr) - ev / 3.0
    P, q = -K * ev, G * math.sqrt(2.0 * (dev ** 2).sum())
    assert q - eta * P > 0.0  # a plastic trial
    dg, dgt, region, eps, tau = one_return(eps_tr, eta, eta2, 0.0, i0, a, K, G)
    r = math.sqrt(P)
    # -G a x² + (a (q - P η_s) - G r I_0 - P Δη a) x + r I_0 (q - P η_s) = 0
    A, B, C = -G * a, a * (q - P * eta) - G * r * i0 - P * (eta2 - eta) * a, r * i0 * (q - P * eta)
    root = math.sqrt(B * B - 4.0 * A * C)  # the positive root (A < 0, C > 0), without cancelling
    x = (-B - root) / (2.0 * A) if B >= 0.0 else 2.0 * C / (root - B)
    assert region == CONE and dgt == 0.0
    assert dg == pytest.approx(x, rel=1e-12)
    assert 0.0 < dg <= (q - eta * P) / G
    qn, Pn = invariants(tau)
    inertial = a * dg / math.sqrt(Pn)
    assert qn == pytest.approx((eta + (eta2 - eta) * inertial / (i0 + inertial)) * Pn, rel=1e-11)
    assert Pn == pytest.approx(P, rel=1e-14)


@pytest.mark.parametrize("eps_tr", TRIALS)
def test_with_dilatancy_the_return_solves_its_scalar_equation(eps_tr):
    """ψ > 0: ``P = P* + K η̄ Δγ`` grows with the flow; the root found here by bisection."""
    K, G, eta, eta2, eta_bar, i0, a = 7e5, 3.2e5, 0.33, 0.55, 0.12, 0.279, 40.0
    ev = sum(eps_tr)
    dev = np.asarray(eps_tr) - ev / 3.0
    P0, q0 = -K * ev, G * math.sqrt(2.0 * (dev ** 2).sum())

    def g(x):
        P = P0 + K * eta_bar * x
        inertial = a * x / math.sqrt(P)
        return q0 - G * x - (eta + (eta2 - eta) * inertial / (i0 + inertial)) * P

    lo, hi = 0.0, (q0 - eta * P0) / (G + K * eta * eta_bar)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if g(mid) > 0.0 else (lo, mid)
    dg, _, region, eps, tau = one_return(eps_tr, eta, eta2, eta_bar, i0, a, K, G)
    assert region == CONE
    assert dg == pytest.approx(0.5 * (lo + hi), rel=1e-12)
    qn, Pn = invariants(tau)
    assert Pn == pytest.approx(P0 + K * eta_bar * dg, rel=1e-13)
    # the plastic strain is the potential's direction: volumetric part η̄ Δγ
    assert sum(eps_tr) - eps.sum() == pytest.approx(eta_bar * dg, rel=1e-10)


@pytest.mark.parametrize("eps_tr", TRIALS)
def test_the_limits_are_the_rate_independent_cones(eps_tr):
    static = one_return(eps_tr, 0.33, 0.33, 0.0, 0.0, 0.0)
    for eta2, i0, a in [(0.33, 0.279, 50.0), (0.55, 1e300, 50.0), (0.55, 0.279, 0.0)]:
        got = one_return(eps_tr, 0.33, eta2, 0.0, i0, a)
        assert got[0] == pytest.approx(static[0], rel=1e-14)
        np.testing.assert_allclose(got[4], static[4], rtol=1e-13, atol=1e-12)
    fast = one_return(eps_tr, 0.33, 0.55, 0.0, 0.279, 1e300)  # any flow at infinite I
    ceiling = one_return(eps_tr, 0.55, 0.55, 0.0, 0.0, 0.0)
    if ceiling[2] == CONE:  # the slower cone still flows: the fast return is its return
        assert fast[0] == pytest.approx(ceiling[0], rel=1e-9)
    assert math.isfinite(fast[0]) and 0.0 <= fast[0] <= static[0]


def shear(rate, J, steps, table, strain=1.0):
    """Simple shear ``F = J^{1/3} (I + γ e_x ⊗ e_y)`` at engineering rate ``rate`` to ``strain``
    through the plastic pass; per step ``(q, P)`` of the Kirchhoff stress and ``Δγ`` from the
    state's ``ε̄p`` (``Δε̄p = Δγ/√3``), and the plastic work's increments."""
    dt = strain / rate / steps
    state, stress = initial_state(1), np.zeros((1, 3, 3))
    mat, v, F = np.zeros(1, np.int64), np.zeros((1, 3)), np.zeros((1, 3, 3))
    out = []
    for n in range(1, steps + 1):
        F[0] = J ** (1.0 / 3.0) * np.array([[1.0, rate * n * dt, 0.0], [0, 1, 0], [0, 0, 1]])
        epsp, work = state[0, STATE_EPSP], state[0, STATE_WORK]
        plastic_pass(3, F, mat, table, state, stress, v, dt)
        q, P = invariants(J * stress[0])
        out.append((q, P, math.sqrt(3.0) * (state[0, STATE_EPSP] - epsp) / dt,
                    state[0, STATE_WORK] - work))
    return np.array(out), dt


@pytest.mark.parametrize("J", [0.99, 0.8])  # b_e within the series' reach, and beyond it
@pytest.mark.parametrize("rate", [1.0, 1e2, 1e3, 1e4])
def test_steady_shear_follows_mu_of_i(J, rate):
    """Past the elastic transient, every step's ``√J2/P`` is μ(I) at its own measured plastic
    rate (to round-off), and that rate is the imposed one (to the elastic strain's order)."""
    rows, dt = shear(rate, J, 400, table_of())
    q, P, gp, work = rows[300:].T
    a = RODS.grain_diameter * math.sqrt(RODS.grain_density)
    inertial = gp * a / np.sqrt(P)
    np.testing.assert_allclose(q / P, mu_of_i(inertial), rtol=1e-10)
    elastic = q / (2.0 * table_of()[0][PCOL_G])  # the elastic shear strain, 0.004 to 0.12
    assert (np.abs(gp / rate - 1.0) < 3.0 * elastic ** 2).all()  # second order in it
    assert (rows[:, 3] >= 0.0).all() and work.min() > 0.0
    assert np.ptp(P) / P.mean() < 1e-10  # no dilatancy: the pressure holds (to round-off)


def test_the_sweep_spans_the_curve_and_the_static_material_stays_put():
    ratios, inertials = [], []
    a = RODS.grain_diameter * math.sqrt(RODS.grain_density)
    for rate in (1.0, 1e2, 1e3, 1e4, 1e5):
        rows, _ = shear(rate, 0.99, 300, table_of())
        q, P, gp, _ = rows[-1]
        ratios.append(q / P)
        inertials.append(gp * a / math.sqrt(P))
    assert inertials[0] < 1e-3 and inertials[-1] > 10.0
    assert np.all(np.diff(ratios) > 0.0)
    np.testing.assert_allclose(ratios, mu_of_i(np.array(inertials)), rtol=1e-10)
    assert ratios[0] == pytest.approx(plane_strain_eta(19.8), rel=5e-3)
    assert ratios[-1] > 0.95 * plane_strain_eta(31.7)
    rows, _ = shear(1e4, 0.99, 300, table_of(friction_angle_2=None))
    assert rows[-1, 0] / rows[-1, 1] == pytest.approx(plane_strain_eta(19.8), rel=1e-12)


def test_a_tensile_trial_goes_to_the_apex_as_without_rate():
    """No pressure, no inertial number: a stretched particle returns to the apex as before."""
    for eps_tr in [(0.01, 0.002, -0.001), (0.003, 0.003, 0.003)]:
        got = one_return(eps_tr, 0.33, 0.55, 0.0, 0.279, 40.0)
        static = one_return(eps_tr, 0.33, 0.33, 0.0, 0.0, 0.0)
        assert got[2] == static[2] and got[0] == static[0]
        np.testing.assert_array_equal(got[4], static[4])
