"""Multi-velocity-field contact (issue 31), each against a closed form or the single-field run:
a block sliding on a fixed block decelerates at μ g (and keeps its speed with μ = 0) with every
interpolator; two disks in a head-on collision first touch when their surfaces meet, not a cell
earlier as in one field, and bounce apart with momentum kept to round-off; two disks in an
oblique frictionless collision keep their tangential velocities (one field halves them); two
spheres in 3D (the bad-input list, the examples and restart: test_contact_scene.py).
"""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from decomposition import world
from parmpm.driver.set_up import set_up


from parmpm import Simulation
from parmpm.scene.load import scene_from_toml

G = 9.81


def run(tmp_path, text: str, name: str) -> list[dict]:
    """Run a scene given as TOML text; its history rows (floats)."""
    sc = scene_from_toml(f'name = "{name}"\n' + text,
                         overrides=["output.snapshots=false", "output.figure=false"])
    Simulation(sc, tmp_path / name, quiet=True).run()
    with open(tmp_path / name / "history.csv") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


# ------------------------------------------------------------------ sliding


def slide_scene(mu: float, interpolator: str = "cpdi") -> str:
    """A 0.2 m x 0.1 m block sliding at 1 m/s on a 0.8 m x 0.1 m block held at its base."""
    return f"""
dim = 2
[grid]
cell_size = 0.02
cells = [50, 20]
[materials.m]
model = "linear_elastic"
density = 1000.0
youngs_modulus = 1e7
poisson_ratio = 0.3
[[bodies]]
shape = "box"
material = "m"
min = [0.1, 0.0]
max = [0.9, 0.1]
[[bodies]]
shape = "box"
material = "m"
min = [0.2, 0.1]
max = [0.4, 0.2]
velocity = [1.0, 0.0]
[method]
interpolator = "{interpolator}"
[boundary]
y_min = "fixed"
[gravity]
g = [0.0, -{G}]
[time]
end = 0.2
[output.history]
every_steps = 10
[contact]
friction = {mu}
"""


def slid(rows) -> tuple[np.ndarray, np.ndarray]:
    """Time and the upper block's speed (its start plus the contact's impulse over its mass)."""
    m = 1000.0 * 0.2 * 0.1
    return (np.array([r["time"] for r in rows]),
            np.array([1.0 + r["contact1.impulse_x"] / m for r in rows]))


@pytest.mark.parametrize("normal, gap", [("gradient", "line"), ("heavy", "line"),
                                         ("separating", "line")])
def test_the_contact_options_slide_a_block_at_mu_g(tmp_path, normal, gap):
    """``[contact] normal`` and ``gap`` other than the defaults, cpdi: the block still slows at
    μ g within 2 % (measured 1.0016, 1.0011, 1.0026 of it). With bspline the line gap brakes it
    by 3–10 % (docs/concepts/contact.md)."""
    rows = run(tmp_path, slide_scene(0.3) + f'normal = "{normal}"\ngap = "{gap}"\n', "slide")
    t, v = slid(rows)
    assert -np.polyfit(t, v, 1)[0] == pytest.approx(0.3 * G, rel=0.02)


@pytest.mark.parametrize("interpolator", ["cpdi", "ugimp", "mpm", "bspline", "cpdi2",
                                          'bspline"\ntransfer = "apic',
                                          'bspline"\ntransfer = "mls'])
def test_block_on_a_fixed_block_decelerates_at_mu_g(tmp_path, interpolator):
    """μ = 0.3: the slope of its speed is −μ g within 2 % (measured 0.9987–1.0011 of it with
    FLIP, 1.0016 with APIC, 1.0006 with MLS); the friction's work is −μ m g times the distance
    slid, within 2 %."""
    rows = run(tmp_path, slide_scene(0.3, interpolator), "slide")
    t, v = slid(rows)
    assert -np.polyfit(t, v, 1)[0] == pytest.approx(0.3 * G, rel=0.02)
    slid_by = 1.0 * t[-1] - 0.5 * 0.3 * G * t[-1] ** 2
    assert rows[-1]["work_contact"] == pytest.approx(-0.3 * 20.0 * G * slid_by, rel=0.02)


def test_block_on_a_block_on_a_wall_and_the_ledger_closes(tmp_path):
    """The lower block held by a "stick" wall instead of the grid face (the walls act on each
    field's grid): the same μ g (measured 0.99999 of it); the energy ledger closes with the
    contact's work in it: the residual and the transfer's share each under 0.5 % of the 10 J
    the block starts with (measured 0.24 % and 0.20 %)."""
    text = slide_scene(0.3).replace('[boundary]\ny_min = "fixed"',
                                    '[[walls]]\nname = "floor"\npoint = [0.0, 0.0]\n'
                                    'normal = [0.0, 1.0]\nfriction = "stick"')
    rows = run(tmp_path, text, "walled")
    t, v = slid(rows)
    assert -np.polyfit(t, v, 1)[0] == pytest.approx(0.3 * G, rel=0.02)
    end = rows[-1]
    assert abs(end["energy_residual"]) < 0.005 * 10.0
    assert abs(end["transfer_dissipation"]) < 0.005 * 10.0


def test_walls_and_fields_over_where_each_field_has_mass_give_every_nodes_bits(monkeypatch):
    """Each contact field's grid update and walls run over the owned nodes of the slots its
    particles reach (elsewhere it has no mass, and a wall skips a massless node), and its
    exchanges over those slots' pairs: against the same steps over every owned node and the
    whole halo plan, the particles and the walls' sums are equal, bit for bit."""
    import decomposition.halo
    import parmpm.step.contact.field_grid

    text = slide_scene(0.3).replace('[boundary]\ny_min = "fixed"',
                                    '[[walls]]\nname = "floor"\npoint = [0.0, 0.0]\n'
                                    'normal = [0.0, 1.0]\nfriction = "stick"')

    def run_steps():
        st = set_up(scene_from_toml('name = "walled"\n' + text), world()).stepper
        g = np.array([0.0, -G, 0.0])
        for k in range(400):
            st.step(5e-5, g, 5e-5 * k)
        return st

    narrowed = run_steps()
    with monkeypatch.context() as m:  # every owned node, the whole plan
        m.setattr(decomposition.halo.HaloPlan, "among", _whole)
        m.setattr(parmpm.step.contact.field_grid, "within", lambda nodes, slots: nodes)
        whole = run_steps()
    assert not narrowed.contact.meet.all()  # some slots hold one field only
    for name in ("x", "v", "F", "stress"):
        assert np.array_equal(getattr(narrowed.P.rows, name), getattr(whole.P.rows, name)), name
    assert np.array_equal(narrowed.walls.sums, whole.walls.sums)
    assert narrowed.walls.sums.any()


def _whole(plan, holding):
    """``plan`` as :meth:`decomposition.HaloPlan.among` would give it with every pair kept."""
    import copy

    sub = copy.copy(plan)
    sub.reached = np.ones(len(holding), bool)
    return sub


def test_frictionless_block_keeps_its_speed(tmp_path):
    """μ = 0: the block slides on at 1 m/s (to 1e-3) and contact takes no energy (0.1 % of
    its kinetic energy)."""
    rows = run(tmp_path, slide_scene(0.0), "glide")
    _, v = slid(rows)
    assert np.abs(v - 1.0).max() < 1e-3
    assert abs(rows[-1]["work_contact"]) < 1e-3 * 10.0


# ------------------------------------------------------------------ disks


def disks_scene(contact: bool, b: float = 0.0, v: float = 0.1, E: float = 1e3, h: float = 0.02,
                end: float = 2.0, seeding: str = "lattice") -> str:
    """Two disks (R = 0.15 m) 0.1 m apart moving at ±v along x, their centres ``b`` apart in
    y; a probe of each disk's mean velocity. ``seeding``: the disks' (the measurements quoted
    below are the lattice's, which these tests keep; issue 40 follows the conforming disks)."""
    return f"""
dim = 2
[grid]
cell_size = {h}
cells = [{round(1 / h)}, {round(1 / h)}]
[materials.m]
model = "neo_hookean"
density = 1000.0
youngs_modulus = {E}
poisson_ratio = 0.3
[[bodies]]
shape = "disk"
material = "m"
center = [0.3, {0.5 - b / 2}]
radius = 0.15
seeding = "{seeding}"
velocity = [{v}, 0.0]
[[bodies]]
shape = "disk"
material = "m"
center = [0.7, {0.5 + b / 2}]
radius = 0.15
seeding = "{seeding}"
velocity = [{-v}, 0.0]
[time]
end = {end}
[output.history]
every_steps = 1
probes = [{{name = "a", body = 0, fields = ["v.x", "v.y"], stats = ["mean"]}},
          {{name = "b", body = 1, fields = ["v.x", "v.y"], stats = ["mean"]}}]
{"[contact]" if contact else ""}
"""


@pytest.fixture(scope="module")
def head_on(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("disks")
    return {c: run(tmp, disks_scene(c), f"disks{int(c)}") for c in (False, True)}


def test_disks_touch_when_their_surfaces_meet(head_on):
    """The surfaces (and the particle domains) meet at t = 0.5 s. With contact the first force
    acts at 0.508 s (measured; the step after); in one field the disks feel each other once
    their supports overlap: their elastic energy rises from 0.343 s, 1.6 cells early."""
    rows = head_on[True]
    first = next(r["time"] for r in rows if r["contact0.force_x"] != 0.0)
    assert 0.49 < first < 0.52
    e0 = rows[0]["kinetic"]
    single = next(r["time"] for r in head_on[False] if r["elastic"] > 1e-3 * e0)
    assert single < 0.4
    assert all(r["elastic"] <= 1e-3 * e0 for r in rows if r["time"] < 0.49)


def test_disks_bounce_apart_keeping_momentum(head_on):
    """They separate (no contact force after 1.31 s, measured) moving apart at equal and
    opposite speeds, 0.088 m/s (restitution 0.88, measured); the total momentum stays at
    round-off (|p| < 1e-12 of one disk's); the energy kept is 0.87 (measured: the contact
    takes 0.014 J of 0.716, the transfer 0.044, the time integrator's residual 0.035 — the
    single field keeps 0.96 but holds the disks together through the nodes they share)."""
    rows = head_on[True]
    end = rows[-1]
    assert end["contact0.force_x"] == 0.0
    m = end["mass"] / 2
    p = np.array([[r["momentum_x"], r["momentum_y"]] for r in rows])
    assert np.abs(p).max() < 1e-12 * m * 0.1
    va, vb = end["a.v.x.mean"], end["b.v.x.mean"]
    assert va < -0.08 and vb > 0.08
    assert va == pytest.approx(-vb, rel=1e-9)
    kept = (end["kinetic"] + end["elastic"]) / rows[0]["kinetic"]
    assert 0.8 < kept <= 1.0


@pytest.mark.slow  # two runs at Δx = 0.01 m through the impact: ~20 s, the fast loop's longest
def test_oblique_frictionless_disks_keep_their_tangential_velocities(tmp_path):
    """Centres 0.15 m apart across the motion: the line of centres at impact is at 30°, and
    each disk's velocity along the contact plane (0.25 m/s) should survive a frictionless
    impact. With contact it is 0.2447 (−2.1 %, measured; asserted 5 %); in one field the
    disks drag each other through the shared nodes to 0.107 (asserted: below 60 %)."""
    phi = math.asin(0.5)
    t = np.array([-math.sin(phi), math.cos(phi)])
    kept = {}
    for c in (False, True):
        end = run(tmp_path, disks_scene(c, b=0.15, v=0.5, E=1e6, h=0.01, end=0.35),
                  f"oblique{int(c)}")[-1]
        assert end.get("contact0.force_x", 0.0) == 0.0  # apart again
        va = np.array([end["a.v.x.mean"], end["a.v.y.mean"]])
        vb = np.array([end["b.v.x.mean"], end["b.v.y.mean"]])
        kept[c] = (va @ t / (-0.5 * math.sin(phi) * -1), vb @ t / (0.5 * math.sin(phi) * -1))
    assert kept[True][0] == pytest.approx(-1.0, rel=0.05)
    assert kept[True][1] == pytest.approx(-1.0, rel=0.05)
    assert abs(kept[False][0]) < 0.6


def turning_line_model(rows, xa0, xb0, mass: float):
    """An independent model of a frictionless oblique impact that lasts: each disk's centre
    moves with its mean velocity (integrated from the history), and the push between them acts
    along the line between the centres as it turns, with the magnitude the run measured.
    Returns the tangential velocity (along the plane at impact) it predicts, over the
    initial, and the force's and the line's mean directions (degrees, weighted by the
    force's size)."""
    t = np.array([r["time"] for r in rows])
    dt = np.diff(t, prepend=0.0)
    va = np.array([[r["a.v.x.mean"], r["a.v.y.mean"]] for r in rows])
    vb = np.array([[r["b.v.x.mean"], r["b.v.y.mean"]] for r in rows])
    force = np.array([[r["contact0.force_x"], r["contact0.force_y"]] for r in rows])
    line = (np.asarray(xb0) + np.cumsum(vb * dt[:, None], axis=0)
            - np.asarray(xa0) - np.cumsum(va * dt[:, None], axis=0))
    line /= np.linalg.norm(line, axis=1)[:, None]
    size = np.linalg.norm(force, axis=1)
    phi = math.asin(0.5)
    tangent = np.array([-math.sin(phi), math.cos(phi)])
    push = ((size * dt)[:, None] * -line).sum(axis=0)  # on disk a, along the turning line
    predicted = (va[0] @ tangent + push @ tangent / mass) / (va[0] @ tangent)
    on = size > 0
    angle = lambda v: np.degrees(np.arctan2(v[:, 1], v[:, 0]))  # noqa: E731
    return (predicted, np.average(angle(-force[on]), weights=size[on]),
            np.average(angle(line[on]), weights=size[on]))


@pytest.mark.slow  # two runs through the impact, conforming disks: ~25 s
def test_an_oblique_impact_that_lasts_follows_the_turning_line_of_centres(tmp_path):
    """The soft disks above, seeded conforming, are in contact for 33 ms, in which they slide
    16 mm past each other and their line of centres turns from 30° to 33°: a frictionless
    push along the turning line gives each 1.086–1.093 of its tangential velocity (the
    independent model, :func:`turning_line_model`), not 1. Measured at Δx = 0.02, 0.01,
    0.005 m: kept 1.0576, 1.0752, 1.0833 against the model's 1.0862, 1.0913, 1.0926 (2.6 %,
    1.5 %, 0.85 % short), the force's mean direction 0.50°, 0.28°, 0.16° behind the line's.
    Asserted at 0.02 and 0.01 m: within 3 % and 2 % of the model, closer when refined, and the
    force within 0.6° and 0.35° of the line."""
    gaps, lags = [], []
    for h, within, lag in ((0.02, 0.03, 0.6), (0.01, 0.02, 0.35)):
        rows = run(tmp_path, disks_scene(True, b=0.15, v=0.5, E=1e6, h=h, end=0.35,
                                         seeding="conforming"), f"turning{h}")
        phi = math.asin(0.5)
        tangent = np.array([-math.sin(phi), math.cos(phi)])
        end = rows[-1]
        kept = np.array([end["a.v.x.mean"], end["a.v.y.mean"]]) @ tangent / (0.5 * tangent[0])
        model, force_angle, line_angle = turning_line_model(
            rows, (0.3, 0.425), (0.7, 0.575), 1000.0 * math.pi * 0.15 ** 2)
        assert model > 1.08  # the physics: the line turns, the tangential velocity grows
        gaps.append(abs(kept / model - 1.0))
        lags.append(line_angle - force_angle)
        assert gaps[-1] < within and 0.0 <= lags[-1] < lag, (h, kept, model, lags[-1])
    assert gaps[1] < gaps[0] and lags[1] < lags[0]


@pytest.mark.parametrize("interpolator", ["cpdi", "ugimp", "bspline"])
def test_bars_in_1d_touch_for_two_wave_transits(tmp_path, interpolator):
    """Two equal elastic bars (L = 0.3 m, c = 1 m/s) meeting at ±0.1 m/s at t = 0.5 s stay in
    contact for exactly 2L/c = 0.6 s (the compression wave's round trip; a closed form for the
    1D elastic impact): the first force acts at 0.509 s (the step after), the last at 1.111
    (cpdi), 1.115 (ugimp), 1.116 s (bspline), measured; asserted to 0.02 s. Momentum stays at
    round-off and the bars move apart."""
    text = f"""
dim = 1
[grid]
cell_size = 0.02
cells = 50
[materials.m]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1e3
poisson_ratio = 0.0
[[bodies]]
min = 0.1
max = 0.4
material = "m"
velocity = 0.1
[[bodies]]
min = 0.5
max = 0.8
material = "m"
velocity = -0.1
[method]
interpolator = "{interpolator}"
[time]
end = 2.5
[output.history]
every_steps = 1
[contact]
"""
    rows = run(tmp_path, text, "bars")
    touching = [r["time"] for r in rows if r["contact0.force_x"] != 0.0]
    assert touching[0] == pytest.approx(0.5, abs=0.02)
    assert touching[-1] == pytest.approx(1.1, abs=0.02)
    m = rows[-1]["mass"] / 2
    assert max(abs(r["momentum_x"]) for r in rows) < 1e-12 * m * 0.1
    assert 0.1 + rows[-1]["contact0.impulse_x"] / m < -0.08


def test_spheres_collide_in_3d(tmp_path):
    """Two spheres (R = 0.1 m, 0.1 m apart, ±0.1 m/s): no force before their domains meet at
    0.5 s, momentum kept to round-off, and they bounce apart."""
    text = """
dim = 3
[grid]
cell_size = 0.05
cells = [16, 8, 8]
[materials.m]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1e3
poisson_ratio = 0.3
[[bodies]]
shape = "sphere"
material = "m"
center = [0.25, 0.2, 0.2]
radius = 0.1
velocity = [0.1, 0.0, 0.0]
[[bodies]]
shape = "sphere"
material = "m"
center = [0.55, 0.2, 0.2]
radius = 0.1
velocity = [-0.1, 0.0, 0.0]
[time]
end = 1.5
[output.history]
every_steps = 1
[contact]
"""
    rows = run(tmp_path, text, "spheres")
    first = next(r["time"] for r in rows if r["contact0.force_x"] != 0.0)
    assert 0.45 < first < 0.55
    m = rows[-1]["mass"] / 2
    p = np.array([[r[f"momentum_{a}"] for a in "xyz"] for r in rows])
    assert np.abs(p).max() < 1e-12 * m * 0.1
    end = rows[-1]
    assert end["contact0.force_x"] == 0.0
    assert 0.1 + end["contact0.impulse_x"] / m < -0.05  # moving back


#: a valid contact scene (two disks, μ = 0.3) for the bad-input list (test_contact_scene.py)
BASE_SCENE = disks_scene(True, end=0.01).replace("[contact]", "[contact]\nfriction = 0.3")


# ------------------------------------------------------------------ a mirror face
PAIR = """
name = "pair"
dim = 2
[grid]
origin = [{x0}, 0.0]
cell_size = 0.02
cells = [{nx}, 15]
patch_size = 5
[materials.m]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
[[bodies]]
min = [{lo}, 0.0]
max = [0.4, 0.1]
material = "m"
[[bodies]]
min = [{up}, 0.1]
max = [0.2, 0.2]
material = "m"
velocity = [0.0, -0.5]
velocity_gradient = [[0.5, 0.0], [0.0, 0.0]]
[boundary]
x_min = "{x_min}"
y_min = "fixed"
[gravity]
g = [0.0, -9.81]
[time]
steps = 10
[output]
snapshots = false
figure = false
[contact]
friction = 0.3
"""


def _by_place(P):
    """The particle fields in reference-position order (x, then y; rounded: the whole's lattice
    is seeded from another origin, its coordinates a last bit off the half's)."""
    key = np.round(P.x0, 9)
    order = np.lexsort((key[:, 1], key[:, 0]))
    return {k: getattr(P, k)[order] for k in ("x0", "x", "v", "stress")}


def test_a_half_pair_on_a_mirror_face_touches_as_the_whole():
    """Two blocks, the upper thrown down onto the lower and spreading (v_x odd in x), μ = 0.3:
    the right halves on a symmetry face at x = 0 move exactly as the x > 0 half of the whole
    pair to round-off (the sums are added in another order: measured 3e-14 m/s), through the
    impact: the contact's first moments are folded with the images' (their reflected
    positions), and after the correction the nodes beyond the face take their twins'
    reflection again. Measured without the fold: 0.04 m/s off by step 60 (the normals at the face
    nodes lean); without the reflection: 4e-6 m/s (the nodes beyond, which no real particle's
    column reaches, went uncorrected)."""
    def state(half):
        text = PAIR.format(x0=0.0 if half else -0.5, nx=25 if half else 50,
                           lo=0.0 if half else -0.4, up=0.0 if half else -0.2,
                           x_min="symmetry" if half else "free")
        if half:  # the half's centre is at x = 0.1: the gradient's field about x = 0 there
            text = text.replace("velocity = [0.0, -0.5]", "velocity = [0.05, -0.5]")
        return set_up(scene_from_toml(text, "<pair>"), world())

    whole, half = state(False), state(True)
    g = np.array([0.0, -9.81, 0.0])
    for s in (whole, half):
        for n in range(60):
            s.stepper.step(2e-4, g, n * 2e-4)
    W, H = _by_place(whole.particles), _by_place(half.particles)
    right = W["x0"][:, 0] > 0
    np.testing.assert_allclose(W["x0"][right], H["x0"], rtol=0, atol=1e-12)
    assert np.abs(H["v"][:, 1]).max() > 0.1  # the impact is under way
    for k, scale in (("x", 1.0), ("v", 1.0), ("stress", 1e6)):
        np.testing.assert_allclose(H[k], W[k][right], rtol=0, atol=1e-11 * scale, err_msg=k)
