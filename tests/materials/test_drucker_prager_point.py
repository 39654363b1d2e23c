"""Drucker–Prager at the material point, in principal Hencky space (issue 42): the Mohr–Coulomb
matchings, triaxial and plane-strain paths against closed forms (failure stress, dilatancy), the
exact apex and cut-off returns, path independence on radial paths, consistency after every
plastic step, and the energy ledger ``Σ τ:Δε_p = ∫ τ:dε − ψ`` converging as the path is refined.
Tension positive throughout; the paths are driven by strain, with the stress-controlled lateral
components solved here by bracketed secant iterations on the compiled return map.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from parmpm.core.errors import SceneError
from parmpm.materials.plasticity.drucker_prager import (
    APEX, CONE, CUTOFF, ELASTIC, drucker_prager_constants, dp_dissipation, dp_return, dp_yield)
from parmpm.materials.plasticity.hencky import hencky_energy

E, NU = 0.84e6, 0.3  # Bui et al. (2008)'s soil
K, G = E / (3.0 * (1.0 - 2.0 * NU)), E / (2.0 * (1.0 + NU))
PHI = 19.8


def ret(eps_tr, cst, c):
    eta, xi, eta_bar, p_t = cst
    eps, tau = np.zeros(3), np.zeros(3)
    dg, dgt, region = dp_return(np.asarray(eps_tr, float), K, G, eta, xi, eta_bar, c, p_t,
                                  0.0, 0.0, 0.0, eps, tau)
    return eps, tau, dg, dgt, region


def mohr_coulomb(tau, phi, c):
    """``(τ_max − τ_min)/2 + (τ_max + τ_min)/2 sin φ − c cos φ`` (tension positive)."""
    s = math.sin(math.radians(phi))
    return 0.5 * (tau.max() - tau.min()) + 0.5 * (tau.max() + tau.min()) * s \
        - c * math.cos(math.radians(phi))


def sqrt_j2(tau):
    s = tau - tau.mean()
    return math.sqrt(0.5 * s @ s)


def solve_lateral(eps_e, d_axial, index, target, cst, c, fixed=None):
    """The lateral strain increment ``x`` (on ``index``: both 1 and 2 for a triaxial path, or 1
    alone with ε_2 ``fixed``) that makes ``τ[1] = target``; regula falsi (Illinois) on a bracket."""
    def state(x):
        d = np.array([d_axial, x, x if fixed is None else fixed])
        return ret(eps_e + d, cst, c) + (d,)

    def r(x):
        return state(x)[1][1] - target
    lo, hi = -abs(d_axial) - 1e-4, abs(d_axial) + 1e-4
    while r(lo) > 0.0:
        lo *= 2.0
    while r(hi) < 0.0:
        hi *= 2.0
    flo, fhi, side = r(lo), r(hi), 0
    for _ in range(200):
        x = (lo * fhi - hi * flo) / (fhi - flo)
        fx = r(x)
        if abs(fx) <= 1e-12 * abs(target) or hi - lo < 1e-17:
            break
        if fx < 0.0:
            lo, flo = x, fx
            fhi = fhi / 2.0 if side == -1 else fhi
            side = -1
        else:
            hi, fhi = x, fx
            flo = flo / 2.0 if side == 1 else flo
            side = 1
    return state(x)


def confined_path(cst, c, conf, steps, strain, plane_strain=False):
    """Confine hydrostatically at ``−conf``, then compress axis 0 by ``strain`` in ``steps``
    keeping ``τ_1`` (and ``τ_2`` on a triaxial path) at ``−conf``; ε_2 frozen in plane strain."""
    eps_e = np.full(3, -conf / (3.0 * K))
    out = []
    for _ in range(steps):
        eps, tau, dg, dgt, region, d = solve_lateral(
            eps_e, -strain / steps, 1, -conf, cst, c, 0.0 if plane_strain else None)
        out.append((eps_e + d, eps, tau, dg, dgt, region))
        eps_e = eps
    return out


# ------------------------------------------------------------------ matchings and inputs
def mc_surface(p, lode, phi, c):
    """The Mohr–Coulomb surface point at mean stress ``p`` and Lode angle ``lode`` (bisection)."""
    d = np.array([math.cos(lode - 2 * math.pi / 3), math.cos(lode + 2 * math.pi / 3),
                  math.cos(lode)])
    lo, hi = 0.0, 1.0e7
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if mohr_coulomb(p + mid * d, phi, c) < 0.0 else (lo, mid)
    return p + lo * d


@pytest.mark.parametrize("matching,touch,other", [("outer", (-2, 1, 1), (-1, -1, 2)),
                                                  ("inner", (-1, -1, 2), (-2, 1, 1))])
def test_matching_touches_mohr_coulomb_on_its_meridian(matching, touch, other):
    """The outer cone meets Mohr–Coulomb on the compressive meridian (τ_1 < τ_2 = τ_3) and holds
    every other Mohr–Coulomb surface point (circumscribed); the inner cone meets it on the
    tensile meridian (τ_1 = τ_2 < τ_3) and lies inside it on the compressive meridian."""
    c = 1.0e3
    eta, xi, _, _ = drucker_prager_constants(PHI, 0.0, c, matching)
    sign = 1.0 if matching == "outer" else -1.0
    for p in (-5.0e4, -1.0e3, 0.0, 0.5 * xi * c / eta):
        r = math.sqrt(3.0) * (xi * c - eta * p)  # √J2 of p + r·dir/3 is r/√3 on both meridians
        on = p + r * np.array(touch) / 3.0
        assert dp_yield(on, eta, xi, c) == pytest.approx(0.0, abs=1e-9 * c)
        assert mohr_coulomb(on, PHI, c) == pytest.approx(0.0, abs=1e-9 * c)
        assert sign * mohr_coulomb(p + r * np.array(other) / 3.0, PHI, c) > 1e-3 * c
        if matching == "outer":
            for lode in np.linspace(0.0, math.pi / 3.0, 7):
                assert dp_yield(mc_surface(p, lode, PHI, c), eta, xi, c) <= 1e-9 * c


def test_plane_strain_matching_is_the_inscribed_cone():
    """The plane-strain cone (associated) lies inside Mohr–Coulomb and touches it at one Lode
    angle between the meridians: over a sweep, f_DP ≥ 0 on the MC surface with minimum ≈ 0."""
    c = 1.0e3
    eta, xi, _, _ = drucker_prager_constants(PHI, PHI, c)
    for p in (-5.0e4, 0.0):
        f = [dp_yield(mc_surface(p, lode, PHI, c), eta, xi, c)
             for lode in np.linspace(0.0, math.pi / 3.0, 241)]
        assert min(f) >= -1e-9 * c and min(f) < 1e-2 * c
        assert max(f) > 0.05 * (xi * c - eta * p)


def test_matching_constants_closed_forms():
    """The three matchings' numbers at φ = 19.8° (Bui et al.) and the φ = 0 limits."""
    t, s = math.tan(math.radians(PHI)), math.sin(math.radians(PHI))
    assert drucker_prager_constants(PHI, 0.0, 0.0)[:3] == pytest.approx(
        (3 * t / math.sqrt(9 + 12 * t * t), 3 / math.sqrt(9 + 12 * t * t), 0.0), rel=1e-15)
    assert drucker_prager_constants(PHI, PHI, 1.0, "outer")[0] == pytest.approx(
        6 * s / (math.sqrt(3) * (3 - s)), rel=1e-15)
    assert drucker_prager_constants(0.0, 0.0, 1.0, "plane_strain") == (0.0, 1.0, 0.0, math.inf)
    assert drucker_prager_constants(0.0, 0.0, 1.0, "outer")[1] == pytest.approx(2 / math.sqrt(3))
    eta, xi, _, p_t = drucker_prager_constants(PHI, 0.0, 2.0)
    assert p_t == xi * 2.0 / eta  # the default cut-off is the apex
    assert drucker_prager_constants(PHI, 0.0, 0.0)[3] == 0.0


@pytest.mark.parametrize("args,msg", [
    ((PHI, 0.0, 1.0, "outside"), "matching 'outside' is not one of plane_strain, outer, inner"),
    ((95.0, 0.0, 1.0), "friction angle 95.0 deg is outside [0, 90)"),
    ((PHI, 25.0, 1.0), "dilatancy angle 25.0 deg is outside [0, phi = 19.8]"),
    ((PHI, 0.0, -1.0), "cohesion -1.0 must be finite and >= 0"),
    ((0.0, 0.0, 0.0), "phi = 0 and c = 0 leave no strength at all"),
    ((PHI, 0.0, 1.0, "outer", 50.0), "tension cut-off 50.0 is outside [0, apex xi c / eta ="),
])
def test_bad_constants_are_one_line_errors(args, msg):
    with pytest.raises(SceneError) as err:
        drucker_prager_constants(*args, where="materials.soil")
    assert str(err.value).startswith("materials.soil: " + msg) and "\n" not in str(err.value)


# ------------------------------------------------------------------ triaxial and plane strain
@pytest.mark.parametrize("matching", ["outer", "inner", "plane_strain"])
@pytest.mark.parametrize("psi", [0.0, 10.0, PHI])
def test_triaxial_failure_stress_and_dilatancy(matching, psi):
    """Triaxial compression at confinement σ_c: the axial stress at failure is the cone's closed
    form ``τ_1 = −σ_c − (ξ c + η σ_c) / (1/√3 − η/3)`` (Mohr–Coulomb's ``σ_c N_φ + 2c √N_φ`` for
    the outer cone), and the plastic strains flow at ``Δε_v^p / Δε_1^p = η̄ / (η̄/3 − 1/√3)``
    (Mohr–Coulomb's ``−2 sin ψ / (1 − sin ψ)`` for the outer cone; none for ψ = 0)."""
    c, conf = 2.0e3, 1.0e4
    cst = drucker_prager_constants(PHI, psi, c, matching)
    eta, xi, eta_bar, _ = cst
    path = confined_path(cst, c, conf, 40, 0.05)
    regions = [row[5] for row in path]
    assert regions[0] == ELASTIC and regions[-1] == CONE and CUTOFF not in regions
    first = regions.index(CONE)
    tau1 = -conf - (xi * c + eta * conf) / (1.0 / math.sqrt(3.0) - eta / 3.0)
    if matching == "outer":
        s = math.sin(math.radians(PHI))
        n_phi = (1 + s) / (1 - s)
        assert tau1 == pytest.approx(-(conf * n_phi + 2 * c * math.sqrt(n_phi)), rel=1e-13)
    for eps_tr, eps, tau, *_ in path[first:]:
        assert tau == pytest.approx([tau1, -conf, -conf], rel=1e-11)
        dep = eps_tr - eps
        assert dep[0] < 0.0
        assert dep.sum() / dep[0] == pytest.approx(eta_bar / (eta_bar / 3 - 1 / math.sqrt(3)),
                                                   rel=1e-9, abs=1e-12)
        if matching == "outer":
            sp = math.sin(math.radians(psi))
            assert dep.sum() / dep[0] == pytest.approx(-2 * sp / (1 - sp), rel=1e-9, abs=1e-12)
    assert path[first - 1][2][0] > tau1  # still elastic the step before


@pytest.mark.parametrize("psi", [0.0, PHI])
def test_plane_strain_limit_state(psi):
    """Plane strain (ε_2 frozen), τ_1 held at −σ_c, axis 0 compressed until the stress stops
    moving. Associated (ψ = φ): the plane-strain matching's limit is Mohr–Coulomb's in the plane.
    ψ = 0: no out-of-plane plastic flow makes ``s_2 = 0`` and the limit ``√J2 = (τ_1 − τ_0)/2 =
    ξ c − η p`` — MC with ``sin φ_eff = η`` (19.417° for φ = 19.8°): weaker than MC by design."""
    c, conf = 2.0e3, 1.0e4
    cst = drucker_prager_constants(PHI, psi, c, "plane_strain")
    eta, xi = cst[:2]
    path = confined_path(cst, c, conf, 400, 0.4, plane_strain=True)
    tau = path[-1][2]
    assert tau[0] < tau[2] < tau[1] == pytest.approx(-conf, rel=1e-12)
    if psi == PHI:
        assert mohr_coulomb(tau, PHI, c) == pytest.approx(0.0, abs=1e-9 * conf)
    else:
        assert tau[2] - tau.mean() == pytest.approx(0.0, abs=1e-9 * conf)
        phi_eff = math.degrees(math.asin(eta))
        assert phi_eff == pytest.approx(19.4169, abs=1e-4)
        assert mohr_coulomb(tau, phi_eff, xi * c / math.cos(math.radians(phi_eff))) == \
            pytest.approx(0.0, abs=1e-9 * conf)
        assert mohr_coulomb(tau, PHI, c) < -1e-3 * conf


# ------------------------------------------------------------------ apex, cut-off, J2 limit
@pytest.mark.parametrize("psi", [0.0, 10.0, PHI])
def test_hydrostatic_extension_lands_exactly_on_the_apex(psi):
    """c = 0: a stretched trial, hydrostatic or sheared inside the apex region, returns to
    τ = 0 exactly, all of the trial strain plastic: ``Δγ = q*/G``, ``Δγ_t = p*/K − η̄ Δγ``."""
    cst = drucker_prager_constants(PHI, psi, 0.0)
    eta_bar = cst[2]
    for eps_tr in ([1e-3, 1e-3, 1e-3], [1.2e-3, 1e-3, 0.8e-3]):
        eps, tau, dg, dgt, region = ret(eps_tr, cst, 0.0)
        assert region == APEX and np.all(tau == 0.0) and np.all(eps == 0.0)
        q, p = sqrt_j2(2 * G * (np.array(eps_tr) - np.mean(eps_tr))), K * np.sum(eps_tr)
        assert dg == pytest.approx(q / G, rel=1e-14, abs=1e-300)
        assert dgt == pytest.approx(p / K - eta_bar * q / G, rel=1e-14) and dgt > 0.0
        assert dp_dissipation(np.array(eps_tr, float), eps, tau) == 0.0


def test_apex_and_cutoff_with_cohesion():
    """c > 0: a hydrostatic stretch stops at ``p = ξ c / η`` (the default cut-off); with a lower
    cut-off p_t the trial lands on the cut-off plane (deviator kept) or on its corner with the
    cone (``√J2 = ξ c − η p_t``), multipliers ≥ 0."""
    c = 1.0e3
    eta, xi, eta_bar, apex = cst = drucker_prager_constants(PHI, 5.0, c)
    assert apex == pytest.approx(xi * c / eta, rel=1e-15)
    eps, tau, dg, dgt, region = ret([0.01, 0.01, 0.01], cst, c)
    assert region == APEX and tau == pytest.approx([apex] * 3, rel=1e-15)
    assert dgt == pytest.approx(0.03 - apex / K, rel=1e-14) and dg == 0.0
    p_t = 0.25 * apex
    low = drucker_prager_constants(PHI, 5.0, c, tension_cutoff=p_t)
    sheared = np.array([1.0, 0.0, -1.0]) * 0.2 * c / G
    eps, tau, dg, dgt, region = ret(0.01 + sheared, low, c)
    assert region == CUTOFF and dg == 0.0 and dgt == pytest.approx((0.03 * K - p_t) / K)
    assert tau == pytest.approx(p_t + 2 * G * sheared, rel=1e-12)
    eps, tau, dg, dgt, region = ret(0.01 + 20 * sheared, low, c)
    assert region == APEX and tau.mean() == pytest.approx(p_t, rel=1e-13)
    assert sqrt_j2(tau) == pytest.approx(xi * c - eta * p_t, rel=1e-12) and dgt > 0.0 < dg
    assert dp_yield(tau, eta, xi, c) == pytest.approx(0.0, abs=1e-12 * c)


def test_path_from_cone_to_apex():
    """c = 0, confined then stretched while sheared: the stress slides down the cone, then
    reaches the apex; there τ = 0 exactly and the plastic strains summed over the steps are the
    whole strain."""
    cst = drucker_prager_constants(PHI, 5.0, 0.0)
    eps_e = np.full(3, -1e4 / (3 * K))
    total, plastic, regions = eps_e.copy(), np.zeros(3), []
    for _ in range(60):
        d = np.array([2e-4, -1e-4, 3e-4])
        eps, tau, dg, dgt, region = ret(eps_e + d, cst, 0.0)
        plastic += eps_e + d - eps
        total += d
        regions.append(region)
        eps_e = eps
    assert regions[0] == ELASTIC and CONE in regions and regions[-1] == APEX
    assert regions.index(CONE) < regions.index(APEX)
    assert np.all(tau == 0.0) and np.all(eps_e == 0.0)
    assert plastic == pytest.approx(total, rel=1e-12, abs=1e-18)


def test_zero_friction_is_the_von_mises_cylinder():
    """φ = 0: ``η = η̄ = 0``, no apex (p_t = ∞): the radial return of a cylinder of radius
    ``√J2 = ξ c``, the mean stress untouched."""
    c = 1.0e3
    cst = drucker_prager_constants(0.0, 0.0, c, "outer")
    rng = np.random.default_rng(7)
    for eps_tr in rng.normal(0.0, 5 * c / G, (200, 3)):
        eps, tau, dg, dgt, region = ret(eps_tr, cst, c)
        p, s = K * eps_tr.sum(), 2 * G * (eps_tr - eps_tr.mean())
        q = sqrt_j2(p + s)
        assert tau == pytest.approx(p + s * min(1.0, 2 * c / math.sqrt(3) / q), rel=1e-12)
        assert region == (CONE if q > 2 * c / math.sqrt(3) else ELASTIC) and dgt == 0.0


# ------------------------------------------------------------------ algorithm properties
def test_one_step_equals_many_on_a_radial_path():
    """The cone return is an affine oblique projection: on a radial strain path from the
    natural state, one step and many give the same state (to round-off); a path with a corner
    does not (the test can tell)."""
    c = 1.0e3
    cst = drucker_prager_constants(PHI, 5.0, c, "outer")
    d = np.array([-3e-2, 1e-2, 0.5e-2])

    def walk(legs, n):
        eps_e, plastic = np.zeros(3), np.zeros(3)
        for leg in legs:
            for _ in range(n):
                eps, tau, *_, region = ret(eps_e + leg / n, cst, c)
                plastic += eps_e + leg / n - eps
                eps_e = eps
        return eps_e, tau, plastic, region
    one, many = walk([d], 1), walk([d], 50)
    assert one[3] == many[3] == CONE
    for a, b in zip(one[:3], many[:3]):
        assert b == pytest.approx(a, rel=1e-11)
    bent = walk([0.5 * d + [0, 5e-3, 0], 0.5 * d - [0, 5e-3, 0]], 50)
    assert abs(bent[1] - one[1]).max() > 1e-3 * abs(one[1]).max()


@pytest.mark.parametrize("psi,cut", [(0.0, None), (10.0, 0.3), (PHI, None)])
def test_every_plastic_state_is_consistent(psi, cut):
    """Random trials over every region: the returned state satisfies its surfaces to round-off
    (f = 0 on the cone and corner, p = p_t on the cut-off, f ≤ 0 and p ≤ p_t everywhere), the
    multipliers are ≥ 0 and rebuild ``Δε_p = Δγ ∂g/∂τ + Δγ_t I/3``, the plastic work is ≥ 0."""
    c = 1.0e3
    eta, xi, eta_bar, apex = drucker_prager_constants(PHI, psi, c)
    cst = drucker_prager_constants(PHI, psi, c, tension_cutoff=None if cut is None else cut * apex)
    p_t = cst[3]
    rng = np.random.default_rng(1)
    seen = set()
    for eps_tr in rng.normal(0.0, 3 * c / G, (3000, 3)):
        eps, tau, dg, dgt, region = ret(eps_tr, cst, c)
        seen.add(region)
        scale = c + abs(tau).max()
        f, p = dp_yield(tau, eta, xi, c), tau.mean()
        assert f <= 1e-12 * scale and p <= p_t + 1e-12 * scale and dg >= 0.0 and dgt >= 0.0
        if region in (CONE, APEX):
            assert abs(f) <= 1e-12 * scale
        if region in (CUTOFF, APEX):
            assert abs(p - p_t) <= 1e-12 * scale
        s, q = 2 * G * (eps_tr - eps_tr.mean()), sqrt_j2(tau)  # the trial deviator: s's direction
        assert tau - p == pytest.approx(s * q / sqrt_j2(s), abs=1e-12 * scale)
        flow = dg * (s / (2 * sqrt_j2(s)) + eta_bar / 3) + dgt / 3
        assert eps_tr - eps == pytest.approx(flow, abs=1e-12 * np.abs(eps_tr).max())
        assert dp_dissipation(eps_tr, eps, tau) >= 0.0
    assert seen == ({ELASTIC, CONE, APEX} if cut is None else {ELASTIC, CONE, CUTOFF, APEX})


def test_return_is_continuous_across_region_boundaries():
    """Trials along lines that cross every region boundary (elastic, cone, corner, cut-off):
    neighbouring returned stresses differ by no more than a few times the trials' difference,
    so no boundary is misplaced (a misplaced one jumps by a finite amount)."""
    c = 1.0e3
    eta, xi, eta_bar, apex = drucker_prager_constants(PHI, 5.0, c)
    cst = drucker_prager_constants(PHI, 5.0, c, tension_cutoff=0.4 * apex)
    crossed = set()
    for dev0, slope in ((0.0, 0.0), (0.2, 0.0), (1.0, 0.0), (1.5, -0.5), (0.5, -0.16)):
        prev, seen = None, []
        for x in np.linspace(-3.0, 3.0, 4001):
            dev = (dev0 + slope * x) * c / G
            eps_tr = x * apex / K / 3 + np.array([dev, 0.0, -dev])
            eps, tau, *_, region = ret(eps_tr, cst, c)
            if not seen or seen[-1] != region:
                seen.append(region)
            if prev is not None:
                assert abs(tau - prev[1]).max() <= 3 * (2 * G + 3 * K) * abs(eps_tr - prev[0]).max()
            prev = eps_tr, tau
        crossed |= set(zip(seen, seen[1:]))
    assert crossed >= {
        (ELASTIC, CONE), (ELASTIC, CUTOFF), (CONE, APEX), (APEX, CUTOFF)}


def ledger(n):
    """Σ τ_{n+1}:Δε_p, the trapezoidal stress power ∫τ:dε and ψ(ε_e) on a curved non-associated
    path (c > 0, ψ = 10°) that yields and then slides over the cone."""
    c = 1.0e3
    cst = drucker_prager_constants(PHI, 10.0, c)
    t = np.linspace(0.0, 1.0, n + 1)
    path = np.stack([-2e-2 * t, 8e-3 * np.sin(math.pi * t), -1e-2 * t ** 2 + 4e-3 * t], axis=1)
    eps_e, tau_n = np.zeros(3), np.zeros(3)
    diss, power, steps = 0.0, 0.0, []
    for k in range(n):
        d = path[k + 1] - path[k]
        eps_tr = eps_e + d
        eps, tau, *_ = ret(eps_tr, cst, c)
        dw = dp_dissipation(eps_tr, eps, tau)
        steps.append(dw)
        diss += dw
        power += 0.5 * (tau_n + tau) @ d
        eps_e, tau_n = eps, tau
    return diss, power - hencky_energy(eps_e, K, G), min(steps)


def test_dissipation_closes_the_energy_ledger():
    """``Σ τ_{n+1}:Δε_p`` against ``∫ τ:dε − ψ(ε_e)``: the gap is ``Σ ½(τ_n − τ_{n+1}):Δε_p``,
    first order in the step, so it halves with each halving of the step; every step's plastic
    work is ≥ 0."""
    rows = [ledger(n) for n in (50, 100, 200, 400, 800)]
    gaps = [abs(power - diss) for diss, power, _ in rows]
    for g0, g1 in zip(gaps, gaps[1:]):
        assert 1.9 < g0 / g1 < 2.3
    assert gaps[-1] < 1e-3 * rows[-1][0]
    assert all(low >= 0.0 for *_, low in rows)
    assert rows[-1][0] > 0.0
