"""A disk on a held block under tilted gravity (``run_scripts/studies/disk_on_block.py``): the
conforming disk's acceleration against Newton's, converging as the grid is refined, and the
lattice disk's flats braking it (issue 40).

Measured (cpdi, 2026-11-29; the same bits on one rank and two): μ = 0 conforming 0.9979,
0.9951, 0.9993 at R/Δx = 5, 10, 20 (within 0.5 % at all three, not monotone from 5 to 10);
lattice 0.9534 at 20. Rolling (μ = 0.3): conforming 0.8412, 0.9444, 0.9908.
"""
from __future__ import annotations

import math

import pytest
from studies.disk_on_block import exact, run

from decomposition import world

pytestmark = pytest.mark.slow  # nine contact runs, about two minutes on one core


@pytest.fixture(scope="module")
def ratios(tmp_path_factory):
    runs = tmp_path_factory.mktemp("disk_on_block")
    cases = [("conforming", 0.0, 5), ("conforming", 0.0, 10), ("conforming", 0.0, 20),
             ("lattice", 0.0, 20), ("conforming", 0.3, 5), ("conforming", 0.3, 10),
             ("conforming", 0.3, 20)]
    return {c: run("cpdi", c[2], c[1], c[0], runs, world())["ratio"] for c in cases}


def test_the_exact_accelerations():
    assert exact(0.0) == pytest.approx(4.905)
    assert exact(0.1) == pytest.approx(9.81 * (0.5 - 0.1 * 3 ** 0.5 / 2))
    assert exact(0.3) == exact(1.0) == pytest.approx(2.0 / 3.0 * 4.905)
    # the sphere (I = 2/5 m R²) rolls from μ = (2/7) tan θ = 0.165 on, at 5/7 g sin θ
    assert exact(0.1, 3) == exact(0.1)
    assert exact(0.17, 3) == exact(0.3, 3) == pytest.approx(5.0 / 7.0 * 4.905)
    assert exact(0.16, 3) == pytest.approx(9.81 * (0.5 - 0.16 * 3 ** 0.5 / 2))


def test_a_frictionless_disk_slides_at_g_sin_theta_closer_when_refined(ratios):
    coarsest = ratios[("conforming", 0.0, 5)]
    coarse, fine = ratios[("conforming", 0.0, 10)], ratios[("conforming", 0.0, 20)]
    assert abs(coarsest - 1.0) < 0.01
    assert abs(coarse - 1.0) < 0.01 and abs(fine - 1.0) < 0.002
    assert abs(fine - 1.0) < abs(coarse - 1.0)


def test_the_lattice_disk_is_braked_by_its_flats(ratios):
    """The same disk on the lattice, at the finer grid: the flats cost it over 3 % (4.7 %
    measured) where the conforming disk is within 0.2 %."""
    assert ratios[("lattice", 0.0, 20)] < 0.97


def test_a_rolling_disk_converges_to_two_thirds_g_sin_theta(ratios):
    errors = [abs(ratios[("conforming", 0.3, n)] - 1.0) for n in (5, 10, 20)]
    assert errors[2] < 0.02
    assert errors[2] < errors[1] < errors[0]  # closer at every refinement


@pytest.fixture(scope="module")
def ramped(tmp_path_factory):
    """Gravity ramped over 0.1 s (the drop's bounce gone), R/Δx = 10: sliding and sticking."""
    runs = tmp_path_factory.mktemp("disk_on_block_ramped")
    return {mu: run("cpdi", 10, mu, "conforming", runs, world(), ramp=0.1)
            for mu in (0.1, math.inf)}


def test_with_gravity_ramped_a_sliding_disk_meets_newton_and_coulomb(ramped):
    """Measured 0.9974 of g (sin θ − μ cos θ), friction 0.1008 of the push (1.0059 and 0.1010
    with gravity at once, the bounce riding the fit)."""
    r = ramped[0.1]
    assert abs(r["ratio"] - 1.0) < 0.01
    assert r["mu_eff"] == pytest.approx(0.1, rel=0.02)


def test_a_disk_that_sticks_rolls_at_two_thirds_g_sin_theta(ramped):
    """"stick": rolls without slipping (measured 0.9815 at R/Δx = 10, 0.9964 at 20); sliding
    at μ = 0.3 would be 0.72 of it."""
    assert abs(ramped[math.inf]["ratio"] - 1.0) < 0.025
