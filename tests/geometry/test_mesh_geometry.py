"""Volume meshes as bodies: :func:`parmpm.io.mesh_file.read_volume_mesh` reads the elements,
:func:`parmpm.geometry.mesh.element_particles` turns them into particles with volumes.

Every claim is checked against moments computed from the elements by closed forms that share
nothing with the module's quadrature (``tests/harness/mesh_harness.py``: simplex second-moment formulas,
Green's theorem for quads, exact polynomial algebra on the trilinear map for hexahedra). Meshes
are numpy triangulations written with meshio into ``tmp_path``.
"""
import os
import subprocess
import sys

import numpy as np
import pytest
from mesh_harness import (TRI_MESHES, analytic_ring, assert_same_moments, cube_grid, gauss_2x2x2,
                          hex_moments, kuhn_tets, particle_moments, polar, polar_tri, polygon_moments,
                          rel_errors, simplex_moments, square_tri, write, write_gmsh22_per_group)

from parmpm.core.errors import SceneError
from parmpm.geometry.mesh import element_particles, mesh_particles, particles_per_element
from parmpm.io.mesh_file import read_volume_mesh

# ---------------------------------------------------------------- moments equal the mesh's own


@pytest.mark.parametrize("ext", ["msh", "vtu", "xdmf", "inp"])
@pytest.mark.parametrize("shape", sorted(TRI_MESHES))
def test_triangle_mesh_particles_carry_its_moments(tmp_path, shape, ext):
    pts, tris = TRI_MESHES[shape]()
    path = write(tmp_path, f"{shape}.{ext}", pts, [("line", tris[:3, :2]), ("triangle", tris)])
    mesh = read_volume_mesh(path, 2)
    assert [b.cell_type for b in mesh.blocks] == ["triangle"] and mesh.points.shape[1] == 2
    x, vol, elem = mesh_particles(mesh.points, mesh.blocks)
    assert len(x) == 3 * len(tris) and np.all(vol > 0)
    assert np.array_equal(elem, np.repeat(np.arange(len(tris)), 3))
    assert_same_moments(particle_moments(x, vol), simplex_moments(pts[tris]), L=3.0)


def test_quads_of_any_convex_shape_carry_their_moments(tmp_path):
    """2×2 Gauss on the bilinear map: exact for degree 2 on every convex quad (trapezoids of an
    annulus, a sheared and tapered grid, random convex quads)."""
    pts, quads, _ = polar(0.5, 1.5, 3, 16)
    mesh = read_volume_mesh(write(tmp_path, "ring.vtu", pts, [("quad", quads)]), 2)
    got = particle_moments(*mesh_particles(mesh.points, mesh.blocks)[:2])
    assert_same_moments(got, polygon_moments(pts[quads]), L=3.0)
    g = np.linspace(0, 1, 5)
    X, Y = np.meshgrid(g, g, indexing="ij")
    grid = np.stack([X + 0.3 * Y + 0.2 * X * Y, Y * (1 + 0.5 * X) + 0.1 * X * X], -1).reshape(-1, 2)
    idx = np.arange(25).reshape(5, 5)
    q = np.stack([idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()], 1)
    got = particle_moments(*element_particles(grid, "quad", q)[:2])
    assert_same_moments(got, polygon_moments(grid[q]), L=2.0)
    rng = np.random.default_rng(7)
    for _ in range(50):
        t = np.sort(rng.uniform(0, 2 * np.pi, 4))
        P = np.stack([np.cos(t), np.sin(t)], 1) * rng.uniform(0.5, 2.0, 2) + rng.uniform(-5, 5, 2)
        got = particle_moments(*element_particles(P, "quad", [[0, 1, 2, 3]])[:2])
        assert_same_moments(got, polygon_moments(P[None]), L=10.0)


def test_tetra_cube_carries_its_moments(tmp_path):
    pts, hexes = cube_grid(3)
    rng = np.random.default_rng(3)
    inner = np.all((pts > pts.min(0) + 1e-9) & (pts < pts.max(0) - 1e-9), axis=1)
    pts[inner] += rng.uniform(-0.05, 0.05, (inner.sum(), 3))
    tets = kuhn_tets(pts, hexes)
    mesh = read_volume_mesh(write(tmp_path, "cube.msh", pts, [("triangle", tets[:2, :3]), ("tetra", tets)]), 3)
    x, vol, _ = mesh_particles(mesh.points, mesh.blocks)
    assert len(x) == 4 * len(tets)
    assert_same_moments(particle_moments(x, vol), simplex_moments(pts[tets]), L=3.0)
    assert abs(vol.sum() - 1.0) < 1e-13


def test_hex_cube_with_distorted_nodes_carries_its_moments(tmp_path):
    """3×3×3 Gauss is exact for degree 2 on any trilinear hexahedron (warped faces too). 2×2×2
    is not: it gets the volume and centroid right but misses the second moments."""
    pts, hexes = cube_grid(2)
    pts += np.random.default_rng(5).uniform(-0.06, 0.06, pts.shape)  # every face warps
    mesh = read_volume_mesh(write(tmp_path, "cube.vtu", pts, [("hexahedron", hexes)]), 3)
    x, vol, _ = mesh_particles(mesh.points, mesh.blocks)
    want = hex_moments(pts[hexes])
    got = particle_moments(x, vol)
    assert len(x) == 27 * 8
    assert_same_moments(got, want, L=3.0)
    two = rel_errors(gauss_2x2x2(pts[hexes]), want, L=3.0)
    assert max(two[:2]) < 1e-12 and two[2] > 1e-9  # the claim; a 2×2×2 rule would fail here
    cube_pts, cube_hexes = cube_grid(2)  # undistorted: the volume of the unit cube
    assert abs(element_particles(cube_pts, "hexahedron", cube_hexes)[1].sum() - 1.0) < 1e-14


# ---------------------------------------------------------------- convergence to the analytic body


@pytest.mark.parametrize("r_in", [0.0, 0.5], ids=["disk", "annulus"])
def test_refined_meshes_approach_the_exact_body_as_h2(r_in):
    """Polygonal meshes of a disk/annulus: volume and moments converge with order 2 (chords)."""
    rows = []
    for m in (2, 4, 8, 16):
        pts, tris = polar_tri(r_in, 1.5, m, 8 * m)
        x, vol, _ = element_particles(pts, "triangle", tris)
        rows.append((m, *rel_errors(particle_moments(x, vol), analytic_ring(r_in, 1.5), L=3.0)))
    err = np.array([r[1:] for r in rows])
    order = np.log2(err[:-1] / err[1:])
    print(f"\n{'disk' if r_in == 0 else 'annulus'}: m  err(V)  err(M1)  err(M2) / orders (pytest -s)")
    for r, o in zip(rows, [("",) * 3] + order.tolist()):
        print(f"  {r[0]:3d}  " + "  ".join(f"{e:.3e}" for e in r[1:]) + "  " + " ".join(
            f"{v:.2f}" if v != "" else "" for v in o))
    assert np.all(np.abs(order[:, [0, 2]] - 2.0) < 0.1)


@pytest.mark.parametrize("cell_type", ["triangle", "quad", "tetra", "hexahedron"])
def test_particles_made_in_blocks_are_the_one_pass_bits(monkeypatch, cell_type):
    """The elements are made a block at a time (bounded temporaries): any block size gives the
    same bits, in the same order, and an element's error names its index in the whole mesh."""
    import parmpm.geometry.mesh as mesh_module

    if cell_type in ("triangle", "quad"):
        pts, conn, _ = polar(0.5, 1.5, 5, 24)
        if cell_type == "triangle":
            conn = np.concatenate([conn[:, [0, 1, 2]], conn[:, [0, 2, 3]]])
    else:
        pts, conn = cube_grid(3)
        pts = pts + np.random.default_rng(3).uniform(-0.05, 0.05, pts.shape)
        if cell_type == "tetra":
            conn = kuhn_tets(pts, conn)
    whole = element_particles(pts, cell_type, conn, split=2)
    for block in (1, 7, 5 * particles_per_element(cell_type, 2) + 3):
        monkeypatch.setattr(mesh_module, "BLOCK_PARTICLES", block)
        for a, b in zip(element_particles(pts, cell_type, conn, split=2), whole):
            assert a.dtype == b.dtype and np.array_equal(a, b)
        flipped = conn.copy()
        flip = {"triangle": [0, 2, 1], "quad": [3, 2, 1, 0], "tetra": [1, 0, 2, 3],
                "hexahedron": [4, 5, 6, 7, 0, 1, 2, 3]}[cell_type]
        flipped[-2] = flipped[-2, flip]  # in the last block or the one before: inverted
        one_line(fails(pts, cell_type, flipped, split=2, first=10),
                 f"element {10 + len(conn) - 2} ({cell_type}")


# ---------------------------------------------------------------- split


@pytest.mark.parametrize("cell_type", ["triangle", "quad", "tetra", "hexahedron"])
@pytest.mark.parametrize("split", [2, 3])
def test_split_gives_split_d_particles_and_the_same_moments(cell_type, split):
    if cell_type in ("triangle", "quad"):
        pts, quads, _ = polar(0.5, 1.5, 2, 8)
        conn = quads if cell_type == "quad" else np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
        want = polygon_moments(pts[conn]) if cell_type == "quad" else simplex_moments(pts[conn])
        d = 2
    else:
        pts, conn = cube_grid(1)
        pts[conn[0, 6]] += [0.2, 0.1, -0.15]
        if cell_type == "tetra":
            conn = kuhn_tets(pts, conn)
            want = simplex_moments(pts[conn])
        else:
            want = hex_moments(pts[conn])
        d = 3
    x1, _, _ = element_particles(pts, cell_type, conn)
    x, vol, elem = element_particles(pts, cell_type, conn, split=split)
    assert len(x) == split ** d * len(x1) == particles_per_element(cell_type, split) * len(conn)
    assert np.all(vol > 0) and np.all(np.diff(elem) >= 0)  # element by element
    assert_same_moments(particle_moments(x, vol), want, L=3.0)
    # each particle lies in its own element: within its nodes' bounding box, equal shares per
    # sub-element for simplices
    X = pts[conn][elem]
    assert np.all((x >= X.min(1) - 1e-12) & (x <= X.max(1) + 1e-12))
    assert np.array_equal(element_particles(pts, cell_type, conn, split=split)[0], x)  # deterministic


# ---------------------------------------------------------------- groups


GMSH41 = """$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
3
1 3 "edge"
2 1 "left"
2 2 "right"
$EndPhysicalNames
$Entities
0 1 2 0
1 0 0 0 1 0 0 1 3 0
1 0 0 0 1 1 0 1 1 0
2 1 0 0 2 1 0 1 2 0
$EndEntities
$Nodes
1 6 1 6
2 1 0 6
1
2
3
4
5
6
0 0 0
1 0 0
1 1 0
0 1 0
2 0 0
2 1 0.0
$EndNodes
$Elements
3 5 1 5
1 1 1 1
1 1 2
2 1 2 2
2 1 2 3
3 1 3 4
2 2 2 2
4 2 5 6
5 2 6 3
$EndElements
"""


def area(mesh):
    return mesh_particles(mesh.points, mesh.blocks)[1].sum()


def test_gmsh_physical_groups_select_cells(tmp_path):
    path = tmp_path / "two.msh"
    path.write_text(GMSH41)
    whole = read_volume_mesh(path, 2)
    assert whole.group_names == {"left": 1, "right": 2}  # 'edge' is a line group
    assert whole.n_cells == 4 and abs(area(whole) - 2.0) < 1e-14
    left = read_volume_mesh(path, 2, groups=["left"])
    assert left.n_cells == 2 and abs(area(left) - 1.0) < 1e-14
    assert np.all(left.points[np.concatenate([b.cells for b in left.blocks])][..., 0] <= 1.0)
    right = read_volume_mesh(path, 2, groups=[2])
    assert right.n_cells == 2 and np.all(np.concatenate([b.group for b in right.blocks]) == 2)
    assert read_volume_mesh(path, 2, groups=["left", 2]).n_cells == 4
    with pytest.raises(SceneError, match=r"no group 'middle' .*available groups: 'left' \(1\), 'right' \(2\)"):
        read_volume_mesh(path, 2, groups=["middle"])
    with pytest.raises(SceneError, match=r"no group 3 .*available"):  # the line group's tag
        read_volume_mesh(path, 2, groups=[3])
    for bad in ([], {"left": 1}, [1.5]):
        with pytest.raises(SceneError, match=r"available groups: 'left' \(1\), 'right' \(2\)"):
            read_volume_mesh(path, 2, groups=bad)


def test_cell_sets_select_cells(tmp_path):
    """Abaqus element sets (overlapping: 'all' holds every cell)."""
    pts, tris = square_tri(2)
    path = write(tmp_path, "sq.inp", pts, [("triangle", tris)],
                 cell_sets={"all": [np.arange(8)], "low": [np.array([0, 1, 4, 5])]})
    mesh = read_volume_mesh(path, 2)
    assert mesh.group_names == {"all": 0, "low": 1}
    low = read_volume_mesh(path, 2, groups=["low"])
    assert low.n_cells == 4 and np.all(low.blocks[0].group == 1)
    assert np.array_equal(low.blocks[0].cells, tris[[0, 1, 4, 5]])
    assert read_volume_mesh(path, 2, groups=["low", "all"]).n_cells == 8


def test_a_cell_listed_again_is_read_once(tmp_path):
    """Issue 41: a cell is its node set. Repeats in a later block of the same type, their nodes
    rotated, are dropped and counted; the first listings keep their blocks and order."""
    pts, quads, _ = polar(0.5, 1.5, 4, 24)
    again = np.roll(quads[3:8], 2, axis=1)
    mesh = read_volume_mesh(write(tmp_path, "q.vtu", pts, [("quad", quads), ("quad", again)]), 2)
    assert len(mesh.blocks) == 1 and np.array_equal(mesh.blocks[0].cells, quads)
    assert mesh.repeats.tolist() == [0] * 3 + [1] * 5 + [0] * (len(quads) - 8)
    once = read_volume_mesh(write(tmp_path, "once.vtu", pts, [("quad", quads)]), 2)
    assert once.repeats is None and np.array_equal(once.blocks[0].cells, quads)


def test_gmsh22_listings_per_group_merge_their_groups(tmp_path):
    """Gmsh 2.2 lists a cell once per physical group: read once, in the first selected group."""
    pts, tris = square_tri(2)
    low = np.arange(len(tris)) < 3
    path = write_gmsh22_per_group(tmp_path / "g.msh", pts, tris,
                                  {"all": np.ones(len(tris), bool), "low": low})
    for groups, tag in ((None, np.ones(len(tris))), (["low", "all"], np.where(low, 2, 1)),
                        (["all", "low"], np.ones(len(tris)))):
        mesh = read_volume_mesh(path, 2, groups)
        assert mesh.n_cells == len(tris) and np.array_equal(mesh.blocks[0].cells, tris)
        assert np.array_equal(mesh.blocks[0].group, tag) and mesh.repeats.sum() == 3, groups
    only = read_volume_mesh(path, 2, ["low"])
    assert only.n_cells == 3 and only.repeats is None  # each listed once among the selected


# ---------------------------------------------------------------- errors: one line, naming the problem


def one_line(exc_info, *parts):
    msg = str(exc_info.value)
    assert "\n" not in msg, msg
    for p in parts:
        assert p in msg, (p, msg)


def test_file_errors(tmp_path):
    with pytest.raises(SceneError) as e:
        read_volume_mesh(tmp_path / "none.msh", 2)
    one_line(e, "none.msh", "no such file")
    with pytest.raises(SceneError) as e:
        read_volume_mesh(tmp_path, 2)
    one_line(e, "is a directory")
    (tmp_path / "empty.msh").write_bytes(b"")
    with pytest.raises(SceneError) as e:
        read_volume_mesh(tmp_path / "empty.msh", 2)
    one_line(e, "empty.msh", "empty")
    (tmp_path / "junk.msh").write_bytes(bytes(range(256)) * 8)
    with pytest.raises(SceneError) as e:
        read_volume_mesh(tmp_path / "junk.msh", 2)
    one_line(e, "junk.msh", "meshio cannot read it", "gmsh")
    (tmp_path / "junk.vtu").write_text("<VTKFile>truncated")
    with pytest.raises(SceneError) as e:
        read_volume_mesh(tmp_path / "junk.vtu", 2)
    one_line(e, "junk.vtu", "meshio cannot read it")
    (tmp_path / "mesh.foo").write_text("1 2 3")
    with pytest.raises(SceneError) as e:
        read_volume_mesh(tmp_path / "mesh.foo", 2)
    one_line(e, "mesh.foo", "meshio cannot read it", "foo")
    with pytest.raises(SceneError) as e:
        read_volume_mesh(tmp_path / "mesh.foo", 4)
    one_line(e, "dimension 4", "expected 2 or 3")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_is_refused_without_opening_it(tmp_path):
    """Before: open() blocked until something wrote to the pipe (a subprocess: a hang fails)."""
    os.mkfifo(tmp_path / "pipe.msh")
    code = ("from parmpm.io.mesh_file import read_volume_mesh\n"
            f"read_volume_mesh({str(tmp_path / 'pipe.msh')!r}, 2)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "is not a regular file (a FIFO, device or socket)" in proc.stderr.splitlines()[-1]


def test_content_errors(tmp_path):
    pts, tris = square_tri(2)
    path = write(tmp_path, "sq.vtu", pts, [("line", tris[:, :2]), ("triangle", tris)])
    with pytest.raises(SceneError) as e:
        read_volume_mesh(path, 3)
    one_line(e, "no 3D cells", "found line, triangle", "tetra or hexahedron")
    with pytest.raises(SceneError) as e:
        read_volume_mesh(write(tmp_path, "lines.vtu", pts, [("line", tris[:, :2])]), 2)
    one_line(e, "no 2D cells", "found line")
    warped = np.column_stack([pts, np.linspace(0, 1, len(pts))])
    with pytest.raises(SceneError) as e:
        read_volume_mesh(write(tmp_path, "warp.vtu", warped, [("triangle", tris)]), 2)
    one_line(e, "warp.vtu", "z spans [0, 1]", "all z equal")
    bad = pts.copy()
    bad[4] = [np.nan, 0.0]
    with pytest.raises(SceneError) as e:
        read_volume_mesh(write(tmp_path, "nan.vtu", bad, [("triangle", tris)]), 2)
    one_line(e, "node 4", "nan", "finite")
    bad[4] = [np.inf, 0.0]
    with pytest.raises(SceneError) as e:
        read_volume_mesh(write(tmp_path, "inf.vtu", bad, [("triangle", tris)]), 2)
    one_line(e, "node 4", "inf", "finite")
    far = tris.copy()
    far[3, 1] = 99
    with pytest.raises(SceneError) as e:
        read_volume_mesh(write(tmp_path, "far.vtu", pts, [("triangle", far)]), 2)
    one_line(e, "triangle cell 3", "99", "nodes 0..8")
    six = np.column_stack([tris, tris])
    with pytest.raises(SceneError) as e:
        read_volume_mesh(write(tmp_path, "t6.vtu", pts, [("triangle6", six)]), 2)
    one_line(e, "'triangle6'", "accepts only triangle and quad")
    p3 = np.random.default_rng(0).uniform(size=(6, 3))
    with pytest.raises(SceneError) as e:
        read_volume_mesh(write(tmp_path, "w.vtu", p3, [("wedge", [[0, 1, 2, 3, 4, 5]])]), 3)
    one_line(e, "'wedge'", "tetra and hexahedron")
    with pytest.raises(SceneError) as e:
        read_volume_mesh(path, 2, groups=["left"])
    one_line(e, "no group 'left'", "available groups: none")


def fails(*args, **kw):
    with pytest.raises(SceneError) as e:
        element_particles(*args, **kw)
    return e


def test_element_errors_name_the_element():
    tri = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [2.0, 0.0]])
    one_line(fails(tri, "triangle", [[0, 1, 2], [0, 2, 1]]), "element 1 (triangle, nodes [0, 2, 1]",
             "inverted", "signed area -0.5", "counter-clockwise")
    one_line(fails(tri, "triangle", [[0, 1, 3]]), "element 0", "zero area")
    tet = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]])
    one_line(fails(tet, "tetra", [[0, 1, 2, 3], [0, 2, 1, 3]]), "element 1 (tetra", "inverted",
             "signed volume -0.167")
    one_line(fails(tet, "tetra", [[0, 1, 2, 4]]), "element 0 (tetra", "zero volume")
    dart = np.array([[0.0, 0.0], [2.0, 0.0], [0.5, 0.5], [0.0, 2.0]])
    one_line(fails(dart, "quad", [[0, 1, 2, 3]]), "element 0 (quad", "not convex")
    bowtie = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    one_line(fails(bowtie, "quad", [[0, 1, 2, 3]]), "element 0 (quad", "tangled")
    flat = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])
    one_line(fails(flat, "quad", [[0, 1, 2, 3]]), "element 0 (quad", "zero area")
    bowtie2 = np.array([[0.0, 0.0], [1.0, 0.0], [0.2, 1.0], [1.0, 1.0]])
    one_line(fails(bowtie2, "quad", [[0, 1, 2, 3]]), "element 0 (quad", "not convex")
    one_line(fails(dart, "quad", [[0, 3, 2, 1]]), "tangled")  # reversed and non-convex
    kite = np.array([[0.0, 0.0], [2.0, 0.0], [2.5, 2.5], [0.0, 2.0]])
    one_line(fails(kite, "quad", [[0, 3, 2, 1]]), "inverted", "signed area -5)", "counter-clockwise")
    pts, hexes = cube_grid(1)
    one_line(fails(pts, "hexahedron", hexes[:, [4, 5, 6, 7, 0, 1, 2, 3]]), "element 0 (hexahedron",
             "inverted", "signed volume -1")
    tangled = pts.copy()
    tangled[hexes[0, 6]] = pts[hexes[0, 0]] + [0.2, 0.2, 0.2]
    one_line(fails(tangled, "hexahedron", hexes), "element 0 (hexahedron", "tangled")
    one_line(fails(tri * 1e200, "triangle", [[0, 1, 2]]), "overflows")
    square_pts, square_tris = square_tri(2)
    bad = square_tris.copy()
    bad[5] = bad[5, [0, 2, 1]]
    with pytest.raises(SceneError) as e:  # counted through the blocks
        mesh_particles(square_pts, [("quad", np.zeros((0, 4), int)), ("triangle", square_tris[:3]),
                                    ("triangle", bad[3:])], label="mesh 'sq.msh'")
    one_line(e, "mesh 'sq.msh': element 5 (triangle")


def test_argument_errors():
    tri = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    for split in (0, 1.5, True, "2"):
        one_line(fails(tri, "triangle", [[0, 1, 2]], split=split), "split", "integer >= 1")
    one_line(fails(tri, "pyramid", [[0, 1, 2]]), "'pyramid'", "expected one of")
    one_line(fails(tri, "tetra", [[0, 1, 2, 0]]), "shape (n, 3)")
    one_line(fails(tri, "triangle", [[0, 1, 5]]), "node 5", "0..2")
    one_line(fails(tri, "triangle", [[0.0, 1.0, 2.0]]), "integers")
    one_line(fails(tri, "quad", [[0, 1, 2]]), "shape (n, 4)")
