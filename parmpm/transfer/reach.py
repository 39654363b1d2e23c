"""Why a particle's support is out of bounds, in one line: how far it reaches, whether it stays
on the grid, which face it crosses and what would hold it (``grid.exterior``, ``method.lcr``,
``grid.ghost``). Called only when a step has found such a particle, so plain numpy is fine here.
"""
from __future__ import annotations

import math

import numpy as np

from parmpm.shapes import BSPLINE, CPDI, CPDI2, CPGIMP, MPM
from parmpm.shapes.cpdi2 import SCRATCH_SHAPE, cap_corners, domain_weights
from parmpm.shapes.scaling import longest_corner
from parmpm.shapes.support import domain_matrix

from parmpm.transfer.discretisation import Discretisation


#: the point methods' support half-width in cells: the hat's one cell, the quadratic B-spline's
#: one and a half (a particle closer to the grid's face than that has a node off the grid)
GRID_SUPPORT = {MPM: 1.0, BSPLINE: 1.5}


def fmt_vec(v) -> str:
    return "(" + ", ".join(f"{float(c):.4g}" for c in np.atleast_1d(v)) + ")"


def support_reach(D: Discretisation, P, i: int) -> tuple[float, bool]:
    """(Longest reach of particle ``i``'s support from its centre, is the support on the grid?)."""
    # ``P``: the particle rows (``Particles.rows``); ``i``: a physical row
    if D.method == CPDI:
        R = np.zeros((3, 3))
        domain_matrix(D.dim, D.method, D.lcr, P.F[i], P.r0[i], R)
        reach = longest_corner(D.dim, R)
    elif D.method == CPDI2:
        reach = float(np.max(np.linalg.norm(capped_corners(D, P, i), axis=1)))
    elif D.method == CPGIMP:
        reach = float(np.max(P.lh0[i] * np.abs(np.diag(P.F[i]))))
    elif D.method in GRID_SUPPORT:
        reach = float(np.max(GRID_SUPPORT[D.method] * D.h[:D.dim]))
    else:
        reach = float(np.max(P.lh0[i]))
    x, half = P.x[i], support_half_widths(D, P, i)
    inside = (np.all(x - half >= D.origin)
              and np.all(x + half <= D.origin + D.h * np.asarray(D.layout.cells)))
    return reach, bool(inside)


def support_half_widths(D: Discretisation, P, i: int) -> np.ndarray:
    """Half-extent per axis of particle ``i``'s support about its centre: the GIMP half-widths,
    the bounding box of the CPDI corners ``x ± Σ_k |R_ak|`` (as interpolated, after scaling; for
    CPDI2 the largest ``|ĉ_αk|`` of its capped corners), or the grid-sized support of the point
    methods (:data:`GRID_SUPPORT`)."""
    # ``P``: the particle rows (``Particles.rows``); ``i``: a physical row
    d = D.dim
    if D.method == CPDI2:
        return np.abs(capped_corners(D, P, i)).max(axis=0)
    if D.method == CPDI:
        R = np.zeros((3, 3))
        domain_matrix(d, D.method, D.lcr, P.F[i], P.r0[i], R)
        return np.abs(R[:d, :d]).sum(axis=1)
    if D.method == CPGIMP:
        return P.lh0[i] * np.abs(np.diag(P.F[i]))
    if D.method in GRID_SUPPORT:
        return GRID_SUPPORT[D.method] * np.asarray(D.h[:d], float)
    return np.array(P.lh0[i], float)


def capped_corners(D: Discretisation, P, i: int) -> np.ndarray:
    """Particle ``i``'s CPDI2 corners as interpolated (after the ``l_cr`` cap), (2^d, d)."""
    d, sc = D.dim, np.zeros(SCRATCH_SHAPE)
    cap_corners(d, np.ascontiguousarray(P.corners[i]), D.lcr, sc)
    return sc[:1 << d, :d].copy()


def inverted_message(D: Discretisation, P, i: int, phase: str) -> str:
    """The one-line explanation of a CPDI2 particle whose domain has turned inside out (its
    capped corners enclose a volume <= 0, or a corner is not finite)."""
    d = D.dim
    sc = np.zeros(SCRATCH_SHAPE)
    sc[:1 << d, :d] = capped_corners(D, P, i)
    vol = domain_weights(d, sc)
    size = {1: "length", 2: "area"}.get(d, "volume")
    return (f"domain of particle {P.gid[i]} at {fmt_vec(P.x[i])} inverted in {phase} (its "
            f"corners, as interpolated, span a signed {size} of {vol:.4g}, not positive: the "
            "grid velocity turned it inside out); reduce time.cfl, refine the grid or cap the "
            "corners with method.lcr")


def reach_message(D: Discretisation, P, bc: np.ndarray, i: int, phase: str) -> str:
    """The one-line explanation of a particle whose support leaves its patch's ghost layer."""
    # ``P``: the particle rows (``Particles.rows``); ``i``: a physical row
    g, dmin = D.layout.ghost, float(D.h.min())
    reach, inside = support_reach(D, P, i)
    x = P.x[i]
    where = "beyond the ghost layer of its patch" if inside else "outside the grid"
    hint = (f"use method.lcr <= {g}dx ({g * dmin:.4g} m) or a larger grid.ghost"
            if inside else outside_hint(D, bc, x, support_half_widths(D, P, i)))
    return (f"particle {P.gid[i]} at {fmt_vec(x)} reaches {where} in {phase} "
            f"(domain reach {reach:.4g} m = {reach / dmin:.3g} cells, ghost width {g} cells); {hint}")


def grid_extent(D: Discretisation) -> str:
    """The computational grid's box in words, saying when it includes an exterior layer."""
    text = f"origin {fmt_vec(D.origin)}, extent {fmt_vec(D.origin + D.h * D.layout.cells)}"
    if np.any(D.exterior_lo) or np.any(D.exterior_hi):
        text += " with the grid.exterior layer"
    return text


def outside_hint(D: Discretisation, bc: np.ndarray, x: np.ndarray, half: np.ndarray) -> str:
    """What would hold a support of half-widths ``half`` at ``x`` that crosses the grid's edge:
    the face it crosses, by how many cells, and the ``grid.exterior`` layer (cells kept outside
    every face, the boundary conditions staying on the faces) that holds such a support wherever
    its centre is inside the physical grid; past a free face, adding cells there also does."""
    lo = D.origin
    hi = D.origin + D.h * np.asarray(D.layout.cells)
    for k in range(D.dim):
        for side, past in ((0, lo[k] - (x[k] - half[k])), (1, x[k] + half[k] - hi[k])):
            if past <= 0:
                continue
            face = f"{'xyz'[k]}_{('min', 'max')[side]}"
            cells = math.ceil(past / D.h[k] - 1e-9)
            pad = (D.exterior_lo, D.exterior_hi)[side][k]
            # the ghost width holds any bounded support whose centre is inside the physical grid
            need = max(int(D.layout.ghost), math.ceil(half[k] / D.h[k] - 1e-9), int(pad) + cells)
            text = (f"it crosses the {face} face by {past / D.h[k]:.3g} cells: set grid.exterior = "
                    f"{need} (cells kept outside every face; the boundary conditions stay on the faces)")
            if bc[k, side] == 0:  # a free face: moving it outwards changes nothing else
                text += (f" or add {cells} cell{'s' * (cells != 1)} on the {face} side "
                         "(grid.cells, grid.origin)")
            return text
    return "enlarge the grid"
