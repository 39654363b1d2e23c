"""Particles from the elements of a volume mesh: one per quadrature point, carrying that point's
exact share of its element's volume (pure numpy; the file is read by :mod:`parmpm.io.mesh_file`).

Each rule has positive weights and integrates every polynomial of degree 2 exactly over the
element, so the particles' volume, centroid and second moments are the mesh's own to round-off:

==============  ======================================================================  ======
``triangle``    3 interior points, barycentric (2/3, 1/6, 1/6) and permutations,        3
                weights 1/3 (Strang & Fix 1973)
``tetra``       4 points, barycentric (a, b, b, b), a = (5 + 3√5)/20, b = (5 − √5)/20,  4
                weights 1/4 (Keast 1986)
``quad``        2×2 Gauss–Legendre on the bilinear map                                  4
``hexahedron``  3×3×3 Gauss–Legendre on the trilinear map                               27
==============  ======================================================================  ======

Why these suffice on mapped elements: with x(ξ) bilinear, f(x(ξ)) of degree 2 has degree ≤ 2 in
each ξ_i and det J is affine in each ξ_i (quad), so the integrand has degree ≤ 3 per variable and
2-point Gauss is exact. On a trilinear hexahedron det J has degree ≤ 2 per variable and the
second-moment integrand ≤ 4, so 3-point Gauss is needed: 2×2×2 still gets the volume and centroid
(degree ≤ 3) but not the second moments unless det J is constant (parallelepipeds).

``split`` = s first divides each element uniformly into s^d sub-elements of equal reference
volume (simplices: Freudenthal's subdivision, Bey 2000; quads/hexahedra: an s^d grid of the
reference square/cube), then applies the rule in each: s^d times the particles, the same moments.
Particles come element by element, and within one in a fixed order: independent of MPI ranks.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from parmpm.core.errors import SceneError

#: the scene dimension of each element type
DIM = {"triangle": 2, "quad": 2, "tetra": 3, "hexahedron": 3}
NODES = {"triangle": 3, "quad": 4, "tetra": 4, "hexahedron": 8}
#: Gauss points per axis of the tensor-product rules
GAUSS = {"quad": 2, "hexahedron": 3}
#: reference corners of quads and hexahedra, in meshio's (VTK's and Gmsh's) node order
CORNERS = {"quad": np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float),
           "hexahedron": np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                                   [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], float)}
#: relative size (of L^d, L the element's largest node distance) below which it has no volume
DEGENERATE = 1e-12
#: particles made at a time: each element's Jacobians and checks are its own, so blocks give the
#: same bits as one pass with a fraction of its temporaries (a 10⁶-particle quad mesh: 119 MB
#: peak in one pass)
BLOCK_PARTICLES = 65_536


def _simplex_rule(d: int) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric points (q, d+1) and weights (q,) summing to 1, exact for degree 2."""
    if d == 2:
        a, b = 2.0 / 3.0, 1.0 / 6.0
    else:
        a, b = (5.0 + 3.0 * math.sqrt(5.0)) / 20.0, (5.0 - math.sqrt(5.0)) / 20.0
    lam = np.full((d + 1, d + 1), b)
    np.fill_diagonal(lam, a)
    return lam, np.full(d + 1, 1.0 / (d + 1))


def _freudenthal(d: int, s: int) -> np.ndarray:
    """The s^d sub-simplices of equal volume of a simplex, as barycentric vertices (s^d, d+1, d+1):
    the Kuhn simplices of an s-grid of the unit cube that lie in 1 ≥ y_1 ≥ … ≥ y_d ≥ 0, whose
    barycentrics on the corners (0,…,0), (1,0,…), …, (1,…,1) are (1−y_1, y_1−y_2, …, y_d)."""
    subs = []
    for origin in itertools.product(range(s), repeat=d):
        for perm in itertools.permutations(range(d)):
            y = [np.array(origin, float)]
            for axis in perm:
                y.append(y[-1] + np.eye(d)[axis])
            y = np.array(y) / s
            lam = np.column_stack([1.0 - y[:, 0]] + [y[:, i] - y[:, i + 1] for i in range(d - 1)]
                                  + [y[:, d - 1]])
            if np.all(lam >= -1e-14):
                subs.append(lam)
    assert len(subs) == s ** d
    return np.array(subs)


def simplex_points(d: int, split: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Reference rule of a split simplex: barycentric points (P, d+1), weights (P,) summing to 1."""
    lam, w = _simplex_rule(d)
    subs = _freudenthal(d, split)
    return np.einsum("qk,skl->sql", lam, subs).reshape(-1, d + 1), np.tile(w, len(subs)) / len(subs)


def tensor_points(cell_type: str, split: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Reference rule of a split quad/hexahedron on [-1, 1]^d: points (P, d), weights (P,) summing
    to 2^d (the reference volume)."""
    d, n = DIM[cell_type], GAUSS[cell_type]
    g, gw = np.polynomial.legendre.leggauss(n)
    pts1 = ((np.arange(split)[:, None] + 0.5 * (g[None, :] + 1.0)) * 2.0 / split - 1.0).reshape(-1)
    w1 = np.tile(gw / split, split)
    grids = np.meshgrid(*([pts1] * d), indexing="ij")
    wgrid = np.prod(np.meshgrid(*([w1] * d), indexing="ij"), axis=0)
    # order: sub-cell by sub-cell, then its Gauss points (element-major, deterministic)
    m = split
    shape = (m, n) * d
    order = list(range(0, 2 * d, 2)) + list(range(1, 2 * d, 2))
    xi = np.stack([gr.reshape(shape).transpose(order).reshape(-1) for gr in grids], axis=1)
    return xi, wgrid.reshape(shape).transpose(order).reshape(-1)


def shape_functions(cell_type: str, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bi/trilinear shape functions N (P, nodes) and their gradients dN (P, nodes, d) at ``xi``."""
    c = CORNERS[cell_type]
    d = c.shape[1]
    f = 0.5 * (1.0 + xi[:, None, :] * c[None, :, :])  # (P, nodes, d) per-axis factors
    N = np.prod(f, axis=2)
    dN = np.empty(f.shape)
    for a in range(d):
        others = np.prod(np.delete(f, a, axis=2), axis=2)
        dN[:, :, a] = 0.5 * c[None, :, a] * others
    return N, dN


def particles_per_element(cell_type: str, split: int = 1) -> int:
    """How many particles :func:`element_particles` makes per element of ``cell_type``."""
    q = DIM[cell_type] + 1 if cell_type in ("triangle", "tetra") else GAUSS[cell_type] ** DIM[cell_type]
    return q * split ** DIM[cell_type]


def _fail(label: str, e: int, cell_type: str, nodes: np.ndarray, centre: np.ndarray, what: str):
    where = ", ".join(f"{v:.6g}" for v in centre)
    raise SceneError(f"{label}: element {e} ({cell_type}, nodes {nodes.tolist()}, centre "
                     f"({where})) {what}")


def _check_inputs(points, cell_type, conn, split, label):
    if cell_type not in DIM:
        raise SceneError(f"{label}: element type {cell_type!r}; expected one of {', '.join(DIM)}")
    if isinstance(split, bool) or not isinstance(split, (int, np.integer)) or split < 1:
        raise SceneError(f"{label}: split {split!r}; expected an integer >= 1")
    d = DIM[cell_type]
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != d or not np.all(np.isfinite(p)):
        raise SceneError(f"{label}: nodes must be finite, shape (n, {d}) for {cell_type} elements; "
                         f"got shape {p.shape}")
    c = np.asarray(conn)
    if c.ndim != 2 or c.shape[1] != NODES[cell_type] or (c.size and c.dtype.kind not in "iu"):
        raise SceneError(f"{label}: {cell_type} connectivity must be integers of shape "
                         f"(n, {NODES[cell_type]}); got {c.dtype} {c.shape}")
    c = c.astype(np.int64)
    if c.size and (c.min() < 0 or c.max() >= len(p)):
        raise SceneError(f"{label}: {cell_type} connectivity names node {c.max() if c.max() >= len(p) else c.min()}"
                         f"; expected 0..{len(p) - 1}")
    return p, c, d, int(split)


def _measure_checks(label, cell_type, conn, X, total, corner_det, first):
    """Refuse degenerate, inverted or tangled elements (``total``: signed measure per element,
    ``corner_det``: (E, k) det J at corners and quadrature points, None for simplices)."""
    d = X.shape[2]
    size = np.max(np.linalg.norm(X - X[:, :1, :], axis=2), axis=1) ** d
    centre = X.mean(axis=1)
    noun = "area" if d == 2 else "volume"
    if not np.all(np.isfinite(total)):
        e = int(np.flatnonzero(~np.isfinite(total))[0])
        _fail(label, first + e, cell_type, conn[e], centre[e], f"has a {noun} that overflows; expected "
              "coordinates small enough to multiply (rescale the mesh)")
    tol = DEGENERATE * size
    flat = np.abs(total) <= tol
    tangled = np.zeros(len(total), dtype=bool)
    if corner_det is not None:  # det J of both signs (or zero) over one element
        tangled = np.any(corner_det <= tol[:, None], axis=1) & np.any(corner_det > tol[:, None], axis=1)
    bad = np.flatnonzero(flat | tangled | (total < 0))
    if not bad.size:
        return
    e = int(bad[0])
    say = lambda what: _fail(label, first + e, cell_type, conn[e], centre[e], what)  # noqa: E731
    if tangled[e]:
        say(f"is not convex or is tangled (det J {corner_det[e].min():.3g} <= 0 at a corner or "
            "quadrature point, > 0 elsewhere); expected a convex element")
    if flat[e]:
        say(f"has zero {noun} ({total[e]:.3g}); expected a non-degenerate element")
    order = "counter-clockwise nodes" if d == 2 else "nodes in Gmsh/VTK order (positive volume)"
    say(f"is inverted (signed {noun} {total[e]:.3g}); expected {order} (reorder them or flip the mesh)")


def element_particles(points, cell_type: str, conn, split: int = 1, label: str = "mesh",
                      first: int = 0, nodes=None):
    """Particles of the elements ``conn`` (E, nodes) over ``points`` (n, d): their positions
    x (N, d), volumes vol (N,) and element index (N,) (counted from ``first``), element by element
    (see the module docstring for the rules). A bad element raises a one-line SceneError starting
    with ``label`` and naming the element's index and its nodes: ``nodes`` (E, nodes), the file's
    numbers of ``conn``'s nodes where ``points`` holds only some of the file's (default ``conn``)."""
    points, conn, d, split = _check_inputs(points, cell_type, conn, split, label)
    nodes = conn if nodes is None else np.asarray(nodes)
    n = particles_per_element(cell_type, split)
    x, vol = np.empty((len(conn) * n, d)), np.empty(len(conn) * n)
    step = max(1, BLOCK_PARTICLES // n)  # elements at a time: the temporaries stay O(block)
    for a in range(0, len(conn), step):
        b = min(a + step, len(conn))
        with np.errstate(over="ignore", invalid="ignore"):
            xb, vb = _particles(points, cell_type, conn[a:b], split, label, first + a,
                                nodes[a:b])
        x[a * n:b * n] = xb.reshape(-1, d)
        vol[a * n:b * n] = vb.reshape(-1)
    return x, vol, np.repeat(np.arange(first, first + len(conn), dtype=np.int64), n)


def _particles(points, cell_type, conn, split, label, first, nodes):
    """Positions (E, P, d) and volumes (E, P) of the particles of each element, after the checks
    (``nodes``: ``conn`` as the file numbers it, for their messages)."""
    d = DIM[cell_type]
    X = points[conn]  # (E, nodes, d)
    if cell_type in ("triangle", "tetra"):
        edges = X[:, 1:, :] - X[:, :1, :]
        signed = np.linalg.det(edges.transpose(0, 2, 1)) / math.factorial(d)
        _measure_checks(label, cell_type, nodes, X, signed, None, first)
        lam, w = simplex_points(d, split)
        x = np.einsum("pk,ekd->epd", lam, X)
        vol = signed[:, None] * w[None, :]
    else:
        xi, w = tensor_points(cell_type, split)
        N, dN = shape_functions(cell_type, xi)
        x = np.einsum("pk,ekd->epd", N, X)
        det = np.linalg.det(np.einsum("pka,ekb->epba", dN, X))  # J_ba = dx_b/dξ_a
        _, dNc = shape_functions(cell_type, CORNERS[cell_type])
        corner = np.linalg.det(np.einsum("pka,ekb->epba", dNc, X))
        signed = det @ w
        _measure_checks(label, cell_type, nodes, X, signed,
                        np.concatenate([corner, det], axis=1), first)
        vol = det * w[None, :]
    return x, vol


def mesh_particles(points, blocks, split: int = 1, label: str = "mesh"):
    """:func:`element_particles` of every block ``(cell_type, conn, ...)`` in order, the element
    index counting through the blocks (a :class:`parmpm.io.mesh_file.VolumeMesh`'s ``blocks``)."""
    xs, vols, elems, first = [], [], [], 0
    for block in blocks:
        x, vol, elem = element_particles(points, block[0], block[1], split, label, first)
        xs.append(x)
        vols.append(vol)
        elems.append(elem)
        first += len(block[1])
    d = np.asarray(points).shape[1]
    if not xs:
        return np.empty((0, d)), np.empty(0), np.empty(0, np.int64)
    return np.concatenate(xs), np.concatenate(vols), np.concatenate(elems)


__all__ = ["element_particles", "mesh_particles", "particles_per_element", "simplex_points",
           "tensor_points"]
