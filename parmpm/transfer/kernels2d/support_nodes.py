"""The nodes a 2D CPDI particle touches with nonzero weight: the separation count's input.

The dimension-generic walk (:func:`parmpm.transfer.generic.support_nodes`) builds each particle's
16 (node, weight, gradient) entries through the generic support, then lists the distinct nodes
among them, turning each local index back into a global id with integer divisions: 0.34 µs a
particle, two thirds of the count (2026-12-01). Here the corners' cells and fractions come from
:func:`parmpm.transfer.kernels2d.cpdi.support`, the one the step's P2G uses, and a node's global id
from its cell's column and row. A node is listed when its weight ``¼ S_x S_y`` is positive,
computed as the generic entries compute it (so an underflow drops the same node), in the generic
walk's order (corners (−,−), (+,−), (−,+), (+,+), each cell's nodes x fastest), each once: the
tests hold the two walks to the same arrays.
"""
import numpy as np

from parmpm.core.jit import helper_kernel, loop_kernel
from parmpm.transfer.kernels2d.cells import frame_2d, slot_2d
from parmpm.transfer.kernels2d.cpdi import support
from parmpm.transfer.kernels2d.loops import particle_at


@loop_kernel
def support_nodes_cpdi(lcr, boxes, order, fields, nodes, count, err):
    """``nodes[i, :count[i]]``: the global flat ids of particle ``i``'s nodes of nonzero weight,
    each once; a particle whose support leaves its slot's box is skipped (its count stays as
    given) and noted in ``err`` (particle, -1), as is one with more nodes than ``nodes`` has
    columns (then cut there)."""
    start = boxes.start
    frame = frame_2d(boxes)
    g0, g1 = boxes.nglob[0], boxes.nglob[1]
    for p in range(start.size - 1):
        slot = slot_2d(boxes, p)
        bx, by, bz = boxes.base[p, 0], boxes.base[p, 1], boxes.base[p, 2]
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            i, code, st = particle_at(support, order, kk, frame, slot, lcr, fields, err)
            if code < 0:
                continue
            _, jx, jy, fx, fy = st
            c = _corner_nodes(nodes, err, i, 0, bx + jx[0], by + jy[0], bz, fx[0], fy[0], g0, g1)
            c = _corner_nodes(nodes, err, i, c, bx + jx[1], by + jy[1], bz, fx[1], fy[1], g0, g1)
            c = _corner_nodes(nodes, err, i, c, bx + jx[2], by + jy[2], bz, fx[2], fy[2], g0, g1)
            c = _corner_nodes(nodes, err, i, c, bx + jx[3], by + jy[3], bz, fx[3], fy[3], g0, g1)
            count[i] = c


@helper_kernel
def _corner_nodes(nodes, err, i, c, jx, jy, jz, fx, fy, g0, g1):
    """Append to ``nodes[i, c:]`` the nodes of global cell ``(jx, jy)`` (layer ``jz``) that the
    corner at fractions ``(fx, fy)`` weighs positively and that are not listed yet; returns the
    new count. Weights as :func:`parmpm.shapes.cpdi.cell_node` and ``cpdi_support`` form them:
    ``(S_x S_y · 1) · ¼``."""
    for e in range(4):
        ox, oy = e & 1, e >> 1
        wx = fx if ox else 1.0 - fx
        wy = fy if oy else 1.0 - fy
        if not (wx * wy * 1.0) * 0.25 <= 0.0:  # a NaN is listed, as the generic walk lists it
            c = append_node(nodes, err, i, c, (jx + ox) + g0 * ((jy + oy) + g1 * jz))
    return c


@helper_kernel
def append_node(nodes, err, i, c, g):
    """``nodes[i, c] = g`` unless ``g`` is among ``nodes[i, :c]``; returns the new count."""
    for f in range(c):
        if nodes[i, f] == g:
            return c
    return push_node(nodes, err, i, c, g)


@helper_kernel
def push_node(nodes, err, i, c, g):
    """``nodes[i, c] = g`` (a node not listed yet); returns the new count. A node past the row's
    width is the reach error (particle ``i``, -1 in ``err``), and is dropped."""
    if c >= nodes.shape[1]:  # more than the ghost layer allows
        if err[0] < 0:
            err[0] = i
            err[1] = -1
        return c
    nodes[i, c] = g
    return c + 1
