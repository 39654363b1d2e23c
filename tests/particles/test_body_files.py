"""Bodies read from files (issue 30): ``shape = "mesh"``, ``"surface"`` and ``"particles"``.

Each against an independent result: a meshed square, disk and annulus seeded through the scene
and :func:`~parmpm.particles.seeding.seed_bodies` carry the mesh's own volume, centroid and
second moments (closed forms of ``tests/harness/mesh_harness.py``, sharing nothing with the quadrature)
to round-off, and approach the analytic shape's as the mesh is refined; a CSG annulus agrees with
the meshed one to its lattice's resolution; particle files written here start runs whose particles
are the file's; a parmpm snapshot starts a new run; an icosphere's STL seeds its volume to the
lattice's resolution; every bad input is one line naming its key. A cell a mesh lists twice (Gmsh
2.2's once per physical group, a file written twice) weighs what it weighs once, with one warning.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from mesh_harness import (analytic_ring, particle_moments, polar, polar_tri, polygon_moments,
                          rel_errors, simplex_moments, square_tri, write, write_gmsh22_per_group)

from parmpm import Simulation
from parmpm.core.errors import SceneError
from parmpm.materials import material_table
from parmpm.materials.laws import cauchy_stress
from parmpm.particles import seeding
from parmpm.particles.locate import locate_patches
from parmpm.particles.seeding import seed_bodies
from parmpm.scene.load import scene_from_toml
from parmpm.transfer.discretisation import Discretisation

RHO = 1000.0
EXAMPLES = Path(__file__).resolve().parents[2] / "docs" / "examples"
DATA = Path(__file__).resolve().parents[1] / "data"
SCENE = """
dim = {dim}
[grid]
origin = {origin}
cell_size = {h}
cells = {cells}
{extra}
[materials.steel]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1e6
poisson_ratio = 0.3
[[bodies]]
{body}
[time]
steps = 1
[output]
snapshots = false
figure = false
"""
QUIET = ["output.history.enabled=false"]


def scene(body: str, dim=2, h=0.1, cells=(60, 60), origin=(-2.0, -2.0), extra="", where=None,
          overrides=()):
    text = SCENE.format(dim=dim, h=h, cells=list(cells), origin=list(origin), body=body,
                        extra=extra)
    if where is not None:  # a scene file: relative paths are relative to its folder
        where.write_text(text)
        from parmpm.scene.load import load_scene
        return load_scene(where, overrides)
    return scene_from_toml(text, "files.toml", overrides)


def seeds_of(sc):
    rows = {n: i for i, n in enumerate(sc.spec.materials)}
    return seed_bodies(sc.spec.grid, sc.spec.bodies, rows)


def particles(sc, keep=None):
    p, _ = material_table(sc.spec.materials)
    return seeds_of(sc).particles(p, keep), p


def mesh_body(path, extra=""):
    return f'shape = "mesh"\nmaterial = "steel"\nfile = "{path}"\n{extra}'


# --- the mesh's own moments, to round-off --------------------------------------------------------
def _quads_moments(pts, quads):
    return polygon_moments(pts[quads])


@pytest.mark.parametrize("name", ["square", "disk", "annulus", "annulus_quads"])
def test_mesh_body_has_the_meshs_own_moments(tmp_path, name):
    if name == "square":
        pts, tris = square_tri()
        cells, want = [("triangle", tris)], simplex_moments(pts[tris])
    elif name == "annulus_quads":
        pts, quads, _ = polar(0.5, 1.5, 4, 24)
        cells, want = [("quad", quads)], _quads_moments(pts, quads)
    else:
        pts, tris = polar_tri(0.0 if name == "disk" else 0.5, 1.5, 4, 24)
        cells, want = [("triangle", tris)], simplex_moments(pts[tris])
    path = write(tmp_path, "m.vtu", pts, cells)
    P, _ = particles(scene(mesh_body(path)))
    L = float(np.max(np.ptp(pts, axis=0)))
    errors = rel_errors(particle_moments(P.x0, P.vol0), want, L)
    assert max(errors) <= 1e-12, (name, errors)
    np.testing.assert_allclose(P.mass.sum(), RHO * want[0], rtol=1e-12)
    np.testing.assert_array_equal(P.mass, RHO * P.vol0)
    np.testing.assert_array_equal(P.lh0[:, 0], 0.5 * np.sqrt(P.vol0))
    np.testing.assert_array_equal(P.r0[:, 0, 0], P.lh0[:, 0])
    assert np.all(P.r0[:, 0, 1] == 0)
    print(f"{name}: relative errors (volume, centroid, second moments) {errors}")


def test_mesh_refinement_approaches_the_analytic_annulus(tmp_path):
    """Polygonal rings inscribed in the circles: the area is short by O((2π/n)²) relative;
    halving the angle step quarters the errors."""
    rows = []
    for k, n in enumerate((12, 24, 48, 96)):
        pts, tris = polar_tri(0.5, 1.5, max(2, n // 6), n)
        path = write(tmp_path, f"ring{k}.vtu", pts, [("triangle", tris)])
        P, _ = particles(scene(mesh_body(path)))
        rows.append(rel_errors(particle_moments(P.x0, P.vol0), analytic_ring(0.5, 1.5), 3.0))
    print("annulus from meshes, n_theta = 12, 24, 48, 96: (volume, centroid, second moments)",
          rows)
    for a, b in zip(rows, rows[1:]):
        assert b[0] < 0.3 * a[0] and b[2] < 0.3 * a[2], rows
    assert rows[-1][0] < 1e-3


def test_csg_annulus_agrees_with_the_meshed_one(tmp_path):
    pts, tris = polar_tri(0.5, 1.5, 16, 192)
    path = write(tmp_path, "ring.vtu", pts, [("triangle", tris)])
    meshed, _ = particles(scene(mesh_body(path)))
    h = 0.05
    csg = scene('material = "steel"\nppc = 2\nshape = "difference"\nparts = ['
                '{shape = "disk", center = [0.3, -0.2], radius = 1.5},'
                '{shape = "disk", center = [0.3, -0.2], radius = 0.5}]\nseeding = "lattice"', h=h,
                cells=(120, 120))
    lattice, _ = particles(csg)
    a, b = particle_moments(meshed.x0, meshed.vol0), particle_moments(lattice.x0, lattice.vol0)
    layer = 2 * math.pi * 2.0 * (h / 2) / a[0]  # the lattice's surface layer, relative
    errors = rel_errors(b, a, 3.0)
    print("CSG annulus (spacing 0.025) against the meshed one:", errors, "layer", layer)
    assert max(errors) < layer, (errors, layer)


def test_mesh_split_keeps_the_moments_and_multiplies_the_particles(tmp_path):
    pts, quads, _ = polar(0.5, 1.5, 3, 16)
    path = write(tmp_path, "q.vtu", pts, [("quad", quads)])
    one, _ = particles(scene(mesh_body(path)))
    three, _ = particles(scene(mesh_body(path, "split = 3")))
    assert three.n == 9 * one.n
    errors = rel_errors(particle_moments(three.x0, three.vol0), particle_moments(one.x0, one.vol0),
                        3.0)
    assert max(errors) <= 1e-12, errors


@pytest.mark.parametrize("block", [seeding.BLOCK, 32])
def test_a_ranks_listed_particles_are_the_ones_in_its_patches(tmp_path, block, monkeypatch):
    monkeypatch.setattr(seeding, "BLOCK", block)
    pts, tris = polar_tri(0.5, 1.5, 4, 24)
    sc = scene(mesh_body(write(tmp_path, "m.vtu", pts, [("triangle", tris)])),
               extra="patch_size = 4")
    D = Discretisation.from_grid(2, 0, None, sc.spec.grid, 2)
    seeds = seeds_of(sc)
    x = seeds.x
    where = np.zeros(len(x), np.int64)
    lay = D.layout
    bad, _ = locate_patches(2, x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                            lay.patches_per_axis, where, where)
    assert bad < 0
    np.testing.assert_array_equal(seeds.patch_counts(D), np.bincount(where, minlength=lay.n_patches))
    owned = np.random.default_rng(3).random(lay.n_patches) < 0.5
    mine, theirs = seeds.members(D, owned), seeds.members(D, ~owned)
    np.testing.assert_array_equal(np.sort(np.concatenate([mine, theirs])), np.arange(seeds.n))
    np.testing.assert_array_equal(mine, np.flatnonzero(owned[where]))
    P, _ = particles(sc, mine)
    whole, _ = particles(sc)
    for k in ("x", "vol0", "mass", "lh0", "r0", "v"):
        np.testing.assert_array_equal(getattr(P, k), getattr(whole, k)[mine], err_msg=k)


def test_relative_paths_are_the_scene_files_and_the_resolved_scene_reads_back(tmp_path):
    pts, tris = square_tri()
    write(tmp_path, "sq.vtu", pts, [("triangle", tris)])
    sc = scene(mesh_body("sq.vtu", "velocity = [1.0, 0.0]"), where=tmp_path / "s.toml")
    assert sc.data["bodies"][0]["file"] == str(tmp_path / "sq.vtu")
    assert sc.spec.bodies[0].ppc is None and sc.spec.bodies[0].split == 1
    body = sc.spec.bodies[0]
    for k, v in sc.data["bodies"][0].items():  # every resolved key reaches its record field
        assert getattr(body, k) == (tuple(v) if isinstance(v, list) else v), k
    again = scene_from_toml(sc.to_toml(), "elsewhere.toml")
    assert again.data == sc.data and again.spec == sc.spec
    lo, hi = sc.spec.bodies[0].bounds()
    assert lo == pts.min(axis=0).tolist() and hi == pts.max(axis=0).tolist()


# --- particle files --------------------------------------------------------------------------------
def _known(n=40, dim=2, seed=1):
    rng = np.random.default_rng(seed)
    return (rng.uniform(-1.0, 1.0, (n, dim)), rng.uniform(1e-3, 4e-3, n),
            rng.standard_normal((n, dim)))


def _write_csv(path, x, vol, v=None, names=None):
    head = ["x", "y", "volume"] + (["vx", "vy"] if v is not None else []) + (
        ["material"] if names is not None else [])
    lines = [",".join(head)]
    for k in range(len(vol)):
        row = [repr(float(c)) for c in x[k]] + [repr(float(vol[k]))]
        row += [repr(float(c)) for c in v[k]] if v is not None else []
        row += [names[k]] if names is not None else []
        lines.append(",".join(row))
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("kind", ["npz", "csv"])
def test_a_particle_file_starts_a_run_with_its_particles(tmp_path, kind):
    x, vol, v = _known()
    if kind == "npz":
        path = tmp_path / "p.npz"
        np.savez(path, x=x, volume=vol, v=v)
    else:
        path = _write_csv(tmp_path / "p.csv", x, vol, v)
    sc = scene(f'shape = "particles"\nmaterial = "steel"\nfile = "{path}"', overrides=QUIET)
    P, _ = particles(sc)
    np.testing.assert_array_equal(P.x, x)
    np.testing.assert_array_equal(P.vol0, vol)
    np.testing.assert_array_equal(P.v, v)
    np.testing.assert_array_equal(P.mass, RHO * vol)
    np.testing.assert_array_equal(P.gid, np.arange(len(vol)))
    summary = Simulation(sc, tmp_path / "o", quiet=True).run()
    assert summary["steps"] == 1 and summary["particles"] == len(vol), summary


def test_file_materials_and_deformation_set_the_stress(tmp_path):
    x, vol, _ = _known(n=6)
    F = np.tile(np.eye(2), (6, 1, 1))
    F[:, 0, 0] = 1.0 + 0.01 * np.arange(6)
    names = np.array(["steel", "soft"] * 3)
    path = tmp_path / "f.npz"
    np.savez(path, x=x, volume=vol * np.linalg.det(F), F=F, material=names)
    extra_material = ('[materials.soft]\nmodel = "neo_hookean"\ndensity = 500.0\n'
                      'youngs_modulus = 1e5\npoisson_ratio = 0.2\n')
    sc = scene(f'shape = "particles"\nfile = "{path}"', extra=extra_material)
    assert sc.spec.bodies[0].material is None
    P, table = particles(sc)
    np.testing.assert_allclose(P.vol0, vol, rtol=1e-15)
    np.testing.assert_array_equal(P.F, F)
    rows = {n: i for i, n in enumerate(sc.spec.materials)}
    assert P.mat.tolist() == [rows[str(n)] for n in names]
    want = np.zeros((6, 2, 2))
    for i in range(6):
        cauchy_stress(2, table[P.mat[i]], F[i].copy(), 0.0, want[i])
    np.testing.assert_array_equal(P.stress, want)
    assert np.all(P.stress[1:, 0, 0] > 0)


def test_a_parmpm_snapshot_starts_a_new_run(tmp_path):
    from parmpm.cli.main import main

    out = tmp_path / "bar"
    rc = main(["run", "hanging_bar_1d", "--out", str(out), "--quiet", "--set", "time.end=0.002",
               "--set", "output.every=0.001", "--set", "output.figure=false",
               "--set", "output.history.enabled=false"])
    assert rc in (0, None)
    body = f'shape = "particles"\nmaterial = "bar"\nfile = "{out / "hanging_bar_1d.h5"}"'
    text = SCENE.format(dim=1, h=0.1, cells=[30], origin=[-2.0], body=body, extra="").replace(
        "[materials.steel]", "[materials.bar]")
    sc = scene_from_toml(text, "again.toml", QUIET)
    P, _ = particles(sc)
    from parmpm.io.particle_file import read_particle_file
    last = read_particle_file(out / "hanging_bar_1d.h5", 1)
    assert P.n == 30 and abs(P.vol0.sum() - 1.0) < 1e-13 and np.any(P.F[:, 0, 0] != 1.0)
    np.testing.assert_array_equal(P.x, last.x)
    np.testing.assert_array_equal(P.F, last.F)
    np.testing.assert_array_equal(P.v, last.velocity)
    summary = Simulation(sc, tmp_path / "o", quiet=True).run()
    assert summary["steps"] == 1, summary


# --- surface bodies --------------------------------------------------------------------------------
def icosphere(level=3, r=0.5, c=(0.1, -0.05, 0.02)):
    t = (1 + 5 ** 0.5) / 2
    V = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
         [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    F = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    V = [np.asarray(p, float) / np.linalg.norm(p) for p in V]
    for _ in range(level):
        mid, out = {}, []
        for a, b, c_ in F:
            m = []
            for i, j in ((a, b), (b, c_), (c_, a)):
                key = (min(i, j), max(i, j))
                if key not in mid:
                    p = V[i] + V[j]
                    V.append(p / np.linalg.norm(p))
                    mid[key] = len(V) - 1
                m.append(mid[key])
            out += [[a, m[0], m[2]], [b, m[1], m[0]], [c_, m[2], m[1]], m]
        F = out
    return np.asarray(V) * r + c, np.asarray(F)


def _stl(path, V, T):
    import meshio
    with np.errstate(invalid="ignore"):  # a flat surface's zero normals
        meshio.write(path, meshio.Mesh(V, [("triangle", T)]), file_format="stl", binary=True)
    return path


def test_surface_body_seeds_its_volume(tmp_path):
    from parmpm.geometry.surface import signed_volume

    V, T = icosphere()
    path = _stl(tmp_path / "ball.stl", V, T)
    h = 0.05
    sc = scene(f'shape = "surface"\nmaterial = "steel"\nppc = 2\nfile = "{path}"', dim=3, h=h,
               cells=(30, 30, 30), origin=(-0.75, -0.75, -0.75))
    P, _ = particles(sc)
    want = signed_volume(V, T)
    got = P.vol0.sum()
    layer = 4 * math.pi * 0.5 ** 2 * (h / 2 / 2) / want  # surface × half a spacing, relative
    print(f"icosphere: seeded {got:.6g} m^3 of {want:.6g} (relative {got / want - 1:.3g}, "
          f"layer {layer:.3g})")
    assert abs(got / want - 1) < layer
    assert np.all(P.vol0 == (h / 2) ** 3)


# --- bad inputs: one line naming the key ---------------------------------------------------------
def _one_line(fragment, body, **kw):
    with pytest.raises(SceneError) as info:
        sc = scene(body, **kw)
        seeds_of(sc)
    message = str(info.value)
    assert "\n" not in message and fragment in message, message


def test_bad_file_bodies_are_one_line(tmp_path):
    pts, tris = square_tri()
    good = write(tmp_path, "sq.vtu", pts, [("triangle", tris)])
    flipped = write(tmp_path, "flip.vtu", pts, [("triangle", tris[:, [0, 2, 1]])])
    _one_line("bodies.0.file: mesh '", mesh_body(tmp_path / "none.msh"))
    _one_line("no such file", mesh_body(tmp_path / "none.msh"))
    _one_line("bodies.0.file", mesh_body(good), dim=3, cells=(40, 40, 40), origin=(-2, -2, -2))
    _one_line("is inverted", mesh_body(flipped))
    _one_line('bodies.0.ppc: not used by shape "mesh"', mesh_body(good, "ppc = 2"))
    _one_line("bodies.0.split: expected an integer from 1 to 16, got 0",
              mesh_body(good, "split = 0"))
    _one_line("bodies.0.split: expected an integer from 1 to 16, got 1000",
              mesh_body(good, "split = 1000"))
    _one_line("bodies.0.file: required key is missing", 'shape = "mesh"\nmaterial = "steel"')
    _one_line("bodies.0.file: body 0 spans", mesh_body(good), origin=(2.0, 2.0))
    _one_line("bodies.0.groups: expected a non-empty list", mesh_body(good, "groups = []"))
    x, vol, _ = _known(n=4)
    named = tmp_path / "named.npz"
    np.savez(named, x=x, volume=vol, material=np.array(["steel", "granite"] * 2))
    _one_line("bodies.0.file: particle file '", f'shape = "particles"\nfile = "{named}"')
    _one_line("names material \"granite\"", f'shape = "particles"\nfile = "{named}"')
    plain = tmp_path / "plain.npz"
    np.savez(plain, x=x, volume=vol)
    _one_line("bodies.0.material: required key is missing",
              f'shape = "particles"\nfile = "{plain}"')
    _one_line('bodies.0.ppc: not used by shape "particles"',
              f'shape = "particles"\nmaterial = "steel"\nppc = 2\nfile = "{plain}"')
    _one_line("bodies.0.step: expected an integer >= 0",
              f'shape = "particles"\nmaterial = "steel"\nstep = -1\nfile = "{plain}"')
    V, T = icosphere(level=1)
    flat = V.copy()
    flat[:, 2] = 0.0
    _one_line("encloses no volume", f'shape = "surface"\nmaterial = "steel"\nfile = '
              f'"{_stl(tmp_path / "flat.stl", flat, T)}"', dim=3, cells=(40, 40, 40),
              origin=(-2, -2, -2))
    tiny = _stl(tmp_path / "tiny.stl", *icosphere(level=1, r=0.002, c=(0.0, 0.0, 0.0)))
    _one_line("bodies.0: the surface holds no point of its particle lattice (spacing 0.1, 0.1, "
              "0.1 m): it is thinner", f'shape = "surface"\nmaterial = "steel"\nppc = 1\n'
              f'file = "{tiny}"', dim=3, cells=(40, 40, 40), origin=(-2, -2, -2))
    _one_line('got "surface" (only for dim 3)', f'shape = "surface"\nmaterial = "steel"\n'
              f'file = "{tmp_path / "flat.stl"}"')


# --- the documented example and the rank case's scene ------------------------------------------
@pytest.mark.parametrize("path", [EXAMPLES / "rings_from_mesh.toml", DATA / "spinning_blob.toml"])
def test_file_body_scenes_run(tmp_path, path):
    from parmpm.scene.load import load_scene

    sc = load_scene(path, ["time.steps=5", "time.end=1.0", "output.snapshots=false",
                           "output.figure=false", "output.history.enabled=false"])
    summary = Simulation(sc, tmp_path / "o", quiet=True).run()
    assert summary["steps"] == 5, summary
    if path.stem == "rings_from_mesh":
        assert summary["particles"] == 2 * 80 * 4


def test_an_open_surface_is_seeded_with_one_warning(tmp_path, caplog):
    V, T = icosphere(level=2)
    path = _stl(tmp_path / "holed.stl", V, T[:-3])  # three triangles gone: a hole
    with caplog.at_level("WARNING"):
        for _ in range(2):  # checked twice (as a restart re-reads the scene): said once
            sc = scene(f'shape = "surface"\nmaterial = "steel"\nppc = 2\nfile = "{path}"', dim=3,
                       h=0.05, cells=(30, 30, 30), origin=(-0.75, -0.75, -0.75))
    said = [r.getMessage() for r in caplog.records if "holed.stl" in r.getMessage()]
    assert len(said) == 1 and "open edges" in said[0] and "\n" not in said[0], said
    P, _ = particles(sc)
    assert abs(P.vol0.sum() / 0.5 - 1) < 0.1  # a sphere of radius 0.5 (~0.52 m^3) nearly whole


def test_a_mesh_inside_a_box_is_counted_by_its_own_volumes(tmp_path):
    from parmpm.scene.overlaps import seeded_twice

    pts, tris = square_tri()  # [1, 3] x [-1, 1]
    path = write(tmp_path, "sq.vtu", pts, [("triangle", tris)])
    body = ('material = "steel"\nmin = [1.0, -1.0]\nmax = [2.0, 1.0]\n[[bodies]]\n'
            + mesh_body(path))
    sc = scene(body)
    seeds = seeds_of(sc)
    found = seeded_twice(None, sc.spec, seeds, np.arange(seeds.n), seeds.x)
    assert len(found) == 1 and found[0]["bodies"] == (0, 1), found
    assert abs(found[0]["volume"] / 2.0 - 1) < 0.05
    assert found[0]["mass"] == pytest.approx(RHO * found[0]["volume"], rel=1e-14)


# --- cells listed more than once (issue 41) ----------------------------------------------------
def _small_square():
    """[0, 0.4]^2 in triangles: 160 kg at 1000 kg/m^3; ``left``: the triangles left of x = 0.2."""
    pts, tris = square_tri(n=4)
    pts = (pts - [1.0, -1.0]) * 0.2
    return pts, tris, pts[tris].mean(axis=1)[:, 0] < 0.2


def _seeded_with_warnings(caplog, body, name):
    with caplog.at_level("WARNING"):
        P, _ = particles(scene(body))
    return P, [r.getMessage() for r in caplog.records if name in r.getMessage()]


@pytest.mark.parametrize("groups", [None, '["all", "left"]', '["left", "all"]', '["left"]'])
def test_a_gmsh22_cell_in_two_groups_is_seeded_once(tmp_path, caplog, groups):
    """Before: 240 kg for the 160 kg square (its left half listed in both groups, seeded twice)."""
    pts, tris, left = _small_square()
    path = write_gmsh22_per_group(tmp_path / "sq.msh", pts, tris,
                                  {"all": np.ones(len(tris), bool), "left": left})
    P, said = _seeded_with_warnings(
        caplog, mesh_body(path, "" if groups is None else f"groups = {groups}"), "sq.msh")
    kept = left if groups == '["left"]' else np.ones(len(tris), bool)
    area = simplex_moments(pts[tris[kept]])[0]
    assert P.mass.sum() == pytest.approx(RHO * area, rel=1e-12)
    assert len(P.mass) == 3 * kept.sum()
    if groups == '["left"]':  # the "all" listing is not selected: nothing was seeded twice
        assert said == [] and area == pytest.approx(0.08, rel=0.05)
        return
    assert area == pytest.approx(0.16, rel=1e-12)
    dropped = simplex_moments(pts[tris[left]])[0]
    assert len(said) == 1 and "\n" not in said[0], said
    assert (f"lists {left.sum()} cells more than once" in said[0]
            and f"dropping {left.sum()} repeated listings of area {dropped:.6g} m^2" in said[0]
            and "Gmsh 2.2" in said[0]), said


def test_a_vtu_with_every_cell_twice_is_seeded_once(tmp_path, caplog):
    """Before: 320 kg for the 160 kg square. The repeats' nodes start elsewhere (rotated):
    the same cell."""
    pts, tris, _ = _small_square()
    twice = np.concatenate([tris, np.roll(tris, 1, axis=1)])
    path = write(tmp_path, "twice.vtu", pts, [("triangle", twice)])
    P, said = _seeded_with_warnings(caplog, mesh_body(path), "twice.vtu")
    assert P.mass.sum() == pytest.approx(RHO * 0.16, rel=1e-12)
    once, _ = particles(scene(mesh_body(write(tmp_path, "once.vtu", pts, [("triangle", tris)]))))
    np.testing.assert_array_equal(P.x0, once.x0)  # the first listings, in file order
    assert len(said) == 1 and f"dropping {len(tris)} repeated listings of area 0.16 m^2" in said[0]
    assert "Gmsh" not in said[0]


@pytest.mark.parametrize("scale, said", [(1.0, False), (1e300, True)])
def test_particle_volumes_past_their_box_are_one_warning(tmp_path, caplog, scale, said):
    """Issue 41: volumes of 1e300 ran as given (with cpdi, domains of 1e150 m); now one line
    naming the file, the sum and the box its points span."""
    x, vol, _ = _known(seed=7)
    path = _write_csv(tmp_path / f"v{scale:g}.csv", x, vol * scale)
    with caplog.at_level("WARNING"):
        scene(f'shape = "particles"\nmaterial = "steel"\nfile = "{path}"', overrides=QUIET)
    lines = [r.getMessage() for r in caplog.records if path.name in r.getMessage()]
    assert len(lines) == int(said), lines
    if said:
        assert "\n" not in lines[0] and "have volumes summing to" in lines[0], lines
        assert lines[0].startswith("bodies.0.file: the particles of "), lines


def test_a_particle_file_with_repeated_rows_is_warned_once(tmp_path, caplog):
    """Every row twice (issue 41): the scene still loads (the rows may be meant) and says so in
    one line naming the key, the count, the first pair's lines and the volume they add (half of
    the file's: the body's mass doubled); the seeded particles are the file's rows."""
    x, vol, _ = _known(n=10)
    path = _write_csv(tmp_path / "twice.csv", np.concatenate([x, x]), np.concatenate([vol, vol]))
    with caplog.at_level("WARNING"):
        sc = scene(f'shape = "particles"\nmaterial = "steel"\nfile = "{path}"', overrides=QUIET)
    said = [r.getMessage() for r in caplog.records if "twice.csv" in r.getMessage()]
    assert len(said) == 1 and "\n" not in said[0], said
    assert said[0].startswith(f"bodies.0.file: particle file '{path}': 10 row(s) repeat an "
                              "earlier row's position (the first: line 12 repeats line 2)"), said
    assert f"they add volume {vol.sum():.6g}, 50 % of the file's total" in said[0], said
    assert particles(sc)[0].n == 20
