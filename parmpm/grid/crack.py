"""Crack faces from the damage field (Homel & Herbold 2017, field-gradient partitioning): where a
node is near broken material, the particles on the two sides of the crack go to two velocity
fields at that node, which then meet through the contact of :mod:`parmpm.grid.contact` — the
faces open, close and slide instead of healing through a shared velocity.

The side of a particle is per node, not per particle:

* the damage field on the grid, ``D_i = Σ_p S_ip m_p D_p / Σ_p S_ip m_p``, and each particle's
  damage gradient ``g_p = Σ_i D_i ∇S_ip`` (which points from the particle towards the crack);
* each node's crack normal ``n_i``: the principal axis of ``T_i = Σ_p S_ip m_p g_p g_pᵀ`` (the
  line the gradients around the node lie along, whichever side they come from: a sum of the
  gradients themselves cancels at a node in the crack), turned to point along
  ``s_i = Σ_p S_ip m_p g_p`` (at a node on one side only, so that a particle whose gradient is
  zero, far from the damage, takes the same field as its neighbours that see it);
* a node has a crack when the most damaged particle reaching it has ``D >= crack_damage``
  (``[contact] crack_damage``); there particle ``p`` goes to the far-side field when
  ``g_p · n_i < 0`` (:func:`crack_field`), elsewhere all to their body's field.

Every sum is P2G's, combined over the ghost layers in the fixed order the grid sums use, and the
largest damage by a maximum, so the sides — and the run — are the same on any number of ranks.
``docs/concepts/contact.md`` says what was measured.
"""
import math

import numpy as np

from parmpm.core.jit import helper_kernel, kernel
from parmpm.materials.damage import largest_eigenvalue_sym3


@helper_kernel
def crack_field(sides, i, p, node):
    """The field of row ``i`` at node ``node`` of slot ``p`` (``sides``:
    :data:`parmpm.core.records.Sides`)."""
    s = 0.0
    for a in range(3):
        s += sides.grad[i, a] * sides.normal[p, a, node]
    return sides.field[i] + sides.fields if s < 0.0 else sides.field[i]


@helper_kernel
def pair_field(sides, field, i, p, node):
    """Row ``i``'s field at a node: its body's (``field[i]``) without cracks (``sides`` None)."""
    if sides is None:
        return field[i]
    return crack_field(sides, i, p, node)


@helper_kernel
def to_fields(sides, i, p, n, idx):
    """Move row ``i``'s ``n`` support entries ``idx`` (nodes of slot ``p``'s box) to their
    fields' copies in the stacked grid (field ``k``'s node ``j`` at ``j + k · stride``, the
    stride the box's node count, so that ``idx % stride`` is still the node); nothing without
    cracks (``sides`` None)."""
    if sides is None:
        return
    for e in range(n):
        idx[e] = field_node(sides, i, p, idx[e])


@helper_kernel
def field_node(sides, i, p, node):
    """Row ``i``'s copy of node ``node`` of slot ``p`` in the stacked grid: the node itself
    without cracks (``sides`` None)."""
    if sides is None:
        return node
    return node + crack_field(sides, i, p, node) * sides.stride


@kernel
def nodal_damage(nodes, sums):
    """``sums[p, 1, node] ← D_i = Σ S m D / Σ S m`` (0 where no mass) at the owned nodes
    (``sums``: (slots, 2, stride) rows ``Σ S m``, ``Σ S m D``)."""
    own_lo, own_hi, base, nloc, face_lo, face_hi = nodes
    L0, L1 = nloc[0], nloc[1]
    for p in range(own_lo.shape[0]):
        for i2 in range(own_lo[p, 2], own_hi[p, 2]):
            for i1 in range(own_lo[p, 1], own_hi[p, 1]):
                row0 = L0 * (i1 + L1 * i2)
                for i0 in range(own_lo[p, 0], own_hi[p, 0]):
                    node = row0 + i0
                    m = sums[p, 0, node]
                    sums[p, 1, node] = sums[p, 1, node] / m if m > 0.0 else 0.0


@helper_kernel
def _principal_axis(d, t, out):
    """The unit principal axis of the symmetric ``t`` (rows of :func:`crack_normals`' sums:
    ``s`` then the upper triangle of ``T``) into ``out``; False when ``T`` is zero."""
    if d == 1:
        if not t[1] > 0.0:
            return False
        out[0] = 1.0
        return True
    if d == 2:
        a, b, c = t[2], t[3], t[4]
        if not a + c > 0.0:
            return False
        theta = 0.5 * math.atan2(2.0 * b, a - c)
        out[0] = math.cos(theta)
        out[1] = math.sin(theta)
        return True
    a00, a01, a02, a11, a12, a22 = t[3], t[4], t[5], t[6], t[7], t[8]
    if not a00 + a11 + a22 > 0.0:
        return False
    lam = largest_eigenvalue_sym3(a00, a01, a02, a11, a12, a22)
    # the eigenvector is the largest cross product of two rows of T − λI
    r0 = (a00 - lam, a01, a02)
    r1 = (a01, a11 - lam, a12)
    r2 = (a02, a12, a22 - lam)
    best = 0.0
    for k in range(3):
        u, v = (r0, r1) if k == 0 else ((r0, r2) if k == 1 else (r1, r2))
        c0 = u[1] * v[2] - u[2] * v[1]
        c1 = u[2] * v[0] - u[0] * v[2]
        c2 = u[0] * v[1] - u[1] * v[0]
        size = c0 * c0 + c1 * c1 + c2 * c2
        if size > best:
            best = size
            out[0], out[1], out[2] = c0, c1, c2
    if not best > 0.0:  # a repeated largest eigenvalue: no one line; the largest diagonal's axis
        k = 0 if a00 >= a11 and a00 >= a22 else (1 if a11 >= a22 else 2)
        out[0], out[1], out[2] = 0.0, 0.0, 0.0
        out[k] = 1.0
        return True
    best = math.sqrt(best)
    for a in range(3):
        out[a] /= best
    return True


@kernel
def crack_normals(d, nodes, tsum, dmax, threshold, normal):
    """``normal[p, :, node]``: the crack normal at every owned node whose most damaged particle
    has ``D >= threshold`` and whose gradients are not all zero, else zero (module doc).
    ``tsum``: (slots, d + d(d+1)/2, stride) rows ``s`` then the upper triangle of ``T``;
    ``dmax``: (slots, 1, stride)."""
    own_lo, own_hi, base, nloc, face_lo, face_hi = nodes
    L0, L1 = nloc[0], nloc[1]
    rows = tsum.shape[1]
    t = np.zeros(rows)
    n = np.zeros(3)
    for p in range(own_lo.shape[0]):
        for i2 in range(own_lo[p, 2], own_hi[p, 2]):
            for i1 in range(own_lo[p, 1], own_hi[p, 1]):
                row0 = L0 * (i1 + L1 * i2)
                for i0 in range(own_lo[p, 0], own_hi[p, 0]):
                    node = row0 + i0
                    for a in range(3):
                        normal[p, a, node] = 0.0
                    if not dmax[p, 0, node] >= threshold:
                        continue
                    for r in range(rows):
                        t[r] = tsum[p, r, node]
                    if not _principal_axis(d, t, n):
                        continue
                    s = 0.0
                    for a in range(d):
                        s += n[a] * t[a]
                    sign = -1.0 if s < 0.0 else 1.0
                    for a in range(d):
                        normal[p, a, node] = sign * n[a]


@kernel
def slots_with_crack(normal, slots, nodes):
    """Per slot of ``normal`` (slots, rows, stride; the first ``nodes`` of each row used): whether
    any of its nodes has a crack normal (stops at the first)."""
    out = np.zeros(slots, np.bool_)
    for p in range(slots):
        for a in range(normal.shape[1]):
            for j in range(nodes):
                if normal[p, a, j] != 0.0:
                    out[p] = True
                    break
            if out[p]:
                break
    return out
