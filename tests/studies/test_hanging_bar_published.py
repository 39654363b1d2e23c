"""The built-in self-weighted bars as published (Sadeghirad, Brannon & Burghardt 2011): the top
held vertically only (a roller), the bottom corner's first peak and rebound in the metrics, and
the 2D bar against the finite-element reference of ``run_scripts/studies/fe_bar.py``.

* the scenes ``hanging_bar``, ``hanging_bar_3d`` and ``hanging_bar_damage`` hold the nodes at and
  above the bar's top along y only; the clamped bar is two ``--set`` lines away;
* the metrics find the bottom-left particle, its first peak (value, time) and rebound;
* the 2D cpdi bar's first peak is within 1 % of a converged Q1 finite-element run of the same bar
  (the change from 20 × 20 to 40 × 40 elements is 0.05 %), the clamped bar's 5 % shallower;
* the roller leaves no sideways drift: the bar is mirror-symmetric, its x-momentum stays at
  round-off.
"""
import json
import math

import numpy as np
import pytest

import parmpm
from parmpm.output.metrics import make_metrics
from parmpm.output.metrics.bars import first_peak_and_rebound

from studies import fe_bar

QUIET = ["output.snapshots=false", "output.figure=false"]
CLAMPED = ["boundary.slip_regions=[]", "boundary.fixed_regions=[{min=[-0.5, 0.0], max=[1.5, 0.2]}]"]
END = 0.12  # s: past the first peak (~0.09 s), before the rebound


@pytest.mark.parametrize("name", ["hanging_bar", "hanging_bar_3d", "hanging_bar_damage"])
def test_builtin_bars_hang_from_a_roller(name):
    data = parmpm.load_scene(name).data
    b = data["boundary"]
    assert b["fixed_regions"] == []
    (roller,) = b["slip_regions"]
    assert roller["normal"] == "y" and roller["min"][1] == 0.0  # every node at y >= 0, y only
    lo, hi = data["bodies"][0]["min"], data["bodies"][0]["max"]
    assert all(r_lo < b_lo and b_hi < r_hi for r_lo, r_hi, b_lo, b_hi in
               zip(roller["min"], roller["max"], lo, hi) if r_lo != 0.0)


def test_clamped_bar_from_the_documented_set_lines():
    data = parmpm.load_scene("hanging_bar", CLAMPED).data
    assert data["boundary"]["slip_regions"] == []
    assert data["boundary"]["fixed_regions"] == [{"min": [-0.5, 0.0], "max": [1.5, 0.2]}]


# --------------------------------------------------------------------------------------------
def test_first_peak_and_rebound_of_a_cosine():
    t = np.linspace(0.0, 1.0, 201)
    u = -(1.0 - np.cos(2 * np.pi * t / 0.4))  # peaks at 0.2 s (-2), rebounds at 0.4 s (0)
    assert first_peak_and_rebound(u) == (40, 80)
    assert first_peak_and_rebound(u[:30]) == (None, None)  # still on the way down
    assert first_peak_and_rebound(u[:45]) == (40, None)  # turned, not yet back up
    assert first_peak_and_rebound(u[:41]) == (None, None)  # the turn has not shown yet
    wiggle = u.copy()
    wiggle[10] += 1e-3 * abs(u[10])  # less than 1 % of the peak: not a turn
    assert first_peak_and_rebound(wiggle) == (40, 80)
    gap = u.copy()
    gap[[5, 60]] = np.nan
    assert first_peak_and_rebound(gap) == (40, 80)
    assert first_peak_and_rebound([]) == (None, None)


def test_metrics_pick_the_bottom_left_particle_and_report_its_history():
    scene = parmpm.load_scene("hanging_bar").spec
    h = 1.0 / 6
    xs, ys = np.meshgrid((np.arange(6) + 0.5) * h, -1.0 + (np.arange(6) + 0.5) * h, indexing="ij")
    x0 = np.stack([xs.ravel(), ys.ravel()], axis=1)
    m = make_metrics(scene, x0, np.ones(x0.shape[0]))
    assert np.allclose(x0[m.corner], [h / 2, -1.0 + h / 2])
    F = np.tile(np.eye(2), (x0.shape[0], 1, 1))
    t = np.linspace(0.0, 0.5, 51)
    for ti in t:
        x = x0.copy()
        x[:, 1] -= 0.5 * (1.0 - np.cos(2 * np.pi * ti / 0.2))
        x[m.corner, 1] -= 0.1 * (1.0 - np.cos(2 * np.pi * ti / 0.2))  # the corner swings more
        m.sample(ti, x, np.zeros_like(x), F, 1)
    r = m.result()
    json.dumps(r, allow_nan=False)
    assert r["corner_particle"] == m.corner
    assert r["corner_first_peak"] == pytest.approx(-1.2)
    assert r["corner_first_peak_time"] == pytest.approx(0.1)
    assert r["corner_rebound"] == pytest.approx(0.0, abs=1e-12)
    assert r["corner_rebound_time"] == pytest.approx(0.2)
    swing = 1.0 - math.cos(2 * math.pi * 0.5 / 0.2)  # 2 at the last sample
    assert r["tip_displacement"] == pytest.approx(-0.5 * swing - 0.1 * swing / 6)  # 6 tip particles


def test_3d_corner_is_the_bottom_corner_on_both_other_axes():
    scene = parmpm.load_scene("hanging_bar_3d").spec
    g = (np.arange(3) + 0.5) / 3
    x0 = np.stack(np.meshgrid(g, g - 1.0, g, indexing="ij"), axis=-1).reshape(-1, 3)
    m = make_metrics(scene, x0, np.ones(x0.shape[0]))
    assert np.allclose(x0[m.corner], [1 / 6, -1 + 1 / 6, 1 / 6])


def test_old_checkpoint_state_without_the_corner_history_restores():
    scene = parmpm.load_scene("hanging_bar").spec
    x0 = np.array([[0.1, -0.9], [0.1, -0.1]])
    m = make_metrics(scene, x0, np.ones(2))
    m.restore({"times": [0.0, 0.1], "tip_history": [0.0, -0.1], "max_stretch_history": [1.0, 1.1],
               "components_history": [1, 1], "separation_time": None, "stretch_at_separation": None})
    m.sample(0.2, x0, np.zeros_like(x0), np.tile(np.eye(2), (2, 1, 1)), 1)
    r = m.result()
    assert r["samples"] == 3 and r["corner_displacement"] == 0.0 and r["corner_first_peak"] is None


# --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def bars(tmp_path_factory):
    """The 2D cpdi bar to END on the roller (as built in) and clamped."""
    d = tmp_path_factory.mktemp("bars")
    common = QUIET + [f"time.end={END}"]
    return {"roller": parmpm.run("hanging_bar", common, out_dir=d / "roller"),
            "clamped": parmpm.run("hanging_bar", common + CLAMPED, out_dir=d / "clamped")}


@pytest.fixture(scope="module")
def fe_reference():
    """Corner-particle peaks of the Q1 bar at 20 × 20 and 40 × 40 elements (roller) and at 20 × 20
    (clamped), sampled at the MPM bottom-left particle's reference position (Δx = 0.1, ppc 3)."""
    point = [(0.1 / 6, -1.0 + 0.1 / 6)]
    out = {}
    for n, support in ((20, "roller"), (40, "roller"), (20, "clamped")):
        t, u, _ = fe_bar.fe_bar(n, END, support, points=point)
        out[(n, support)] = fe_bar.peaks(t, u[:, 0])
    return out


@pytest.mark.slow
def test_fe_reference_is_converged(fe_reference):
    a, b = fe_reference[(20, "roller")]["first_peak"], fe_reference[(40, "roller")]["first_peak"]
    assert abs(a - b) / abs(b) < 1e-3
    assert fe_reference[(40, "roller")]["first_peak_time"] == pytest.approx(0.0900, abs=5e-4)


@pytest.mark.slow
def test_cpdi_bar_first_peak_matches_the_fe_reference(bars, fe_reference):
    for support, n in (("roller", 40), ("clamped", 20)):
        m, ref = bars[support]["metrics"], fe_reference[(n, support)]
        assert m["corner_particle"] == 0
        assert abs(m["corner_first_peak"] / ref["first_peak"] - 1.0) < 0.01, (support, m, ref)
        assert abs(m["corner_first_peak_time"] / ref["first_peak_time"] - 1.0) < 0.04, (support, m, ref)
        assert m["corner_rebound"] is None  # END is before the rebound


@pytest.mark.slow
def test_roller_peak_is_about_5_percent_deeper_than_clamped(bars):
    roller = bars["roller"]["metrics"]["corner_first_peak"]
    clamped = bars["clamped"]["metrics"]["corner_first_peak"]
    assert 0.04 < roller / clamped - 1.0 < 0.07


@pytest.mark.slow
def test_roller_bar_does_not_drift_sideways(bars):
    px, py = bars["roller"]["final"]["momentum"]
    assert abs(px) < 1e-12 * abs(py)
