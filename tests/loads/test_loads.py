"""External loads and their time functions (issue 30), each against a closed form: the time
functions' integrals, a bar pulled by an end traction, a box under pressure on every face, a point
load's and a body force's momentum, and the Kirsch plate with a hole. The scene runner and the
shared material are :mod:`test_walls`'s."""
from __future__ import annotations

import numpy as np
import pytest

from parmpm import Simulation
from parmpm.loads.time_functions import TimeFunction
from parmpm.scene.load import scene_from_toml
from test_walls import MATERIAL, last_snapshot, run

# ------------------------------------------------------------------ time functions

@pytest.mark.parametrize("tf", [
    TimeFunction(), TimeFunction("ramp", 0.3), TimeFunction("smooth_step", 0.3),
    TimeFunction("table", points=((0.0, 0.5), (0.1, 1.0), (0.4, -1.0), (0.5, 2.0))),
    TimeFunction("table", points=((0.2, 1.0), (0.3, 3.0))),
])
def test_time_function_integral_is_the_integral_of_its_value(tf):
    """The closed-form integral against a fine trapezoid sum of the values."""
    t = np.linspace(0.0, 0.8, 160_001)
    f = np.array([tf.value(s) for s in t])
    numeric = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(t))])
    for k in (0, 1000, 37_123, 80_000, 160_000):
        assert tf.integral(t[k]) == pytest.approx(numeric[k], abs=1e-8)


def test_time_function_values():
    assert TimeFunction("ramp", 2.0).value(1.0) == 0.5
    assert TimeFunction("ramp", 2.0).value(5.0) == 1.0
    s = TimeFunction("smooth_step", 1.0)
    assert (s.value(0.0), s.value(0.5), s.value(1.0), s.value(9.0)) == (0.0, 0.5, 1.0, 1.0)
    tab = TimeFunction("table", points=((1.0, 2.0), (3.0, 4.0)))
    assert (tab.value(0.0), tab.value(2.0), tab.value(7.0)) == (2.0, 3.0, 4.0)


# ------------------------------------------------------------------ loads

def bar_scene(load: str, end: float = 0.3, boundary: str = 'x_min = "slip"',
              damping: float = 30.0) -> str:
    return f"""
dim = 2
[grid]
cell_size = 0.05
cells = [24, 8]
[boundary]
{boundary}
[materials.rock]
model = "linear_elastic"
density = 1000.0
youngs_modulus = 1e6
poisson_ratio = 0.0
[[bodies]]
shape = "box"
material = "rock"
ppc = 2
min = [0.0, 0.1]
max = [1.0, 0.3]
{load}
[damping]
coefficient = {damping}
[time]
end = {end}
[output.history]
every_steps = 20
probes = [{{name = "tip", point = [0.99, 0.2], fields = ["u.x"]}},
          {{name = "mid", region = {{min = [0.4, 0.0], max = [0.6, 1.0]}}, field = "stress.xx", stats = ["mean"]}}]
"""


def test_end_traction_stretches_a_bar_by_sigma_l_over_e(tmp_path):
    """Traction 1e4 Pa on the end face (smooth step over 0.1 s, damped): σ_xx = 1e4 Pa inside,
    u(x) = σ x / E at the tip particle (x = 0.9875 m); the load's work less what the bar holds
    and damping took is small (the ledger closes to the load work's particle estimate)."""
    rows = run(tmp_path, bar_scene("""
[[loads]]
kind = "traction"
body = 0
region = {min = [0.99, 0.0], max = [1.1, 1.0]}
value = [1e4, 0.0]
time = {function = "smooth_step", duration = 0.1}
"""), "trac")
    last = rows[-1]
    assert last["mid.stress.xx.mean"] == pytest.approx(1e4, rel=0.01)
    assert last["tip.u.x"] == pytest.approx(1e4 * 0.9875 / 1e6, rel=0.02)
    held = last["elastic"] + last["kinetic"] + last["damping_dissipation"]
    assert last["work_loads"] == pytest.approx(held, rel=0.05)


def test_pressure_on_every_face_compresses_a_box_evenly(tmp_path):
    """A pressure p on every face of a free box (no gravity): σ_xx = σ_yy = −p a cell inside the
    surface (the load acts at the surface particles' centres, so the stress of the outer cell's
    particles is partial: docs/concepts/loads.md), and no net force."""
    text = bar_scene("""
[[loads]]
kind = "pressure"
body = 0
pressure = 5e3
time = {function = "smooth_step", duration = 0.1}
""", boundary="")
    text = text.replace('probes = [{name = "tip", point = [0.99, 0.2], fields = ["u.x"]},',
                        'probes = [{name = "yy", region = {min = [0.4, 0.16], max = [0.6, 0.24]}, '
                        'field = "stress.yy", stats = ["mean"]},')
    last = run(tmp_path, text, "pressure")[-1]
    assert last["mid.stress.xx.mean"] == pytest.approx(-5e3, rel=0.01)
    assert last["yy.stress.yy.mean"] == pytest.approx(-5e3, rel=0.01)
    assert abs(last["momentum_x"]) < 1e-6 and abs(last["momentum_y"]) < 1e-6


@pytest.mark.parametrize("load, momentum", [
    # a point force of 3 N ramped over 0.05 s: momentum F ∫f = 3 (0.1 − 0.025)
    ('kind = "point"\nat = [0.5, 0.2]\nvalue = [3.0, 0.0]\n'
     'time = {function = "ramp", duration = 0.05}', 3.0 * 0.075),
    # a body force of 2 m/s² on the first of two bodies (200 kg): 2·200·0.1
    ('kind = "body_force"\nbody = 0\nvalue = [2.0, 0.0]', 2.0 * 200.0 * 0.1),
])
def test_a_loads_impulse_is_its_force_times_its_time_integral(tmp_path, load, momentum):
    text = bar_scene(f"[[loads]]\n{load}\n", end=0.1, boundary="", damping=0.0) + """
[[bodies]]
shape = "box"
material = "rock"
ppc = 2
min = [0.0, 0.32]
max = [1.0, 0.38]
"""
    last = run(tmp_path, text, "impulse")[-1]
    assert last["time"] == pytest.approx(0.1)
    assert last["momentum_x"] == pytest.approx(momentum, rel=1e-5)
    assert abs(last["momentum_y"]) < 1e-9 * momentum


def kirsch_scene(h: float) -> str:
    n = int(round(0.6 / h))
    return f"""
dim = 2
[grid]
cell_size = {h}
cells = [{n}, {n}]
[boundary]
x_min = "symmetry"
y_min = "symmetry"
{MATERIAL}
[[bodies]]
shape = "difference"
material = "rock"
ppc = 2
parts = [{{shape = "box", min = [0.0, 0.0], max = [0.6, 0.6]}},
         {{shape = "disk", center = [0.0, 0.0], radius = 0.1}}]
[[loads]]
kind = "traction"
body = 0
region = {{min = [0.59, 0.0], max = [0.61, 0.6]}}
normal = [1.0, 0.0]
value = [1e3, 0.0]
time = {{function = "smooth_step", duration = 0.1}}
[damping]
coefficient = 40.0
[time]
end = 0.4
[output]
every = 0.4
history = false
"""


def test_kirsch_hole_concentrates_stress_three_times(tmp_path):
    """A quarter plate (0.6 m, symmetry faces) with a hole of radius a = 0.1 m pulled by 1 kPa:
    the particle nearest the hole's top (θ = 90°) carries σ_xx → 3σ∞ (Kirsch 1898), within
    10 % at Δx = a/8 and closer than at Δx = a/4; each is within 5 % of Kirsch's σ_xx at its own
    radius, 1 + a²/2r² + 3a⁴/2r⁴; far from the hole, and a cell in from the loaded edge (whose
    particles carry part of the load: docs/concepts/loads.md), σ_xx = σ∞ to 1 %. Without
    ``normal`` the region also took the two corner faces on the symmetry line: 4.2 % (a/4) and
    2.1 % (a/8) more load, σ_xx = 1.042 and 1.021 σ∞ there (issue 41)."""
    a, errors = 0.1, []
    for h in (0.025, 0.0125):
        sc = scene_from_toml(f'name = "k{h}"\n' + kirsch_scene(h), overrides=["output.figure=false"])
        Simulation(sc, tmp_path / f"k{h}", quiet=True).run()
        s = last_snapshot(tmp_path / f"k{h}")
        x, sxx = s["x"][:, :2], s["stress"][:, 0] / 1e3
        r = np.hypot(x[:, 0], x[:, 1])
        top = np.flatnonzero(x[:, 0] < h / 2)
        i = top[np.argmin(r[top])]
        q = (a / r[i]) ** 2
        assert sxx[i] == pytest.approx(1 + q / 2 + 1.5 * q * q, rel=0.05)
        errors.append(abs(sxx[i] - 3.0) / 3.0)
        far = (x[:, 0] > 0.45) & (x[:, 0] < 0.6 - h)
        assert np.mean(sxx[far]) == pytest.approx(1.0, rel=0.01)
    assert errors[1] < 0.10
    assert errors[1] < errors[0]


# ------------------------------------------------------------------ which faces a load takes

def pulled_block(h: float, extra: str = "", region: str = "[0.69, 0.19], max = [0.71, 0.41]",
                 body: str = 'shape = "box"\nmin = [0.3, 0.2]\nmax = [0.7, 0.4]') -> str:
    """A free 0.4 x 0.2 m block (no gravity, no damping) pulled by 1 kPa on its right face,
    the region drawn around that face as the docs' examples drew it (issue 41)."""
    n = int(round(1.0 / h))
    return f"""
dim = 2
[grid]
cell_size = {h}
cells = [{n}, {n // 2 + 2}]
{MATERIAL}
[[bodies]]
{body}
material = "rock"
ppc = 2
[[loads]]
kind = "traction"
body = 0
region = {{min = {region}}}
value = [1e3, 0.0]
{extra}
[time]
end = 0.05
[output.history]
every_steps = 1000000
"""


@pytest.mark.parametrize("h, extra", [(0.04, 0.2), (0.02, 0.1), (0.01, 0.1)])
def test_a_traction_with_normal_loads_exactly_the_face_meant(tmp_path, h, extra):
    """The traction bar (issue 41): with ``normal = [1, 0]`` the block gains momentum
    t x 0.2 m x 0.05 s = 10 N s, to rounding, at every resolution; without it the top and
    bottom faces of the corner particles in the region (1, 1, 2 columns of Δx/2 at x ≥ 0.69)
    are pulled too: ``extra`` more."""
    exact = 1e3 * 0.2 * 0.05
    with_normal = run(tmp_path, pulled_block(h, "normal = [1.0, 0.0]"), "n")[-1]
    assert with_normal["time"] == pytest.approx(0.05)
    assert with_normal["momentum_x"] == pytest.approx(exact, rel=1e-6)
    assert abs(with_normal["momentum_y"]) < 1e-9 * exact
    without = run(tmp_path, pulled_block(h), "w")[-1]
    assert without["momentum_x"] == pytest.approx(exact * (1 + extra), rel=1e-6)


def test_a_region_holding_faces_facing_several_ways_is_one_warning(tmp_path, caplog):
    """The corner faces are named: counts and lengths per direction, and the normal that keeps
    the largest; with ``normal`` (or a region that holds only the face) no warning."""
    warnings = []
    for name, extra, region in (("w", "", "[0.69, 0.19], max = [0.71, 0.41]"),
                                ("n", "normal = [1.0, 0.0]", "[0.69, 0.19], max = [0.71, 0.41]"),
                                ("r", "", "[0.69, 0.201], max = [0.71, 0.399]")):
        caplog.clear()
        with caplog.at_level("WARNING"):
            run(tmp_path, pulled_block(0.02, extra, region).replace("0.05", "0.001"), name)
        warnings.append([r.getMessage() for r in caplog.records if "loads.0" in r.getMessage()])
    assert warnings[0] == [
        "loads.0: the traction's region holds faces facing 3 ways: 20 facing +x (0.2 m), "
        "1 facing -y (0.01 m), 1 facing +y (0.01 m); each is loaded (add normal = [1, 0] to "
        "load only the faces facing +x)"]
    assert warnings[1] == warnings[2] == []


@pytest.mark.parametrize("at, said", [
    ("[0.7, 0.4]", None),   # the block's corner: its corner particle, 0.0071 m away
    ("[0.1, 0.1]", "loads.0: the point load's nearest particle (id 0) is 0.2303 m from "
                   "at = [0.1, 0.1], more than a cell (0.02 m): the force acts there"),
])
def test_a_point_load_far_from_every_particle_is_one_warning(tmp_path, caplog, at, said):
    """Issue 41: the nearest particle more than a cell from ``at`` is named with its distance
    (outside the grid it is an error: tests/scene/test_bad_inputs.py)."""
    text = pulled_block(0.02).replace("0.05", "0.001")
    text = text[:text.index("[[loads]]")] + (
        f'[[loads]]\nkind = "point"\nat = {at}\nvalue = [1.0, 0.0]\n'
        + text[text.index("[time]"):])
    with caplog.at_level("WARNING"):
        run(tmp_path, text, "point")
    lines = [r.getMessage() for r in caplog.records if "loads.0" in r.getMessage()]
    assert lines == ([] if said is None else [said])
