"""Seeding (:mod:`parmpm.particles.seeding`): bodies made block by block (a box's lattice kept axis by
axis, a turned box turned block by block, a disk or sphere masked block by block) give the same
points, bit for bit, the same particles per patch and the same members of a rank's patches as
seeding every particle at once and locating each one — what lets set-up skip holding every
position."""
from __future__ import annotations

import numpy as np
import pytest

from parmpm import Simulation, load_scene
from parmpm.materials import material_table
from parmpm.particles.locate import locate_patches
from parmpm.particles import seeding
from parmpm.geometry.primitives import turn as _turn
from parmpm.particles.seeding import _ball, _Lattice, _lattice, _Turned, seed_bodies


def test_lattice_points_are_the_meshgrid_points():
    lo, h, n = np.array([0.1, -0.3, 0.2]), np.array([0.05, 0.025, 0.1]), [7, 5, 3]
    lat = _Lattice(lo, h, n)
    full = _lattice(lo, lo + np.array(n) * h, h)
    assert np.array_equal(lat.full(), full)
    ids = np.array([0, 6, 7, 34, 104])
    assert np.array_equal(lat[ids], full[ids])


CASES = [
    ("tension_bar", ["metrics.kind=none", "grid.patch_size=[5, 3]", "grid.origin=[-0.6013, -0.1071]"]),
    ("hanging_bar_3d", ["metrics.kind=none", "grid.patch_size=3"]),
    ("hanging_bar_1d", ["metrics.kind=none", "grid.patch_size=4"]),
    ("tension_bar", ["bodies.2.angle=10.0", "bodies.0.angle=-3.0", "grid.patch_size=[5, 3]"]),
    ("spinning_disk", ["grid.patch_size=5"]),
    ("hanging_bar_3d", ["bodies.0={shape='sphere', center=[0.5, -0.5, 0.5], radius=0.45, "
                        "material='bar', ppc=3}", "grid.patch_size=3"]),
    ("manufactured", ["grid.patch_size=3"]),
]


@pytest.mark.parametrize("block", [seeding.BLOCK, 32])
@pytest.mark.parametrize("scene, over", CASES)
def test_counts_and_members_match_locating_every_particle(scene, over, block, tmp_path,
                                                         monkeypatch):
    monkeypatch.setattr(seeding, "BLOCK", block)
    sc = load_scene(scene, over)
    sim = Simulation(sc, tmp_path, quiet=True)  # for its discretisation
    D, lay = sim.state.disc, sim.state.disc.layout
    _, names = material_table(sc.spec.materials)
    seeds = seed_bodies(sc.spec.grid, sc.spec.bodies, {n: i for i, n in enumerate(names)})
    x = seeds.x
    if sc.data.get("manufactured"):  # the particles start displaced: found where they start
        seeds.motion = lambda X: X + 0.01 * np.sin(7.0 * X)
        x = seeds.motion(x)
    where = np.zeros(len(x), np.int64)
    bad, _ = locate_patches(sc.dim, x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                            lay.patches_per_axis, where, where)
    assert bad < 0
    counts = seeds.patch_counts(D)
    assert np.array_equal(counts, np.bincount(where, minlength=lay.n_patches))
    owned = np.random.default_rng(1).random(lay.n_patches) < 0.4
    mine = seeds.members(D, owned)
    assert np.array_equal(mine, np.flatnonzero(owned[where]))
    params, _ = material_table(sc.spec.materials)
    np.testing.assert_array_equal(seeds.particles(params, mine).x0, seeds.x[mine])


@pytest.mark.parametrize("block", [16, 48, 4096])
@pytest.mark.parametrize("d, count", [(2, (37, 23)), (2, (64, 1)), (3, (9, 7, 5)), (2, (1, 1))])
def test_turned_blocks_are_the_whole_body_turned(d, count, block, monkeypatch):
    """Turned block by block (aligned blocks, a short last one joined to the one before), every
    point has the bits of the whole body turned in one BLAS call."""
    monkeypatch.setattr(seeding, "BLOCK", block)
    lo, h = np.array([0.1, -0.3, 0.2])[:d], np.array([0.05, 0.025, 0.1])[:d]
    lat = _Lattice(lo, h, count)
    mid, turn = lo + 0.5 * np.array(count) * h, _turn(d, 23.0)
    whole = (lat.full() - mid) @ turn.T + mid
    body = _Turned(lat, mid, turn)
    assert np.array_equal(body.points(np.arange(lat.n)), whole)
    ids = np.sort(np.random.default_rng(2).choice(lat.n, lat.n // 3 + 1, replace=False))
    assert np.array_equal(body.points(ids), whole[ids])


@pytest.mark.parametrize("block", [32, 4096])
def test_ball_is_its_box_lattice_masked(block, monkeypatch):
    monkeypatch.setattr(seeding, "BLOCK", block)
    for d in (2, 3):
        lo, h, n = np.full(d, -0.61), np.full(d, 0.05), [27, 25, 24][:d]
        c, r = np.array([0.02, -0.01, 0.03])[:d], 0.55
        lat = _Lattice(lo, h, n)
        full = _lattice(lo, lo + np.array(n) * h, h)
        ball = _ball(lat, c, r)
        expect = full[np.sum((full - c) ** 2, axis=1) <= r * r]
        assert len(ball) == expect.shape[0]
        assert np.array_equal(ball.points(np.arange(len(ball))), expect)
        ids = np.array([0, 5, len(ball) // 2, len(ball) - 1])
        assert np.array_equal(ball.points(ids), expect[ids])


def test_outside_the_grid_names_the_particle(tmp_path):
    from parmpm.core.errors import SimulationError

    sc = load_scene("spinning_disk", ["grid.patch_size=6"])
    D = Simulation(sc, tmp_path, quiet=True).state.disc
    seeds = seed_bodies(sc.spec.grid, sc.spec.bodies, {"disk": 0})
    seeds.motion = lambda X: X + np.where(np.arange(len(X))[:, None] == 7, 5.0, 0.0)
    with pytest.raises(SimulationError, match=r"particle 7 at \(.*\) is outside the grid"):
        seeds.patch_counts(D)


# --- issue 28: overlapping bodies are seeded twice, and say so --------------------------------
OVERLAP_BASE = """
dim = {dim}
[grid]
origin = {origin}
cell_size = 0.25
cells = {cells}
[materials.steel]
model = "linear_elastic"
density = 1000.0
youngs_modulus = 1e6
poisson_ratio = 0.3
[materials.rubber]
model = "linear_elastic"
density = 500.0
youngs_modulus = 1e5
poisson_ratio = 0.3
[time]
end = 1.0
steps = 1
[output]
snapshots = false
figure = false
history = false
[metrics]
kind = "none"
[checkpoint]
at_end = false
"""


def _box(lo, hi, material="steel", ppc=2, angle=None):
    turn = f"\nangle = {angle}" if angle is not None else ""
    return (f'\n[[bodies]]\nshape = "box"\nmin = {list(lo)}\nmax = {list(hi)}\n'
            f'material = "{material}"\nppc = {ppc}{turn}\n')


def _disk(c, r, material="steel", ppc=2):
    return (f'\n[[bodies]]\nshape = "disk"\ncenter = {list(c)}\nradius = {r}\n'
            f'material = "{material}"\nppc = {ppc}\n')


def _overlap_scene(tmp_path, dim, bodies, cells=None):
    cells = cells or [16, 8, 8][:dim]
    text = OVERLAP_BASE.format(dim=dim, origin=[0.0] * dim, cells=cells) + "".join(bodies)
    path = tmp_path / "overlap.toml"
    path.write_text(text)
    return path


def _seeded_twice(path):
    from parmpm.scene.overlaps import seeded_twice

    scene = load_scene(path)
    data, spec = scene.data, scene.spec
    names = material_table(spec.materials)[1]
    seeds = seed_bodies(spec.grid, spec.bodies, {n: i for i, n in enumerate(names)})
    return seeded_twice(None, spec, seeds, np.arange(seeds.n), seeds.x), data, seeds


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_two_overlapping_boxes_report_the_closed_form_overlap(tmp_path, dim):
    """Boxes [0, 2]×[0, 1]^(d-1) and [1.25, 3]×[0.5, 1.5]^(d-1): their overlap is
    0.75 · 0.5^(d-1), and the later box's particles inside the first weigh ρ times that.
    Before: nothing said (the particles seeded twice, silently)."""
    a = _box([0.0] + [0.0] * (dim - 1), [2.0] + [1.0] * (dim - 1))
    b = _box([1.25] + [0.5] * (dim - 1), [3.0] + [1.5] * (dim - 1))
    found, data, seeds = _seeded_twice(_overlap_scene(tmp_path, dim, [a, b]))
    exact = 0.75 * 0.5 ** (dim - 1)
    assert len(found) == 1 and found[0]["bodies"] == (0, 1)
    assert found[0]["volume"] == pytest.approx(exact, rel=1e-12)
    assert found[0]["mass"] == pytest.approx(1000.0 * exact, rel=1e-12)
    # what was seeded twice is exactly the excess over the union's mass (2 + 1.75 − overlap)
    names = sorted(data["materials"])  # material_table's row order
    params = np.zeros((len(names), 2))
    params[:, 1] = [data["materials"][n]["density"] for n in names]
    excess = seeds.mass(params).sum() - 1000.0 * (2.0 + 1.75 - exact)
    assert excess == pytest.approx(found[0]["mass"], rel=1e-9)


def test_box_and_disk_overlap_is_the_half_disk(tmp_path):
    """A disk of radius 0.5 centred on the box's right edge: the half disk, π r²/2, inside the
    box (the disk's lattice estimates it to the particle spacing: within 2 %)."""
    found, _, _ = _seeded_twice(_overlap_scene(
        tmp_path, 2, [_box([0.0, 0.0], [2.0, 1.0]), _disk([2.0, 0.5], 0.5, "rubber", ppc=8)]))
    assert [o["bodies"] for o in found] == [(0, 1)]
    assert found[0]["volume"] == pytest.approx(np.pi * 0.25 / 2, rel=0.02)
    assert found[0]["mass"] == pytest.approx(500.0 * found[0]["volume"], rel=1e-12)


def test_a_turned_box_holding_a_small_box_reports_the_small_box(tmp_path):
    """A box turned by 30° that holds all of a small box: the overlap is the small box."""
    big = _box([1.0, 0.5], [3.0, 1.5], angle=30.0)
    small = _box([1.75, 0.75], [2.25, 1.25])
    found, _, _ = _seeded_twice(_overlap_scene(tmp_path, 2, [big, small]))
    assert len(found) == 1 and found[0]["volume"] == pytest.approx(0.25, rel=1e-12)


def test_touching_and_distant_bodies_say_nothing(tmp_path):
    """Boxes sharing a face, a disk touching a box, and a disk inside a box's bounds but
    outside it (a turned box's corner): no particle seeded twice."""
    bodies = [_box([0.0, 0.0], [1.0, 1.0]), _box([1.0, 0.0], [2.0, 1.0]),
              _disk([2.5, 0.5], 0.5), _box([3.0, 0.0], [4.0, 2.0])]
    found, _, _ = _seeded_twice(_overlap_scene(tmp_path, 2, bodies))
    assert found == []


def test_an_overlapping_scene_warns_once_naming_the_bodies(tmp_path, caplog):
    """The run's set-up warns, one line per pair, on rank 0."""
    path = _overlap_scene(tmp_path, 2, [_box([0.0, 0.0], [2.0, 1.0]),
                                         _box([1.0, 0.0], [3.0, 1.0])])
    with caplog.at_level("WARNING", logger="parmpm"):
        Simulation(load_scene(path), tmp_path / "out", quiet=True).run()
    lines = [r.getMessage() for r in caplog.records if "overlap" in r.getMessage()]
    assert lines == ["bodies.0 and bodies.1 overlap: 1 m² of bodies.1 (64 particles, 1000 kg) "
                     "lies inside bodies.0 and is seeded twice (the scene holds that material "
                     "twice; make the bodies touch, not overlap)"]


def test_an_overlapping_scene_warns_once_on_two_ranks(tmp_path, mpirun):
    """Under two ranks (each counting its own particles) the same line, printed once."""
    import subprocess
    import sys

    path = _overlap_scene(tmp_path, 2, [_box([0.0, 0.0], [2.0, 1.0]),
                                         _box([1.0, 0.0], [3.0, 1.0]), _disk([3.0, 0.5], 0.5)])
    proc = subprocess.run([mpirun, "-n", "2", sys.executable, "-m", "parmpm", "run", str(path),
                           "--out", str(tmp_path / "o"), "-q", "--set", "grid.patch_size=4"],
                          capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    found, _, _ = _seeded_twice(path)
    assert len(found) == 2
    for o in found:
        (i, j) = o["bodies"]
        hits = [ln for ln in proc.stderr.splitlines() if f"bodies.{i} and bodies.{j} overlap" in ln]
        assert len(hits) == 1 and f"({o['particles']} particles" in hits[0], proc.stderr
