"""The nodes a 3D CPDI particle touches with nonzero weight: the separation count's input.

:mod:`parmpm.transfer.kernels2d.support_nodes` in 3D. The generic walk's 64 entries a particle
(8 corners × 8 nodes) are deduplicated by comparing each with the ones before it; here the
corners' cells come from :func:`parmpm.transfer.kernels3d.cpdi.support` (the step's own), a node is
listed when its weight ``⅛ (S_x S_y) S_z`` is positive, computed as the generic entries compute it,
in the generic walk's order (corner bits x, y, z; each cell's nodes x fastest), each once.
"""
import numpy as np

from parmpm.core.jit import helper_kernel, loop_kernel
from parmpm.transfer.kernels2d.loops import particle_at
from parmpm.transfer.kernels2d.support_nodes import append_node, push_node
from parmpm.transfer.kernels3d.cells import frame_3d, slot_3d
from parmpm.transfer.kernels3d.cpdi import support


@loop_kernel
def support_nodes_cpdi(lcr, boxes, order, fields, nodes, count, err):
    """:func:`parmpm.transfer.kernels2d.support_nodes.support_nodes_cpdi` in 3D: each particle's
    nodes of nonzero weight once, in ``nodes[i, :count[i]]``, the reach error in ``err``."""
    frame = frame_3d(boxes)
    start = boxes.start
    g0, g1 = boxes.nglob[0], boxes.nglob[1]
    for p in range(start.size - 1):
        slot = slot_3d(boxes, p)
        bx, by, bz = slot[0], slot[1], slot[2]
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            i, code, st = particle_at(support, order, kk, frame, slot, lcr, fields, err)
            if code < 0:
                continue
            _, jx, jy, jz, fx, fy, fz = st
            # the nodes' box, local: a bit each when it has at most 64 (domains up to 2 cells
            # across), else the list is searched
            lx, sx = min(jx), max(jx) - min(jx) + 2
            ly, sy = min(jy), max(jy) - min(jy) + 2
            lz, sz = min(jz), max(jz) - min(jz) + 2
            box = (lx, ly, lz, sx, sy) if sx * sy * sz <= 64 else (-1, 0, 0, 0, 0)
            c = 0
            seen = np.uint64(0)
            for a in range(8):
                c, seen = _corner_nodes(nodes, err, i, c, seen, box, (jx[a], jy[a], jz[a]),
                                        (bx, by, bz), fx[a], fy[a], fz[a], g0, g1)
            count[i] = c


@helper_kernel
def _corner_nodes(nodes, err, i, c, seen, box, cell, base, fx, fy, fz, g0, g1):
    """Append to ``nodes[i, c:]`` the nodes of local cell ``cell`` (slot origin ``base``) that
    the corner at fractions ``(fx, fy, fz)`` weighs positively and that are not listed yet:
    ``seen`` has a bit per node of the particle's node ``box`` (its low corner and two of its
    sizes; a negative corner: no bits, search the list). Returns the new count and ``seen``.
    Weights as :func:`parmpm.shapes.cpdi.cell_node` and ``cpdi_support`` form them."""
    lx, ly, lz, sx, sy = box
    jx, jy, jz = cell
    for e in range(8):
        ox, oy, oz = e & 1, (e >> 1) & 1, e >> 2
        wx = fx if ox else 1.0 - fx
        wy = fy if oy else 1.0 - fy
        wz = fz if oz else 1.0 - fz
        if (wx * wy * wz) * 0.125 <= 0.0:  # a NaN is listed, as the generic walk lists it
            continue
        g = (base[0] + jx + ox) + g0 * ((base[1] + jy + oy) + g1 * (base[2] + jz + oz))
        if lx < 0:
            c = append_node(nodes, err, i, c, g)
            continue
        bit = np.uint64(1) << np.uint64((jx + ox - lx) + sx * ((jy + oy - ly) + sy * (jz + oz - lz)))
        if seen & bit:
            continue
        seen |= bit
        c = push_node(nodes, err, i, c, g)
    return c, seen
