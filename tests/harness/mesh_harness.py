"""Independent moments and small meshes for ``tests/geometry/test_mesh_geometry.py``.

The moments are closed forms that share nothing with :mod:`parmpm.geometry.mesh`'s quadrature:
the simplex second-moment formula, Green's theorem over a polygon's edges, and exact polynomial
algebra on the trilinear map of a hexahedron. The meshes are numpy triangulations of a square,
a disk, an annulus and a cube, written with meshio where a test wants a file.
"""
import itertools
import math

import meshio
import numpy as np
# ---------------------------------------------------------------- independent moments (closed forms)


def simplex_moments(X):
    """Volume, first and second moments of simplices X (E, d+1, d): V = |det|/d!,
    ∫x = V s/(d+1), ∫x xᵀ = V (Σ v vᵀ + s sᵀ)/((d+1)(d+2)) with s = Σ v."""
    d = X.shape[2]
    V = np.abs(np.linalg.det((X[:, 1:] - X[:, :1]).transpose(0, 2, 1))) / math.factorial(d)
    s = X.sum(axis=1)
    vv = np.einsum("eki,ekj->eij", X, X) + np.einsum("ei,ej->eij", s, s)
    return V.sum(), (V[:, None] * s).sum(0) / (d + 1), (V[:, None, None] * vv).sum(0) / ((d + 1) * (d + 2))


def polygon_moments(X):
    """Green's theorem over the edges of counter-clockwise polygons X (E, k, 2)."""
    x, y = X[..., 0], X[..., 1]
    x1, y1 = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    c = x * y1 - x1 * y
    A = c.sum() / 2
    m1 = np.array([((x + x1) * c).sum(), ((y + y1) * c).sum()]) / 6
    xx = ((x * x + x * x1 + x1 * x1) * c).sum() / 12
    yy = ((y * y + y * y1 + y1 * y1) * c).sum() / 12
    xy = ((x * y1 + 2 * x * y + 2 * x1 * y1 + x1 * y) * c).sum() / 24
    return A, m1, np.array([[xx, xy], [xy, yy]])


def _pmul(a, b):
    """Product of polynomials in (ξ, η, ζ) stored as coefficient arrays c[i, j, k] of ξ^i η^j ζ^k."""
    out = np.zeros(tuple(p + q - 1 for p, q in zip(a.shape, b.shape)))
    for idx in zip(*np.nonzero(a)):
        out[tuple(slice(i, i + n) for i, n in zip(idx, b.shape))] += a[idx] * b
    return out


def _pint(c):
    """∫ over [-1, 1]^3 of a coefficient array: Π 2/(i+1) for even powers, 0 for odd."""
    m = [np.array([2.0 / (i + 1) if i % 2 == 0 else 0.0 for i in range(n)]) for n in c.shape]
    return np.einsum("ijk,i,j,k->", c, *m)


HEX_CORNERS = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                        [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]])


def hex_moments(X):
    """Exact moments of trilinear hexahedra X (E, 8, 3) by polynomial algebra: x(ξ) and det J as
    coefficient arrays, the integrand multiplied out and integrated monomial by monomial."""
    V, m1, m2 = 0.0, np.zeros(3), np.zeros((3, 3))
    for nodes in X:
        xs = []
        for b in range(3):
            c = np.zeros((2, 2, 2))
            for n, corner in enumerate(HEX_CORNERS):  # N_n = Π (1 + c_a ξ_a)/2
                c += nodes[n, b] / 8 * np.einsum("i,j,k->ijk", *[np.array([1.0, s]) for s in corner])
            xs.append(c)
        J = [[np.roll(xs[b] * (np.arange(2)[:, None, None] if a == 0 else np.arange(2)[None, :, None]
                               if a == 1 else np.arange(2)[None, None, :]), -1, axis=a)
              for a in range(3)] for b in range(3)]  # d x_b / d ξ_a
        det = np.zeros((1, 1, 1))
        for perm in itertools.permutations(range(3)):
            sign = np.linalg.det(np.eye(3)[list(perm)])
            det = _padd(det, sign * _pmul(_pmul(J[0][perm[0]], J[1][perm[1]]), J[2][perm[2]]))
        V += _pint(det)
        for i in range(3):
            xd = _pmul(xs[i], det)
            m1[i] += _pint(xd)
            for j in range(3):
                m2[i, j] += _pint(_pmul(xs[j], xd))
    return V, m1, m2


def _padd(a, b):
    shape = tuple(max(p, q) for p, q in zip(a.shape, b.shape))
    out = np.zeros(shape)
    out[tuple(slice(0, n) for n in a.shape)] += a
    out[tuple(slice(0, n) for n in b.shape)] += b
    return out


def particle_moments(x, vol):
    return vol.sum(), vol @ x, np.einsum("n,ni,nj->ij", vol, x, x)


def assert_same_moments(got, want, L, tol=1e-12):
    """Relative agreement: volume by V, first moments by V L, second by V L²."""
    V = want[0]
    assert abs(got[0] - V) <= tol * V, (got[0], V)
    assert np.max(np.abs(got[1] - want[1])) <= tol * V * L, (got[1], want[1])
    assert np.max(np.abs(got[2] - want[2])) <= tol * V * L * L, (got[2], want[2])


def rel_errors(got, want, L):
    V = want[0]
    return (abs(got[0] - V) / V, np.max(np.abs(got[1] - want[1])) / (V * L),
            np.max(np.abs(got[2] - want[2])) / (V * L * L))

# ---------------------------------------------------------------- meshes built here


def square_tri(n=6, seed=1):
    """[1, 3] × [-1, 1] split into n² squares, two triangles each, interior nodes jiggled."""
    g = np.linspace(0.0, 1.0, n + 1)
    X, Y = np.meshgrid(g, g, indexing="ij")
    rng = np.random.default_rng(seed)
    jig = rng.uniform(-0.25, 0.25, X.shape + (2,)) / n
    jig[[0, -1], :, :] = 0
    jig[:, [0, -1], :] = 0
    pts = np.stack([X, Y], -1) + jig
    pts = (pts * 2.0 + [1.0, -1.0]).reshape(-1, 2)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return pts, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def polar(r_in, r_out, m, n_theta, centre=(0.3, -0.2)):
    """Rings of nodes between r_in and r_out (m+1 rings, a centre node if r_in = 0): the
    quads between rings, counter-clockwise, and the centre's fan of triangles."""
    t = 2 * np.pi * np.arange(n_theta) / n_theta
    radii = np.linspace(r_in, r_out, m + 1)
    rings = radii[1:] if r_in == 0 else radii
    pts = [np.zeros((1, 2))] if r_in == 0 else []
    pts += [np.stack([r * np.cos(t), r * np.sin(t)], 1) for r in rings]
    pts = np.concatenate(pts) + centre
    first = 1 if r_in == 0 else 0
    ring = lambda k: first + k * n_theta + np.arange(n_theta)  # noqa: E731
    quads = np.concatenate([np.stack([ring(k), ring(k + 1), np.roll(ring(k + 1), -1), np.roll(ring(k), -1)], 1)
                            for k in range(len(rings) - 1)]) if len(rings) > 1 else np.zeros((0, 4), int)
    fan = np.stack([np.zeros(n_theta, int), ring(0), np.roll(ring(0), -1)], 1) if r_in == 0 else None
    return pts, quads, fan


def polar_tri(r_in, r_out, m, n_theta):
    pts, quads, fan = polar(r_in, r_out, m, n_theta)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return pts, tris if fan is None else np.concatenate([fan, tris])


def write(tmp_path, name, pts, cells, **kw):
    """Write with meshio; 2D nodes get z = 0 (as Gmsh and VTK store them)."""
    if pts.shape[1] == 2:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    path = tmp_path / name
    fmt = {"msh": "gmsh22"}.get(name.rsplit(".", 1)[1])
    if fmt:  # Gmsh wants its tags
        kw.setdefault("cell_data", {"gmsh:physical": [np.ones(len(c[1]), int) for c in cells],
                                    "gmsh:geometrical": [np.ones(len(c[1]), int) for c in cells]})
    binary = {"binary": fmt is None} if name.endswith((".msh", ".vtu")) else {}
    meshio.write(path, meshio.Mesh(pts, cells, **kw), file_format=fmt, **binary)
    return path


def write_gmsh22_per_group(path, pts, tris, groups):
    """A Gmsh 2.2 ASCII file as Gmsh writes one whose triangles are in several physical groups:
    each triangle listed once per group holding it (``groups``: name -> boolean mask over
    ``tris``), same element number each time. meshio's writer cannot make such a file."""
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", str(len(groups))]
    lines += [f'2 {k + 1} "{name}"' for k, name in enumerate(groups)]
    lines += ["$EndPhysicalNames", "$Nodes", str(len(pts))]
    lines += [f"{i + 1} {float(x)!r} {float(y)!r} 0" for i, (x, y) in enumerate(pts)]
    rows = [f"{e + 1} 2 2 {k + 1} 1 " + " ".join(str(n + 1) for n in t)
            for e, t in enumerate(tris) for k, mask in enumerate(groups.values()) if mask[e]]
    lines += ["$EndNodes", "$Elements", str(len(rows)), *rows, "$EndElements", ""]
    path.write_text("\n".join(lines))
    return path


TRI_MESHES = {"square": lambda: square_tri(), "disk": lambda: polar_tri(0.0, 1.5, 4, 24),
              "annulus": lambda: polar_tri(0.5, 1.5, 4, 24)}

def cube_grid(n, offset=(2.0, -1.0, 0.5)):
    g = np.linspace(0, 1, n + 1)
    pts = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3) + offset
    idx = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    c = lambda i, j, k: idx[i:n + i, j:n + j, k:n + k].ravel()  # noqa: E731
    hexes = np.stack([c(0, 0, 0), c(1, 0, 0), c(1, 1, 0), c(0, 1, 0),
                      c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)], 1)
    return pts, hexes


def kuhn_tets(pts, hexes):
    """Six tetrahedra per hexahedron around its diagonal 0-6, positively oriented (as Gmsh)."""
    kuhn = [[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]]
    tets = np.concatenate([hexes[:, k] for k in kuhn])
    V = np.linalg.det((pts[tets[:, 1:]] - pts[tets[:, :1]]).transpose(0, 2, 1))
    tets[V < 0] = tets[V < 0][:, [0, 2, 1, 3]]
    return tets


def gauss_2x2x2(X):
    """What a 2×2×2 rule would give (for the claim that it is not enough)."""
    g = np.array([-1, 1]) / np.sqrt(3)
    xi = np.array(list(itertools.product(g, g, g)))
    f = 0.5 * (1 + xi[:, None, :] * HEX_CORNERS[None])
    N = f.prod(2)
    dN = np.stack([0.5 * HEX_CORNERS[None, :, a] * np.delete(f, a, 2).prod(2) for a in range(3)], 2)
    x = np.einsum("pk,ekd->epd", N, X).reshape(-1, 3)
    det = np.linalg.det(np.einsum("pka,ekb->epab", dN, X)).reshape(-1)
    return particle_moments(x, det)


def analytic_ring(r_in, r_out, centre=(0.3, -0.2)):
    c = np.asarray(centre)
    A = np.pi * (r_out ** 2 - r_in ** 2)
    return A, A * c, np.pi * (r_out ** 4 - r_in ** 4) / 4 * np.eye(2) + A * np.outer(c, c)
