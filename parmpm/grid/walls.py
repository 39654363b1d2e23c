"""Rigid walls on the grid: planes at any angle, fixed or moving, with Coulomb friction.

A wall is the plane through ``p`` with unit normal ``n`` pointing out of the wall (towards the
bodies), moving at ``v_w``. A node's mass comes from particles up to a support away, so a node
behind the plane has mass long before the body reaches it (a rolling disk's nodes ahead of its
contact would be stopped, and the disk pushed and braked ahead of its contact). So first the
nodes under the points where a particle's domain touches or crosses the plane are marked
(:func:`touching`, summed over the ghost layers like the mass); after the grid update, every
marked owned node with mass that lies on or behind the plane, ``(x_i − p)·n ≤ 0``, is
checked: if its velocity relative to the wall approaches it, ``v_n = (v_i − v_w)·n < 0``,
the wall takes the normal part (the node stops entering it) and friction acts on the tangential
part ``v_t`` with the normal velocity jump ``Δ = −v_n`` (Bardenhagen et al. 2000, with the wall
as a second body of infinite mass):

    stick  if |v_t| ≤ μ Δ:  v_i ← v_w
    slip   otherwise:        v_i ← v_w + v_t (1 − μ Δ / |v_t|)

``μ = inf`` ("stick") never slips. A node that moves away from the wall is left alone: bodies
leave walls freely. The change ``m_i (v_i' − v_i)`` is the impulse the wall gives the node; its
sum over a wall's nodes is the wall's reaction on the bodies, and ``½ m_i (|v_i'|² − |v_i|²)``
the change of the grid's kinetic energy. The energy ledger counts the work of the forces and of
gravity over a node's mean velocity ``(v + v')/2`` — the velocity the node really has — and the
rest of that change as the wall's work (≤ 0 for a fixed wall: it only takes energy out). Both are
summed per patch slot so that the totals can be added in patch order, the same on any number of
ranks. The increment rows ``Δv`` (FLIP) take the same change, so the particles get the wall's
impulse as well. ``docs/concepts/loads.md`` has the derivation.
"""
import numpy as np

from parmpm.core.jit import kernel
from parmpm.grid.near import domain_vectors, half_extent, node_box


@kernel
def touching(d, start, order, x, F, r0, point, normal, origin, h, base, nloc, touch):
    """Mark in ``touch`` (slots, nodes: zeroed by the caller) the nodes where a particle's domain
    touches or crosses a wall: its signed distance to the plane less its domain's half-extent
    along the normal (the domain is ``F r0``) is ≤ 0. Marked are the nodes of the touching point's
    column: within the domain's axis extent plus a cell of the particle, and at most ``c h`` from
    the domain's point nearest the plane measured along the plane (``c`` = ½ in 2D, ½√2 in 3D:
    half a cell's face diagonal, so the nearest column of an axis-aligned wall is always in). A
    node ahead of a rolling body, whose mass comes from particles a cell away, stays free until
    the body's surface above it reaches the wall (docs/concepts/boundaries.md)."""
    nw = point.shape[0]
    hmin = h[0]
    for a in range(1, d):
        hmin = min(hmin, h[a])
    column2 = 0.25 * (d - 1) * hmin * hmin  # (c h)²
    r = np.zeros((3, 3))
    c = np.zeros(3)
    lo = np.zeros(3, np.int64)  # the marked node box (axes beyond d: 0..0)
    hi = np.zeros(3, np.int64)
    for p in range(start.size - 1):
        for kk in range(start[p], start[p + 1]):
            i = order[kk]
            domain_vectors(d, F, r0, i, r)
            for w in range(nw):
                s = 0.0
                for a in range(d):
                    s += (x[i, a] - point[w, a]) * normal[w, a]
                if s - half_extent(d, r, normal[w]) > 0.0:
                    continue
                node_box(d, x, i, r, 1.0, origin, h, base[p], nloc, lo, hi)
                for a in range(d):  # the domain's point nearest the plane
                    c[a] = x[i, a]
                    for j in range(d):
                        rn = 0.0
                        for b in range(d):
                            rn += r[b, j] * normal[w, b]
                        if rn > 0.0:
                            c[a] -= r[a, j]
                        elif rn < 0.0:
                            c[a] += r[a, j]
                for i2 in range(lo[2], hi[2] + 1):
                    for i1 in range(lo[1], hi[1] + 1):
                        for i0 in range(lo[0], hi[0] + 1):
                            qn = 0.0
                            qq = 0.0
                            for a in range(d):
                                ia = i0 if a == 0 else (i1 if a == 1 else i2)
                                q = origin[a] + (base[p, a] + ia) * h[a] - c[a]
                                qn += q * normal[w, a]
                                qq += q * q
                            if qq - qn * qn <= column2:
                                touch[p, i0 + nloc[0] * (i1 + nloc[1] * i2)] = 1.0
                break  # one wall touched is enough to mark


@kernel
def apply_walls(d, nodes, origin, h, point, normal, velocity, mu, dt, gvec, heavy, touch, gsum,
                gnew, momentum_only):
    """Correct the grid velocities of the block ``gnew`` (rows ``v``, then ``Δv`` unless
    ``momentum_only``) for every wall ``w`` (``point``, ``normal``, ``velocity``: (nw, 3),
    ``mu``: (nw,)); returns per slot and wall (columns): the impulse given to the nodes (3), the
    wall's work, and what the force rows' and gravity's work gain when their mean velocity is the
    corrected one (the energy ledger's account; ``heavy``: the lightest node whose force row
    counts, as in the update)."""
    own_lo, own_hi, base, nloc, face_lo, face_hi = nodes
    nw = point.shape[0]
    out = np.zeros((gsum.shape[0], nw, 6))
    L0, L1 = nloc[0], nloc[1]
    x = np.zeros(3)
    vt = np.zeros(3)
    for p in range(gsum.shape[0]):
        G = gsum[p]
        W = gnew[p]
        for i2 in range(own_lo[p, 2], own_hi[p, 2]):
            x[2] = origin[2] + (base[p, 2] + i2) * h[2]
            for i1 in range(own_lo[p, 1], own_hi[p, 1]):
                x[1] = origin[1] + (base[p, 1] + i1) * h[1]
                row0 = L0 * (i1 + L1 * i2)
                for i0 in range(own_lo[p, 0], own_hi[p, 0]):
                    node = row0 + i0
                    m = G[0, node]
                    if not m > 0.0 or touch[p, node] == 0.0:
                        continue
                    x[0] = origin[0] + (base[p, 0] + i0) * h[0]
                    for w in range(nw):
                        s = 0.0
                        vn = 0.0
                        for k in range(d):
                            s += (x[k] - point[w, k]) * normal[w, k]
                            vn += (W[k, node] - velocity[w, k]) * normal[w, k]
                        if s > 0.0 or not vn < 0.0:
                            continue
                        slide = 0.0
                        for k in range(d):
                            vt[k] = W[k, node] - velocity[w, k] - vn * normal[w, k]
                            slide += vt[k] * vt[k]
                        slide = np.sqrt(slide)
                        grip = -mu[w] * vn  # μΔ, Δ = −v_n > 0
                        keep = 0.0 if slide <= grip else 1.0 - grip / slide
                        ke = 0.0
                        wf = 0.0
                        wg = 0.0
                        for k in range(d):
                            old = W[k, node]
                            new = velocity[w, k] + vt[k] * keep
                            W[k, node] = new
                            if not momentum_only:
                                W[d + k, node] += new - old
                                out[p, w, k] += m * (new - old)
                                ke += 0.5 * m * (new * new - old * old)
                                if m > heavy:
                                    wf += 0.5 * dt * G[1 + d + k, node] * (new - old)
                                wg += 0.5 * dt * m * gvec[k] * (new - old)
                        out[p, w, 3] += ke - wf - wg
                        out[p, w, 4] += wf
                        out[p, w, 5] += wg
    return out
