"""Symmetry faces: the mirror condition, the slip face that stays second-order for wide supports.

A ``"slip"`` face zeroes the normal velocity on the face's node and on every node beyond it.
That is exact for the hat function, whose particles never weight a node beyond the face, but a
quadratic B-spline particle within half a cell of the face weights the node one cell beyond it,
and the velocity field of a symmetric motion there is ``v_n(−Δx) = −v_n(+Δx)``, not 0: holding it
at 0 is an O(Δx) error that makes B-spline MPM first order on the manufactured solution
(Steffen, Kirby & Berzins 2008 discuss such boundary losses).

A ``"symmetry"`` face is a mirror: the body continues beyond the face as its reflection
(docs/symmetry.md). On the grid that is exact and local. Each patch folds its own P2G partial
sums before the ghost-layer accumulation (the fold is linear, so the owners' totals are the
folded totals, and the per-patch work does not depend on which rank holds the patch): every node
``f + j`` on the body's side adds the reflection ``R`` (the normal component's sign flipped) of
node ``f − j`` beyond the face, which is what the image particles would have given it; the face
node's normal momentum and force vanish (real and image cancel); every node beyond the face then
holds the reflection of its mirror. The grid update is pointwise, so the nodes beyond the face
come out as the mirrors of their twins as long as gravity is reflected there too
(:func:`parmpm.grid.update.reflected_gravity`); on the face node the normal velocity is held at 0. Folds run axis
after axis (reflections commute), so a corner between two symmetry faces gets its doubly
reflected image.

A ``"clamped"`` face is the odd mirror, for a body attached to a rigid face: the image moves
with the opposite velocity (``v(f − j) = −v(f + j)``, every component), the natural extension
of a field that vanishes on the face, so a B-spline particle near a clamp sees a velocity that
is linear through the face instead of one held at 0 on the node beyond it (what ``"fixed"``
does, a first-order error for the B-spline). The fold is the same with every vector component
flipped; the face node is held at ``v = 0``.

The node beyond the face carries the image's mass, so an energy sum over the grid skips those
nodes (:func:`parmpm.grid.update.beyond_mirror`), and the face node keeps its own (not doubled) mass: its velocity
is the same either way, and the sum over the remaining nodes is then exactly the body's half.
"""
from __future__ import annotations

import numpy as np

from parmpm.grid.update import CLAMPED, SYMMETRY, is_mirror
from parmpm.core.jit import helper_kernel, kernel


def row_signs(d: int, bc: np.ndarray) -> np.ndarray:
    """(3, 2, 1 + 2d) sign of each row of the P2G block (m, mv, f) under the reflection across
    face ``(k, side)``: the mass keeps its sign; across a symmetry face the vectors' component
    ``k`` flips (an even mirror), across a clamped face every component (an odd mirror)."""
    signs = np.ones((3, 2, 1 + 2 * d))
    for k in range(d):
        for side in range(2):
            if bc[k, side] == SYMMETRY:
                signs[k, side, 1 + k] = signs[k, side, 1 + d + k] = -1.0
            elif bc[k, side] == CLAMPED:
                signs[k, side, 1:] = -1.0
    return signs


def mirror_faces(bc: np.ndarray) -> np.ndarray:
    """(3, 2) bool: which faces are mirrors (symmetry or clamped)."""
    return np.vectorize(is_mirror, otypes=[bool])(np.asarray(bc))


def check_blocks(layout, face_lo, face_hi, bc) -> str | None:
    """None when every patch's local block (owned nodes and ghosts) holds the mirror of each of
    its nodes beyond a mirror face, else a one-line explanation (the same on every rank: it
    reads only the global layout). Holds whenever the exterior layer is no wider than the ghost
    layer and a patch at least that wide, so in practice it guards a user's ``grid.exterior``."""
    sym = mirror_faces(bc)
    coords = layout.patch_coords()
    lo = layout.local_base(coords)
    hi = lo + layout.local_nodes3 - 1  # inclusive
    last = np.asarray(layout.global_nodes3) - 1
    for k in range(3):
        for side in range(2):
            if not sym[k, side]:
                continue
            if side == 0:
                f = int(face_lo[k])
                far = np.maximum(lo[:, k], 0)  # the farthest node beyond the face, per block
                bad = (lo[:, k] < f) & (2 * f - far > hi[:, k])
                width = f
            else:
                f = int(face_hi[k])
                far = np.minimum(hi[:, k], last[k])
                bad = (hi[:, k] > f) & (2 * f - far < lo[:, k])
                width = int(last[k]) - f
            if np.any(bad):
                face = "xyz"[k] + ("_min" if side == 0 else "_max")
                kind = "symmetry" if bc[k, side] == SYMMETRY else "clamped"
                return (f"boundary.{face} = \"{kind}\" reflects the exterior layer into the "
                        f"patches that hold it, but a patch of {int(layout.psize3[k])} cells with "
                        f"{int(layout.ghost3[k])} ghost cells cannot hold the mirror of an exterior "
                        f"layer of {width} cells; use a larger grid.patch_size or a narrower "
                        f"grid.exterior")
    return None


@kernel
def fold_sums(d, nloc, base, face_lo, face_hi, sym, signs, first, last, block):
    """The image's contribution, added on the body's side of every mirror face to the rows
    ``first..last - 1`` (:func:`row_signs`) of every patch's local block (before the ghost
    accumulation: partial sums); the face node's flipped rows are zeroed, and the nodes beyond
    the face take the reflection of their (folded) mirror."""
    for k in range(d):
        for side in range(2):
            if sym[k, side]:
                f = face_lo[k] if side == 0 else face_hi[k]
                _fold_axis(nloc, base, k, side, f, signs[k, side], first, last, block, 0)


@kernel
def reflect_beyond(d, nloc, base, face_lo, face_hi, sym, signs, block):
    """Every node beyond a mirror face takes the reflection (``signs``: per face, per row of
    ``block``) of its twin on the body's side, and nothing else changes: after a correction that
    is not the same at a node and its mirror (contact's, which sees real particles only), the
    nodes beyond again hold what the images would have given them."""
    for k in range(d):
        for side in range(2):
            if sym[k, side]:
                f = face_lo[k] if side == 0 else face_hi[k]
                _fold_axis(nloc, base, k, side, f, signs[k, side], 0, block.shape[1], block, 1)


@helper_kernel
def _fold_axis(nloc, base, k, side, f, sign, first, last, block, skip):
    """One face: node lines along axis ``k`` (``stride`` apart), the body's side first (``skip``
    1: only the nodes beyond)."""
    stride = 1
    for a in range(k):
        stride *= nloc[a]
    n_k = nloc[k]
    outer = 1
    for a in range(k + 1, 3):
        outer *= nloc[a]
    for p in range(block.shape[0]):
        B = block[p]
        b = base[p, k]
        for beyond in range(skip, 2):  # 0: the face and the body's side; 1: the nodes beyond
            for ik in range(n_k):
                dist = (b + ik - f) if side == 0 else (f - b - ik)  # > 0: the body's side
                if (dist < 0) != (beyond == 1):
                    continue
                im = ik - 2 * dist if side == 0 else ik + 2 * dist
                if dist != 0 and (im < 0 or im >= n_k):
                    continue  # the mirror is outside this block (check_blocks: never beyond)
                for o in range(outer):
                    for i in range(stride):
                        node = i + stride * (ik + n_k * o)
                        mnode = i + stride * (im + n_k * o)
                        if dist == 0:
                            for r in range(first, last):
                                if sign[r] < 0.0:
                                    B[r, node] = 0.0
                        elif dist > 0:
                            for r in range(first, last):
                                B[r, node] += sign[r] * B[r, mnode]
                        else:
                            for r in range(first, last):
                                B[r, node] = sign[r] * B[r, mnode]


@kernel
def fold_moments(d, nloc, base, face_lo, face_hi, sym, origin, h, mass, X):
    """Contact's first moments ``X`` (rows ``1..d``: ``Σ S m x``) with the images' added, as
    :func:`fold_sums` adds their mass: an image's position is the reflection of its particle's
    whatever the face's kind (the odd mirror flips velocities, not places), so across the plane
    ``x_k = c`` its moment is ``2 c m' − X_k`` along ``k`` and ``X`` across it. ``mass``: a copy
    of the unfolded mass row (slots, 1, stride), folded here axis by axis alongside; the face
    node's moment along ``k`` is its mass at the face (its image's centre and its own meet
    there). Call it before :func:`fold_sums` folds the mass itself."""
    for k in range(d):
        for side in range(2):
            if sym[k, side]:
                f = face_lo[k] if side == 0 else face_hi[k]
                _fold_moments_axis(nloc, base, k, side, f, origin[k] + f * h[k], mass, X)


@helper_kernel
def _fold_moments_axis(nloc, base, k, side, f, c, mass, X):
    """One face (:func:`_fold_axis`'s walk), the plane at ``x_k = c``."""
    stride = 1
    for a in range(k):
        stride *= nloc[a]
    n_k = nloc[k]
    outer = 1
    for a in range(k + 1, 3):
        outer *= nloc[a]
    rows = X.shape[1]
    for p in range(X.shape[0]):
        b = base[p, k]
        for beyond in range(2):
            for ik in range(n_k):
                dist = (b + ik - f) if side == 0 else (f - b - ik)
                if (dist < 0) != (beyond == 1):
                    continue
                im = ik - 2 * dist if side == 0 else ik + 2 * dist
                if dist != 0 and (im < 0 or im >= n_k):
                    continue
                for o in range(outer):
                    for i in range(stride):
                        node = i + stride * (ik + n_k * o)
                        mnode = i + stride * (im + n_k * o)
                        if dist == 0:
                            X[p, 1 + k, node] = c * mass[p, 0, node]
                            continue
                        m_img = mass[p, 0, mnode]
                        keep = 1.0 if dist > 0 else 0.0  # beyond: the reflection alone
                        for r in range(1, rows):
                            img = X[p, r, mnode]
                            if r == 1 + k:
                                img = 2.0 * c * m_img - img
                            X[p, r, node] = keep * X[p, r, node] + img
                        mass[p, 0, node] = keep * mass[p, 0, node] + m_img
