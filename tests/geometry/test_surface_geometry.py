"""Closed triangulated surfaces as bodies: reading STL/OBJ/PLY, the generalised winding number and
the inside test, checked against computations written here — a convex polyhedron's half-space
test, the divergence-theorem volume as Σ x n_x A, the octant's solid angle 4π/8 — never against
the module's own output.
"""
import math
import os
import subprocess
import sys

import meshio
import numpy as np
import pytest

from parmpm.core.errors import SceneError
from parmpm.geometry.surface import check_surface, inside_surface, winding_numbers
from parmpm.geometry.winding import build_tree, tree_winding, winding_sum
from parmpm.io.surface_file import read_surface


def icosphere(level: int) -> tuple[np.ndarray, np.ndarray]:
    """A unit icosahedron's faces, each split ``level`` times into four, new vertices pushed onto
    the unit sphere; triangles counter-clockwise seen from outside."""
    t = (1 + 5 ** 0.5) / 2
    V = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
         [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    V = [list(np.divide(v, np.linalg.norm(v))) for v in V]
    F = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    for _ in range(level):
        middle: dict = {}
        F = [f for a, b, c in F
             for ab, bc, ca in [[_midpoint(V, middle, i, j) for i, j in ((a, b), (b, c), (c, a))]]
             for f in ([a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca])]
    return np.array(V), np.array(F)


def _midpoint(V: list, middle: dict, i: int, j: int) -> int:
    """The index of the edge (i, j)'s midpoint pushed onto the unit sphere, added once."""
    key = (min(i, j), max(i, j))
    if key not in middle:
        m = np.add(V[i], V[j])
        V.append(list(m / np.linalg.norm(m)))
        middle[key] = len(V) - 1
    return middle[key]


CUBE_V = np.array([[x, y, z] for x in (0., 1.) for y in (0., 1.) for z in (0., 1.)])
#: the cube's six faces as quads, counter-clockwise seen from outside
CUBE_QUADS = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6],
                       [0, 2, 6, 4], [1, 5, 7, 3]])
CUBE_T = np.concatenate([CUBE_QUADS[:, [0, 1, 2]], CUBE_QUADS[:, [0, 2, 3]]])


def volume(V, T) -> float:
    """Divergence theorem with the field (x, 0, 0): V = Σ A n_x x̄ over the triangles."""
    a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    area_normal = 0.5 * np.cross(b - a, c - a)
    return float(np.sum(area_normal[:, 0] * (a[:, 0] + b[:, 0] + c[:, 0]) / 3))


def convex_inside(V, T, x) -> np.ndarray:
    """Inside a convex polyhedron: behind every face's plane."""
    a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    n = np.cross(b - a, c - a)
    return np.all(np.einsum("fk,pfk->pf", n, x[:, None, :] - a[None]) < 0, axis=1)


def lattice(lo, hi, h) -> np.ndarray:
    """Cell centres of spacing ``h`` filling the box [lo, hi]^3."""
    g = np.arange(lo + h / 2, hi, h)
    return np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)


def canonical(V, T) -> np.ndarray:
    """The triangles' corner coordinates, each rolled to start at its smallest corner (keeping
    its orientation), sorted: equal for the same surface whatever the vertex numbering."""
    P = np.round(V[T], 6)
    out = []
    for tri in P:
        k = min(range(3), key=lambda i: tuple(tri[i]))
        out.append(np.roll(tri, -k, axis=0).ravel())
    return np.array(sorted(map(tuple, out)))


# ---- reading ---------------------------------------------------------------------------------

WRITERS = [("sphere.stl", "stl", dict(binary=False)), ("sphere_b.stl", "stl", dict(binary=True)),
           ("sphere.obj", "obj", {}), ("sphere.ply", "ply", dict(binary=False)),
           ("sphere_b.ply", "ply", dict(binary=True))]


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize("name,fmt,options", WRITERS)
def test_round_trip_keeps_the_triangles(tmp_path, name, fmt, options):
    V, T = icosphere(2)
    meshio.write(tmp_path / name, meshio.Mesh(V, [("triangle", T)]), file_format=fmt, **options)
    V2, T2 = read_surface(tmp_path / name)
    assert V2.dtype == np.float64 and T2.dtype == np.int64 and V2.shape[1] == 3
    np.testing.assert_allclose(canonical(V2, T2), canonical(V, T), atol=2e-6)


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize("name,fmt", [("cube.obj", "obj"), ("cube.ply", "ply")])
def test_quads_become_two_triangles_each(tmp_path, name, fmt):
    meshio.write(tmp_path / name, meshio.Mesh(CUBE_V, [("quad", CUBE_QUADS)]), file_format=fmt)
    V, T = read_surface(tmp_path / name)
    assert T.shape == (12, 3)
    assert volume(V, T) == pytest.approx(1.0, abs=1e-12)


def test_obj_with_texture_normals_negative_indices_and_a_pentagon(tmp_path):
    path = tmp_path / "tet.obj"
    path.write_text("# a tetrahedron\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1 1.0\nvt 0 0\nvn 0 0 1\n"
                    "f 1/1/1 3/1/1 2/1/1\nf 1//1 2//1 4//1\nf -4 -1 -2\nf 2 3 4\n"
                    "o pentagon\nv 5 0 0\nv 6 0 0\nv 6 1 0\nv 5.5 2 0\nv 5 1 0\nf 5 6 7 8 9\n")
    V, T = read_surface(path)
    assert T[:4].tolist() == [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
    assert T[4:].tolist() == [[4, 5, 6], [4, 6, 7], [4, 7, 8]]
    assert volume(V, T[:4]) == pytest.approx(1 / 6, abs=1e-15)


def bad(tmp_path, name, content):
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    return path


PLY_HEAD = (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
            b"property double z\nelement face 1\nproperty list uint8 int32 vertex_indices\n"
            b"end_header\n")
GARBAGE = bytes(np.random.default_rng(1).integers(0, 256, 333, dtype=np.uint8))
BAD_FILES = [
    ("missing.stl", None, "not found"),
    ("empty.stl", b"", "is empty"), ("empty.obj", b"", "is empty"), ("empty.ply", b"", "is empty"),
    ("garbage.stl", GARBAGE, "cannot be read as STL"),
    ("garbage.obj", GARBAGE, "expected an OBJ text file"),
    ("latin.obj", "v 0 0 0\nf 1 2 3 # caf\u00e9\n".encode("latin-1"), "refers to vertices"),
    ("faces.obj", b"f 1 2 3\n", "holds no vertices (1 triangles)"),
    ("header.ply", b"ply\nformat ascii 1.0\nelement vertex 3\n", "has no PLY header"),
    ("garbage.ply", GARBAGE, "has no PLY header"),
    ("words.stl", b"hello world\n", "cannot be read as STL"),
    ("cut.stl", b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n", "cannot be read"),
    ("cut.ply", PLY_HEAD + b"0 0 0\n1 0 0\n", "cannot be read as PLY"),
    ("none.stl", b"solid x\nendsolid x\n", "no triangles"),
    ("points.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\n", "no triangles"),
    ("flat2d.obj", b"v 0 0\nv 1 0\nv 0 1\nf 1 2 3\n", "line 1 'v 0 0'"),
    ("word.obj", b"v 0 0 0\nv 1 0 zero\nv 0 1 0\nf 1 2 3\n", "line 2"),
    ("nan.obj", b"v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "vertex 0 is [0.0, 0.0, nan]"),
    ("inf.stl", b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 inf\nvertex 1 0 0\n"
     b"vertex 0 1 0\nendloop\nendfacet\nendsolid x\n", "not finite"),
    ("range.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n", "triangle 0 refers to vertices [0, 1, 6]"),
    ("before.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", "out of range"),
    ("range.ply", PLY_HEAD + b"0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n", "expected indices 0..2"),
    # issue 41: before, OverflowError (a traceback); the 10,000-digit one filled the screen
    ("int64.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 %d\n" % 2**70,
     "line 4: face index 1180591620717411303424 is beyond any vertex count"),
    ("digits.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 -2 1" + b"0" * 9999 + b"\n",
     "line 4: face index 10000000000000000000...00000000 (10000 digits) is beyond"),
    ("mesh.vtk", b"# vtk\n", "unknown extension '.vtk'"),
]


@pytest.mark.parametrize("name,content,expect", BAD_FILES)
def test_bad_files_give_one_line_naming_the_file(tmp_path, name, content, expect):
    path = bad(tmp_path, name, content)
    with pytest.raises(SceneError) as err:
        read_surface(path)
    message = str(err.value)
    assert "\n" not in message and f"'{path}'" in message and expect in message, message


def test_a_directory_is_refused(tmp_path):
    (tmp_path / "dir.stl").mkdir()
    with pytest.raises(SceneError, match="is a directory"):
        read_surface(tmp_path / "dir.stl")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_is_refused_without_opening_it(tmp_path):
    """Before: open() blocked until something wrote to the pipe (a subprocess: a hang fails)."""
    os.mkfifo(tmp_path / "pipe.stl")
    code = ("from parmpm.io.surface_file import read_surface\n"
            f"read_surface({str(tmp_path / 'pipe.stl')!r})")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "is not a regular file (a FIFO, device or socket)" in proc.stderr.splitlines()[-1]


# ---- winding number --------------------------------------------------------------------------

def test_one_triangle_sees_an_octant():
    """The triangle (e_x, e_y, e_z) covers one eighth of the sphere seen from the origin."""
    V, T = np.eye(3), np.array([[0, 1, 2]])
    x = np.zeros((1, 3))
    assert winding_numbers(V, T, x)[0] == pytest.approx(1 / 8, abs=1e-15)
    assert winding_numbers(V, T[:, ::-1], x)[0] == pytest.approx(-1 / 8, abs=1e-15)


def test_winding_number_is_one_inside_zero_outside():
    V, T = icosphere(2)
    rng = np.random.default_rng(2)
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    r = np.concatenate([rng.uniform(0, 0.8, 200), rng.uniform(1.2, 10, 200)])
    x = u * r[:, None]
    w = winding_numbers(V, T, x)
    np.testing.assert_allclose(w, (r < 1).astype(float), rtol=0, atol=1e-10)
    # the kernel through .py_func: the same numbers, readable failures
    corners = np.ascontiguousarray(V[T].reshape(-1, 9))
    out = np.zeros(8)
    winding_sum.py_func(corners, x[::50], np.ones(8, bool), out)
    np.testing.assert_allclose(out, (r[::50] < 1).astype(float), rtol=0, atol=1e-10)


@pytest.mark.parametrize("level", [1, 3])
def test_the_tree_stays_within_its_error_of_the_exact_sum(level):
    """The far clusters' expansion moves the winding number by under 0.05 (it is exact for a
    single leaf), so ``w >= 1/2`` classifies as the exact sum does; the compiled kernel and its
    ``.py_func`` agree."""
    V, T = icosphere(level)
    x = np.random.default_rng(3).uniform(-1.3, 1.3, (3000, 3))
    r = np.linalg.norm(x, axis=1)
    tree, todo = build_tree(np.ascontiguousarray(V[T].reshape(-1, 9))), np.ones(len(x), bool)
    w = np.zeros(len(x))
    tree_winding(*tree, x, todo, w)
    far = np.abs(r - 1) > 0.2
    np.testing.assert_allclose(w[far], (r[far] < 1).astype(float), rtol=0, atol=0.05)
    np.testing.assert_array_equal(w >= 0.5, convex_inside(V, T, x))
    w_py = np.zeros(60)
    tree_winding.py_func(*tree, x[::50], todo[::50], w_py)
    np.testing.assert_allclose(w_py, w[::50], rtol=0, atol=1e-12)


def test_the_lattice_volume_converges_to_the_polyhedron_volume():
    V, T = icosphere(2)
    exact = volume(V, T)
    assert 4.0 < exact < 4 * math.pi / 3
    area = float(np.sum(0.5 * np.linalg.norm(np.cross(V[T[:, 1]] - V[T[:, 0]],
                                                      V[T[:, 2]] - V[T[:, 0]]), axis=1)))
    errors = []
    for h in (0.2, 0.1, 0.05):
        x = lattice(-1.0, 1.0, h)
        inside = inside_surface(V, T, x)
        np.testing.assert_array_equal(inside, convex_inside(V, T, x))
        errors.append(abs(inside.sum() * h ** 3 - exact))
        assert errors[-1] < 0.5 * area * h  # at most half a cell's layer over the surface
    assert errors[2] < errors[1] < errors[0]


def test_the_cube_on_its_lattice_is_exact_and_a_turned_cube_converges():
    x = lattice(-0.5, 1.5, 0.1)
    assert inside_surface(CUBE_V, CUBE_T, x).sum() * 0.1 ** 3 == pytest.approx(1.0, abs=1e-12)
    a = 0.4
    Q = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    Q = Q @ np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    V = (CUBE_V - 0.5) @ Q.T
    errors = []
    for h in (0.1, 0.05, 0.025):
        x = lattice(-1.0, 1.0, h)
        inside = inside_surface(V, CUBE_T, x)
        np.testing.assert_array_equal(inside, convex_inside(V, CUBE_T, x))
        errors.append(abs(inside.sum() * h ** 3 - 1.0))
        assert errors[-1] < 0.5 * 6 * h
    assert errors[2] < errors[0]


def test_a_sphere_with_a_hole_still_classifies_points_away_from_it():
    V, T = icosphere(2)
    hole = T[7]
    h = 0.1
    x = lattice(-1.2, 1.2, h)
    centre = V[hole].mean(axis=0)
    reach = np.max(np.linalg.norm(V[hole] - centre, axis=1))
    away = np.linalg.norm(x - centre, axis=1) > reach + h
    inside = inside_surface(V, np.delete(T, 7, axis=0), x)
    np.testing.assert_array_equal(inside[away], convex_inside(V, T, x[away]))
    assert check_surface(V, np.delete(T, 7, axis=0), "holed").open_edges == 3


def test_flipped_surfaces_give_the_same_inside_set():
    V, T = icosphere(2)
    x = lattice(-1.2, 1.2, 0.1)
    expect = convex_inside(V, T, x)
    flipped = T[:, ::-1]
    np.testing.assert_array_equal(inside_surface(V, flipped, x), expect)
    summary = check_surface(V, flipped, "inward")
    assert summary.inward and summary.volume == pytest.approx(volume(V, T), rel=1e-12)
    assert winding_numbers(V, flipped, np.zeros((1, 3)))[0] == pytest.approx(-1, abs=1e-12)
    # a few flipped triangles: only the points near them may change
    some = [3, 100, 250]
    T2 = T.copy()
    T2[some] = T2[some][:, ::-1]
    centres = V[T[some]].mean(axis=1)
    away = np.min(np.linalg.norm(x[:, None] - centres[None], axis=2), axis=1) > 0.4
    np.testing.assert_array_equal(inside_surface(V, T2, x)[away], expect[away])
    assert check_surface(V, T2, "some").misoriented_edges == 9


def test_check_surface_counts_and_refusals():
    V, T = icosphere(1)
    s = check_surface(V, T, "ball")
    assert (s.open_edges, s.nonmanifold_edges, s.misoriented_edges, s.inward) == (0, 0, 0, False)
    assert s.volume == pytest.approx(volume(V, T), rel=1e-12)
    fin = np.vstack([V, [[3.0, 0.0, 0.0]]])
    assert check_surface(fin, np.vstack([T, [[T[0, 0], T[0, 1], len(V)]]]), "fin").nonmanifold_edges == 1
    sheet = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]])
    for tris, why in [([[0, 1, 2], [0, 2, 3]], "encloses no volume"),
                      ([[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2]], "encloses no volume"),
                      ([[0, 1, 1], [2, 2, 3]], "zero area")]:
        with pytest.raises(SceneError, match=why) as err:
            check_surface(sheet, np.array(tris), "plate.stl")
        assert "\n" not in str(err.value) and "'plate.stl'" in str(err.value)


@pytest.mark.parametrize("scale", [1e-150, 1e-3, 1e90])
def test_tiny_and_huge_bodies_are_the_same_body(scale):
    """The winding number is scale-free; the checks and the sum work on the unit-size surface,
    so nothing underflows (a 1e-150 m body is not 'flat') or overflows."""
    V, T = icosphere(1)
    x = lattice(-1.2, 1.2, 0.2)
    np.testing.assert_array_equal(inside_surface(V * scale, T, x * scale), convex_inside(V, T, x))
    s = check_surface(V * scale, T, "scaled")
    assert s.volume == pytest.approx(volume(V, T) * scale ** 3, rel=1e-12)
    np.testing.assert_allclose(winding_numbers(V * scale, T, np.zeros((1, 3))), [1.0], atol=1e-12)


def test_coordinates_beyond_floating_point_are_refused():
    V, T = icosphere(0)
    with pytest.raises(SceneError, match="beyond floating point"):
        check_surface(V * 1e308, T, "huge.stl")
