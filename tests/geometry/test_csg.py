"""CSG bodies (:mod:`parmpm.geometry.csg`, :mod:`parmpm.scene.parts`): union, difference and
intersection of boxes, disks, spheres, cylinders, polygons and half-spaces.

Each against an independent result: inside tests at hand-computed points; the seeded mass,
centroid and second moments of an annulus against the analytic annulus as the lattice is refined
(the error bounded by the lattice's surface error, perimeter × spacing); a plate with a hole and
two overlapping disks against their analytic areas (the overlap seeded once); a rank's particles
(counted, found and built per patch, O(N/P)) against locating every particle; every bad part a
one-line error naming its full key.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from parmpm import Simulation
from parmpm.core.errors import SceneError
from parmpm.geometry import csg
from parmpm.particles import seeding
from parmpm.particles.locate import locate_patches
from parmpm.particles.seeding import seed_bodies
from parmpm.scene.load import load_scene, scene_from_toml
from parmpm.scene.records import Part, build
from parmpm.transfer.discretisation import Discretisation

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "plate_with_hole.toml"
RHO = 1000.0


def part(parts=None, **kw) -> Part:
    """A part record; ``parts``: records already."""
    p = build(Part, kw)
    return dataclasses.replace(p, parts=tuple(parts)) if parts else p


BOX = part(shape="box", min=[0.0, 0.0], max=[2.0, 1.0])
DISK = part(shape="disk", center=[1.0, 0.5], radius=0.25)


# --- inside tests at hand-computed points --------------------------------------------------------
@pytest.mark.parametrize("shape, dim, inside, outside", [
    (BOX, 2, [[0.1, 0.1], [1.9, 0.9]], [[2.1, 0.5], [1.0, 1.0], [-0.01, 0.5]]),
    (part(shape="box", min=[0.0, 0.0], max=[2.0, 1.0], angle=90.0), 2,  # turned: 1 wide, 2 tall
     [[1.0, 1.4], [1.4, -0.4]], [[0.1, 0.5], [1.9, 0.5]]),
    (DISK, 2, [[1.0, 0.5], [1.24, 0.5]], [[1.26, 0.5], [1.2, 0.7]]),
    (part(shape="sphere", center=[0.0, 0.0, 0.0], radius=1.0), 3, [[0.5, 0.5, 0.5]],
     [[0.6, 0.6, 0.6]]),
    (part(shape="cylinder", axis="y", center=[0.0, 1.0, 0.0], radius=0.5, length=2.0), 3,
     [[0.3, 0.1, -0.3], [0.0, 1.99, 0.0]], [[0.4, 1.0, 0.4], [0.0, 2.01, 0.0], [0.0, -0.01, 0.0]]),
    (part(shape="polygon", vertices=[[0, 0], [2, 0], [2, 2], [1, 1], [0, 2]]), 2,  # a notch
     [[0.5, 1.2], [1.5, 1.2], [1.0, 0.9]], [[1.0, 1.2], [2.1, 1.0], [1.0, -0.1]]),
    (part(shape="polygon", vertices=[[0, 2], [1, 1], [2, 2], [2, 0], [0, 0]]), 2,  # clockwise
     [[0.5, 1.2], [1.0, 0.9]], [[1.0, 1.2]]),
    (part(shape="half_space", point=[1.0, 1.0], normal=[1.0, 1.0]), 2, [[0.9, 1.0], [-5, -5]],
     [[1.1, 1.0], [0.0, 2.1]]),
    (part(shape="half_space", point=[1.0, 1.0], normal=[1e308, 1e308]), 2,  # no overflow
     [[0.9, 1.0], [-5, -5], [0.5, 1.4]], [[1.1, 1.0], [0.0, 2.1], [1.4, 0.7]]),
    (part(shape="half_space", point=[1.0, 1.0], normal=[1e-320, 0.0]), 2,  # nor underflow
     [[0.9, 1.0], [-5, 5]], [[1.1, 1.0]]),
    (part(shape="difference", parts=[BOX, DISK]), 2, [[0.1, 0.1], [1.3, 0.5]], [[1.0, 0.5]]),
    (part(shape="union", parts=[DISK, part(shape="disk", center=[1.4, 0.5], radius=0.25)]), 2,
     [[0.8, 0.5], [1.6, 0.5], [1.2, 0.5]], [[0.5, 0.5], [1.2, 0.75]]),
    (part(shape="intersection", parts=[BOX, part(shape="half_space", point=[1.0, 0.0],
                                                 normal=[1.0, 0.0])]), 2,
     [[0.5, 0.5]], [[1.5, 0.5], [0.5, 1.5]]),
    (part(shape="difference", parts=[  # nested: a box minus (a disk that is not in the notch)
        BOX, part(shape="difference", parts=[DISK, part(shape="box", min=[0.0, 0.0],
                                                         max=[1.0, 1.0])])]), 2,
     [[0.9, 0.5], [0.1, 0.1]], [[1.1, 0.5]]),
])
def test_inside_at_hand_computed_points(shape, dim, inside, outside):
    assert shape.inside(dim, np.asarray(inside, float)).all()
    assert not shape.inside(dim, np.asarray(outside, float)).any()


def test_bounds_of_combinations():
    notch = part(shape="half_space", point=[1.5, 0.0], normal=[1.0, 0.0])
    assert part(shape="intersection", parts=[BOX, notch]).bounds(2) == ([0.0, 0.0], [1.5, 1.0])
    assert part(shape="difference", parts=[BOX, notch]).bounds(2) == ([0.0, 0.0], [2.0, 1.0])
    far = part(shape="disk", center=[3.0, 0.5], radius=0.5)
    assert part(shape="union", parts=[BOX, far]).bounds(2) == ([0.0, 0.0], [3.5, 1.0])
    slant = part(shape="half_space", point=[0.0, 0.0], normal=[1.0, 1.0])
    assert math.isinf(slant.bounds(2)[1][0])


def test_polygon_area_and_simplicity():
    square = [[0, 0], [1, 0], [1, 1], [0, 1]]
    assert csg.polygon_area(square) == 1.0 and csg.polygon_area(square[::-1]) == -1.0
    assert csg.polygon_crossing(square) is None
    assert csg.polygon_crossing([[0, 0], [1, 1], [1, 0], [0, 1]]) == (0, 2)  # a bow tie
    assert csg.polygon_crossing([[0, 0], [2, 0], [1, 0], [1, 1]]) is not None  # folds back
    assert csg.polygon_crossing([[0, 0], [2, 0], [2, 2], [1, 0], [0, 2]]) is not None  # touches


# --- seeded mass, centroid and moments against the analytic shapes -------------------------------
SCENE = """
dim = {dim}
[grid]
cell_size = {h}
cells = {cells}
{extra}
[materials.steel]
model = "linear_elastic"
density = 1000.0
youngs_modulus = 1e6
poisson_ratio = 0.3
[[bodies]]
material = "steel"
ppc = 2
{body}
[time]
steps = 1
"""

ANNULUS = """shape = "difference"
parts = [{shape = "disk", center = [1.013, 0.987], radius = 0.8},
         {shape = "disk", center = [1.013, 0.987], radius = 0.4}]"""
#: the annulus on its lattice (by default it is seeded in rings: test_conforming_csg.py)
LATTICE_ANNULUS = ANNULUS + '\nseeding = "lattice"'


def scene(body: str, h: float = 0.1, cells=(20, 20), dim: int = 2, extra: str = ""):
    return scene_from_toml(SCENE.format(dim=dim, h=h, cells=list(cells), body=body, extra=extra),
                           "csg.toml")


def seeded(sc):
    """(positions, particle volume) of the one body of ``sc``."""
    seeds = seed_bodies(sc.spec.grid, sc.spec.bodies, {"steel": 0})
    return seeds.x, float(np.prod(seeds.chunks[0][2]))


def test_annulus_converges_to_the_analytic_annulus():
    """A lattice count's error is bounded by its surface layer (perimeter × spacing, relative:
    ``P·s/A``), which halves with the spacing; a smooth boundary's errors partly cancel, so the
    measured errors sit well below it and shrink irregularly (the Gauss circle problem):
    (mass, centroid / R, second moments) relative errors, spacing 0.05 to 0.00625:
    (1.3e-3, 3.1e-4, 6.0e-3), (3.0e-3, 1.5e-3, 2.6e-4), (1.3e-3, 5.2e-4, 2.8e-3),
    (2.3e-4, 3.4e-5, 1.2e-4)."""
    R, r, c = 0.8, 0.4, np.array([1.013, 0.987])
    area = math.pi * (R * R - r * r)
    moment = math.pi / 4 * (R ** 4 - r ** 4)  # ∫ (x − c_x)² dA, the same about y
    perimeter = 2 * math.pi * (R + r)
    errors = []
    for k in range(4):
        h = 0.1 / 2 ** k
        x, vol = seeded(scene(LATTICE_ANNULUS, h, (20 * 2 ** k,) * 2))
        layer = perimeter * (h / 2) / area  # the surface layer's share of the area
        errors.append((abs(vol * len(x) / area - 1), float(np.max(np.abs(x.mean(axis=0) - c))) / R,
                       float(np.max(np.abs(np.sum((x - c) ** 2, axis=0) * vol / moment - 1)))))
        assert max(errors[-1]) <= 0.05 * layer, (h, layer, errors)
    print("annulus errors (mass, centroid / R, second moments) per halving:", errors)
    assert all(e < 0.25 * e0 for e, e0 in zip(errors[-1], errors[0])), errors


def test_plate_with_a_hole_weighs_its_area():
    body = """shape = "difference"
parts = [{shape = "box", min = [0.2, 0.3], max = [1.8, 1.3]},
         {shape = "disk", center = [1.0, 0.8], radius = 0.2}]"""
    for h, tol in ((0.1, 2e-2), (0.025, 3e-3)):
        x, vol = seeded(scene(body, h, (round(2 / h),) * 2))
        area = 1.6 * 1.0 - math.pi * 0.2 ** 2
        assert abs(vol * len(x) / area - 1) < tol, (h, vol * len(x), area)


def test_overlapping_disks_in_a_union_are_seeded_once():
    r, d = 0.5, 0.6  # two disks of radius r, centres d apart
    lens = 2 * r * r * math.acos(d / (2 * r)) - 0.5 * d * math.sqrt(4 * r * r - d * d)
    body = f"""shape = "union"
parts = [{{shape = "disk", center = [0.7, 1.0], radius = {r}}},
         {{shape = "disk", center = [{0.7 + d}, 1.0], radius = {r}}}]"""
    x, vol = seeded(scene(body, 0.025, (80, 80)))
    assert len(np.unique(x, axis=0)) == len(x)
    area = 2 * math.pi * r * r - lens
    assert abs(vol * len(x) / area - 1) < 5e-3, (vol * len(x), area)


def test_notched_bar_and_cylinder_in_3d():
    body = """shape = "difference"
parts = [{shape = "box", min = [0.0, 0.0, 0.0], max = [1.0, 0.4, 0.4]},
         {shape = "intersection", parts = [
            {shape = "half_space", point = [0.5, 0.3, 0.0], normal = [-1.0, -1.0, 0.0]},
            {shape = "half_space", point = [0.5, 0.3, 0.0], normal = [1.0, -1.0, 0.0]}]},
         {shape = "cylinder", axis = "x", center = [0.5, 0.2, 0.2], radius = 0.05, length = 2.0}]"""
    x, vol = seeded(scene(body, 0.05, (20, 8, 8), dim=3))
    notch = 0.1 * 0.1 * 0.4  # the V of depth 0.1 above y = 0.3, 0.2 wide at the top
    hole = math.pi * 0.05 ** 2 * 1.0
    expect = 0.4 * 0.4 - notch - hole
    assert abs(vol * len(x) / expect - 1) < 0.03, (vol * len(x), expect)
    assert not np.any((x[:, 1] > 0.3 + np.abs(x[:, 0] - 0.5) + 1e-9) & (x[:, 1] < 0.4))


# --- a rank's particles: O(N/P), the same as locating every one ----------------------------------
@pytest.mark.parametrize("block", [seeding.BLOCK, 32])
def test_a_ranks_particles_are_the_ones_in_its_patches(block, monkeypatch):
    monkeypatch.setattr(seeding, "BLOCK", block)
    sc = scene(LATTICE_ANNULUS, extra="patch_size = 4")
    grid, dim = sc.spec.grid, 2
    D = Discretisation.from_grid(dim, 0, None, grid, 2)
    seeds = seed_bodies(grid, sc.spec.bodies, {"steel": 0})
    full = seeds.chunks[0][0].lattice.full()  # the bounding lattice, every point at once
    x = seeds.x
    np.testing.assert_array_equal(x, full[sc.spec.bodies[0].inside(dim, full)])
    where = np.zeros(len(x), np.int64)
    lay = D.layout
    bad, _ = locate_patches(dim, x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                            lay.patches_per_axis, where, where)
    assert bad < 0
    np.testing.assert_array_equal(seeds.patch_counts(D), np.bincount(where, minlength=lay.n_patches))
    owned = np.random.default_rng(3).random(lay.n_patches) < 0.5  # rank 0's; rank 1 the rest
    mine, theirs = seeds.members(D, owned), seeds.members(D, ~owned)
    np.testing.assert_array_equal(np.sort(np.concatenate([mine, theirs])), np.arange(seeds.n))
    np.testing.assert_array_equal(mine, np.flatnonzero(owned[where]))
    params = np.array([[0.0, RHO] + [0.0] * 8])
    P = seeds.particles(params, mine)
    np.testing.assert_array_equal(P.gid, mine)
    np.testing.assert_array_equal(P.x0, x[mine])
    assert np.all(P.vol0 == np.prod(seeds.chunks[0][2]))


def test_spin_is_about_the_bounds_centre():
    body = ANNULUS + "\nangular_velocity = 2.0"
    sc = scene(body)
    seeds = seed_bodies(sc.spec.grid, sc.spec.bodies, {"steel": 0})
    P = seeds.particles(np.array([[0.0, RHO] + [0.0] * 8]))
    r = P.x - np.array([1.013, 0.987])
    np.testing.assert_allclose(P.v, 2.0 * np.stack([-r[:, 1], r[:, 0]], axis=1), atol=1e-12)


# --- bad inputs: one line, naming the full key ---------------------------------------------------
def _parts(*items: str) -> str:
    return 'shape = "difference"\nparts = [' + ", ".join(items) + "]"


B = '{shape = "box", min = [0.5, 0.5], max = [1.5, 1.5]}'


@pytest.mark.parametrize("body, dim, fragment", [
    (_parts(B, '{shape = "disk", center = [1.0, 1.0], radius = -0.1}'), 2,
     "bodies.0.parts.1.radius: expected a number > 0, got -0.1"),
    (_parts(B, '{shape = "disk", center = [1.0, 1.0], radius = nan}'), 2,
     "bodies.0.parts.1.radius: expected a number > 0, got nan"),
    (_parts(B, '{shape = "disk", center = [1.0, inf], radius = 0.1}'), 2,
     "bodies.0.parts.1.center: expected a list of 2 numbers"),
    (_parts(B, '{shape = "disk", center = [1.0, 1.0], radius = "big"}'), 2,
     "bodies.0.parts.1.radius: expected a number > 0"),
    (_parts(B, '{shape = "disk", center = [1.0, 1.0], radius = 0.0}'), 2,
     "bodies.0.parts.1.radius"),
    (_parts(B, '{shape = "disk", center = [1.0, 1.0]}'), 2,
     "bodies.0.parts.1.radius: required key is missing"),
    (_parts(B, '{shape = "disc", center = [1.0, 1.0], radius = 0.1}'), 2,
     'bodies.0.parts.1.shape: expected one of "box"'),
    (_parts(B, '{shape = "disk", center = [1.0, 1.0], radius = 0.1, min = [0, 0]}'), 2,
     'bodies.0.parts.1.min: not used by shape "disk"'),
    (_parts(B, '{shape = "disk", centre = [1.0, 1.0], radius = 0.1}'), 2,
     "unknown key 'bodies.0.parts.1.centre'"),
    (_parts(B, '{shape = "sphere", center = [1.0, 1.0], radius = 0.1}'), 2,
     'bodies.0.parts.1.shape: expected "box", "disk"'),
    (_parts(B, '{shape = "cylinder", axis = "x", center = [1, 1], radius = 0.1, length = 1}'), 2,
     "bodies.0.parts.1.shape"),
    (_parts(B, "3"), 2, "bodies.0.parts.1: expected a table"),
    ('shape = "union"\nparts = []', 2, "bodies.0.parts: expected a list of 1 to 100 tables"),
    ('shape = "union"', 2, "bodies.0.parts: required key is missing"),
    ('shape = "polygon"\nvertices = [[0.1, 0.1], [1.0, 0.1], [1.0, 1.0]]\nangle = 30.0', 2,
     'bodies.0.angle: expected only on shape "box" (a polygon is placed by its own coordinates'),
    ('shape = "union"\nparts = [' + "{shape = \"union\", parts = [" * 9 + B + "]}" * 9 + "]", 2,
     "combinations nest at most 8 deep"),
    ('shape = "half_space"\npoint = [1.0, 1.0]\nnormal = [0.0, 1.0]', 2,
     "bodies.0.shape: a half_space is unbounded"),
    (_parts('{shape = "half_space", point = [1.0, 1.0], normal = [0.0, 1.0]}', B), 2,
     "bodies.0.parts.0: expected a bounded first part"),
    ('shape = "union"\nparts = [' + B + ', {shape = "half_space", point = [1.0, 1.0], '
     "normal = [0.0, 1.0]}]", 2, "bodies.0.parts: the union is unbounded"),
    (_parts(B, '{shape = "half_space", point = [1.0, 1.0], normal = [0.0, 0.0]}'), 2,
     "bodies.0.parts.1.normal: expected a nonzero vector"),
    ('shape = "intersection"\nparts = [' + B + ', {shape = "box", min = [1.6, 0.5], '
     "max = [1.9, 1.5]}]", 2, "bodies.0.parts: the intersection is empty"),
    ('shape = "polygon"\nvertices = [[0.5, 0.5], [1.0, 0.5]]', 2,
     "bodies.0.vertices: expected a list of 3 to 1000 points"),
    ('shape = "polygon"\nvertices = [[0.5, 0.5], [1.0, 0.5], [1.5, 0.5]]', 2,
     "bodies.0.vertices: expected a polygon that encloses an area, got area 0"),
    ('shape = "polygon"\nvertices = [[0.5, 0.5], [1.5, 1.5], [1.5, 0.5], [0.5, 1.2]]', 2,
     "bodies.0.vertices: expected a simple polygon"),
    (_parts(B, '{shape = "polygon", vertices = [[0.5, 0.5], [1.0, "a"], [1.5, 0.5]]}'), 2,
     "bodies.0.parts.1.vertices.1: expected a list of 2 numbers"),
    ('shape = "polygon"\nvertices = [[0.5, 0.5], [3.0, 0.5], [1.5, 1.5]]', 2,
     "bodies.0.vertices: body 0 spans [0.5, 3.0] on axis 0"),
    (_parts(B, '{shape = "disk", center = [1.0, 1.0], radius = 0.1}') + "\nangle = 10.0", 2,
     'bodies.0.angle: expected only on shape "box"'),
    ('shape = "cylinder"\naxis = "w"\ncenter = [1, 1, 1]\nradius = 0.1\nlength = 1.0', 3,
     'bodies.0.axis: expected one of "x", "y", "z"'),
    ('shape = "cylinder"\naxis = "z"\ncenter = [1, 1, 1]\nradius = 0.1\nlength = -1.0', 3,
     "bodies.0.length: expected a number > 0"),
    (_parts('{shape = "box", min = [0.5, 0.5, 0.5], max = [1.5, 1.5, 1.5]}',
            '{shape = "polygon", vertices = [[0, 0], [1, 0], [0, 1]]}'), 3,
     'bodies.0.parts.1.shape: expected "box", "sphere"'),
])
def test_a_bad_part_is_one_line_naming_its_key(body, dim, fragment):
    with pytest.raises(SceneError) as info:
        scene(body, dim=dim, cells=(20,) * dim)
    message = str(info.value)
    assert "\n" not in message and fragment in message, message


def test_a_difference_that_removes_everything_names_the_body():
    body = _parts(B, '{shape = "disk", center = [1.0, 1.0], radius = 0.9}')
    sc = scene(body)  # valid geometry: only seeding finds it empty
    with pytest.raises(SceneError, match=r"^bodies\.0: the difference holds no point of its "
                                         r"particle lattice"):
        seed_bodies(sc.spec.grid, sc.spec.bodies, {"steel": 0})


NOTCHED = """shape = "difference"
parts = [{shape = "box", min = [0.2, 0.2, 0.2], max = [1.8, 0.6, 0.6], angle = 5.0},
         {shape = "intersection", parts = [
            {shape = "half_space", point = [1.0, 0.5, 0.0], normal = [-1.0, -1.0, 0.0]},
            {shape = "half_space", point = [1.0, 0.5, 0.0], normal = [1.0, -1.0, 0.0]}]},
         {shape = "cylinder", axis = "x", center = [1.0, 0.4, 0.4], radius = 0.05, length = 2.0}]
velocity_gradient = [[0.1, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]"""


@pytest.mark.parametrize("body, dim", [
    (ANNULUS.replace('"disk", center = [1.013, 0.987], radius = 0.4',
                     '"polygon", vertices = [[0.9, 0.9], [1.1, 0.9], [1.0, 1.1]]'), 2),
    ('shape = "polygon"\nvertices = [[0.5, 0.5], [1.5, 0.5], [1.0, 1.5]]', 2),
    (NOTCHED, 3),
])
def test_the_resolved_body_reads_back(body, dim):
    """Every key of the resolved body reaches a record field (the records' own test, on CSG
    bodies), and the resolved TOML (``[[bodies.parts]]`` tables) reads back the same."""
    from test_scene_records import _reaches

    sc = scene(body, dim=dim, cells=(20,) * dim)
    _reaches(sc.data, sc.spec, "")
    again = scene_from_toml(sc.to_toml(), "again.toml")
    assert again.spec == sc.spec and again.data == sc.data


def test_the_records_hold_the_parts():
    sc = scene(ANNULUS.replace('"disk", center = [1.013, 0.987], radius = 0.4',
                               '"polygon", vertices = [[0.9, 0.9], [1.1, 0.9], [1.0, 1.1]]'))
    body = sc.spec.bodies[0]
    assert body.parts[1].vertices == ((0.9, 0.9), (1.1, 0.9), (1.0, 1.1))
    assert body.bounds() == ([1.013 - 0.8, 0.987 - 0.8], [1.013 + 0.8, 0.987 + 0.8])
    assert body.inside(2, [[0.5, 0.987], [1.0, 1.0]]).tolist() == [True, False]


# --- the documented example ----------------------------------------------------------------------
def test_plate_with_hole_example_runs(tmp_path):
    sc = load_scene(EXAMPLE, ["time.steps=5", "time.end=1.0", "output.snapshots=false",
                              "output.figure=false", "output.history=false"])
    assert sc.spec.bodies[0].shape == "difference"
    summary = Simulation(sc, tmp_path / "o", quiet=True).run()
    assert summary["steps"] == 5, summary
