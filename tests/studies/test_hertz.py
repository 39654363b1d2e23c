"""Two elastic spheres meeting head on (``run_scripts/studies/hertz.py``): the Hertz model the
study measures against, and the contact's force history closing on it as the grid is refined
(issue 40).

Measured (cpdi, conforming shells, ppc 1, V = 0.5 m/s, 2026-11-29): the contact's duration
(force above 5 % of its peak) 0.788, 0.864, 0.941, 0.951, 0.934, 0.947 of Hertz's at R/Δx = 4,
6, 8, 10, 14, 20; the peak force 0.986, 0.981, 0.978, 0.969, 1.056, 1.051; the restitution
0.61, 0.84, 0.84, 0.87, 0.94, 0.95; at 28: 0.941, 1.068, 0.97. One sphere onto a rigid plane at
V = 0.2 m/s is within 2.6 % at R/Δx = 28 (docs/concepts/contact.md has the whole study).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from studies.hertz import hertz_constants, hertz_history, run, span_above

from decomposition import world


@pytest.mark.parametrize("speed", [0.2, 0.5, 2.0])
def test_the_integrated_hertz_history_meets_the_closed_forms(speed):
    """RK4 on ``m* δ'' = −k δ^{3/2}`` against Johnson's closed forms: the peak force, and the
    duration ``2.868 (m*²/(R* E*² V))^{1/5}`` (2.868 is rounded: 3e-4)."""
    c = hertz_constants(speed)
    t, f = hertz_history(speed)
    assert f.max() == pytest.approx(c["force_max"], rel=1e-6)
    assert t[-1] == pytest.approx(c["duration"], rel=5e-4)
    # the impulse of an elastic rebound: m* (2 V)
    assert np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(t)) == pytest.approx(2.0 * c["m_star"] * speed, rel=1e-4)


def test_the_contact_radius_and_overlap_at_half_a_metre_a_second():
    c = hertz_constants(0.5)
    assert c["radius_max"] == pytest.approx(math.sqrt(0.05 * c["delta_max"]))
    assert c["delta_max"] == pytest.approx(6.928e-3, rel=1e-3)
    assert c["force_max"] == pytest.approx(94.47, rel=1e-3)


def test_the_span_above_a_share_of_the_peak():
    """A half sine of period 2T stays above 5 % of its peak for T (1 − 2 asin(0.05)/π)."""
    t = np.linspace(0.0, 1.0, 20001)
    f = np.sin(np.pi * t)
    assert span_above(t, f, 0.05) == pytest.approx(1.0 - 2.0 * math.asin(0.05) / math.pi,
                                                   abs=1e-7)


@pytest.mark.slow  # two 3D contact runs, about a minute on one core
def test_the_spheres_close_on_hertz_when_refined(tmp_path):
    coarse, fine = (run("cpdi", n, 0.5, 1, tmp_path, world()) for n in (6, 10))
    assert abs(fine["duration_ratio"] - 1.0) < abs(coarse["duration_ratio"] - 1.0)
    assert abs(fine["duration_ratio"] - 1.0) < 0.07
    for r in (coarse, fine):
        assert abs(r["peak_ratio"] - 1.0) < 0.05
        # the impulse is what the rebound's restitution says: m V (1 + e) / 2
        assert r["impulse_ratio"] == pytest.approx((1.0 + r["restitution"]) / 2.0, abs=0.01)
    assert fine["restitution"] > coarse["restitution"]
