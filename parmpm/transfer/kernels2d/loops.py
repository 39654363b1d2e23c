"""The 2D kernels' particle loops, written once; each interpolator supplies its numba functions.

Every 2D transfer walks the patch slots in order and each slot's particles in canonical order
(:func:`parmpm.transfer.rows.row`) against the slot's node box. :func:`each_particle` is that
walk for P2G and the MUSL re-map; :func:`each_particle_g2p` adds what every G2P does after its
gathers: the FLIP/PIC blend (or APIC's ``v_p``, ``C_p``), the three update modes (USL; MUSL
motion, which stops at ``Δx``; MUSL deformation, which moves by it), the position, the next
patch and the ``F``/stress update. An interpolator module supplies ``@helper_kernel`` functions:

* ``support(i, frame, slot, shape, fields) -> (code, st)``: particle ``i``'s stencil ``st``
  (cells, fractions, weights: whatever its transfers read) in the slot's node box, ``code`` 0, or
  −1 (it leaves the box), −2 (an inverted domain); ``shape``: the kernel's ``lcr``;
* ``scatter(i, g, frame, st, fields, args, side)``: its P2G (or momentum) sums into
  ``g = grid[slot]``;
* ``gather(step, i, g, frame, st, shape, fields, side) -> (v, Δv, C, Δt L, extra)``: its G2P sums, as
  tuples of components (``C`` is read only under APIC, ``step = (mode, Δt, flip, apic)``);
* ``follow(i, dt, extra, fields)``: what moves with the particle besides it (cpdi2's corners;
  :func:`stays` for the rest), after its motion and before its next patch.

The loops and the hooks are inlined at numba's IR level (a hook passed to an inlined loop resolves
to the kernel module's global), so each kernel compiles to one loop body, the code its
hand-written loop gave, and is cached like any kernel. (A kernel factory's closures are not: numba
keys their cache with a pickle of the closure's cells, a new one in every process.)
``frame = (ox, oy, 1/Δx, 1/Δy, L0)`` and ``slot = (bx, by, jlx, jly, jhx, jhy)``:
:func:`~parmpm.transfer.kernels2d.cells.frame_2d`, :func:`~parmpm.transfer.kernels2d.cells.slot_2d`.

What a hook writes reaches it as a kernel argument or a part of one (``g``, ``fields``, ``err``,
``shape``: cpdi2's scratch), never through ``args``, ``st`` or ``extra``, tuples built in the
kernel: numba's dead-code elimination, which it runs after inlining an overload (the patch
arithmetic of :func:`~parmpm.grid.patch_index.next_patch_2d`), does not see that an array taken
out of such a tuple is the caller's, and drops a write into it that nothing reads afterwards.
"""
import numpy as np

from parmpm.core.jit import helper_kernel, hook_helper_kernel
from parmpm.grid.patch_index import next_patch_2d
from parmpm.materials.kinematics import flip_pic
from parmpm.transfer.kernels2d.cells import frame_2d, note_patch, slot_2d
from parmpm.transfer.kernels2d.material import update_F_stress
from parmpm.transfer.rows import row
from parmpm.transfer.running_speed import NO_SPEED
from parmpm.transfer.sided import slot_side
from parmpm.transfer.update_order import G2P_MUSL_DEFORM, G2P_MUSL_MOTION

#: the affine field of a gather whose transfer is not APIC (never written)
NO_AFFINE = (0.0, 0.0, 0.0, 0.0)


@helper_kernel
def note_error(err, i, code):
    """The first particle whose support failed, and its code (−1 reach, −2 inverted)."""
    if err[0] < 0:
        err[0] = i
        err[1] = code


@hook_helper_kernel
def particle_at(support, order, kk, frame, slot, shape, fields, err):
    """The physical row ``i`` at canonical position ``kk``, and its ``support``: ``(i, code, st)``;
    a failure (``code < 0``) is noted in ``err``. Both loops' first step, in 2D and 3D."""
    i = row(order, kk)
    code, st = support(i, frame, slot, shape, fields)
    if code < 0:
        note_error(err, i, code)
    return i, code, st


@helper_kernel
def stays(i, dt, extra, fields):
    """``follow`` of an interpolator whose particles carry nothing else along."""


@hook_helper_kernel
def centre_support(axis, i, frame, slot, fields):
    """The ``support`` of an interpolator centred on particle ``i`` (standard MPM, B-splines):
    per axis, ``axis(ξ, base, jlo, jhi)`` gives the first local node (−1: out of the box) and the
    offset; the stencil is ``(jx, jy, fx, fy)``."""
    x = fields.x
    ox, oy, ihx, ihy, _ = frame
    bx, by, jlx, jly, jhx, jhy = slot
    jx, fx = axis((x[i, 0] - ox) * ihx, bx, jlx, jhx)
    jy, fy = axis((x[i, 1] - oy) * ihy, by, jly, jhy)
    return (-1 if jx < 0 or jy < 0 else 0), (jx, jy, fx, fy)


@hook_helper_kernel
def each_particle(support, scatter, boxes, order, grid, err, shape, fields, args):
    """``scatter`` every particle of every patch slot into the slot's ``grid`` rows, skipping (and
    noting in ``err``) those whose ``support`` fails."""
    start = boxes.start
    frame = frame_2d(boxes)
    for p in range(start.size - 1):
        g = grid[p]
        slot = slot_2d(boxes, p)
        side = slot_side(fields.sides, p)
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            i, code, st = particle_at(support, order, kk, frame, slot, shape, fields, err)
            if code >= 0:
                scatter(i, g, frame, st, fields, args, side)


@hook_helper_kernel
def each_particle_g2p(support, gather, follow, step, boxes, order, grid, err, where, shape,
                      fields, material):
    """G2P of every particle in mode ``step[0]``; returns the largest ``c_p + |v_p|`` (when the
    stress is updated; 0 or ``inf`` without ``material.cfl``: :mod:`parmpm.transfer.
    running_speed`), the particles that changed patch and the first that left the grid. A
    particle whose support fails keeps its slot's patch."""
    mode, dt, flip, apic = step
    x, v, F, stress, dx, C = fields.x, fields.v, fields.F, fields.stress, fields.dx, fields.affine
    mat, params, damage, cfl = material
    start, slot_patch, new_patch = boxes.start, where.slot_patch, where.new_patch
    run = NO_SPEED  # (the largest c_p + |v_p|, what it needs: running_speed)
    moved = 0
    first_out = -1
    frame = frame_2d(boxes)
    for p in range(start.size - 1):
        g = grid[p]
        sp = slot_patch[p]
        slot = slot_2d(boxes, p)
        side = slot_side(fields.sides, p)
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            i, code, st = particle_at(support, order, kk, frame, slot, shape, fields, err)
            if code < 0:
                new_patch[i] = sp
                continue
            xx, xy = x[i, 0], x[i, 1]
            (vx, vy), (dvx, dvy), c, dtl, extra = gather(step, i, g, frame, st, shape,
                                                            fields, side)
            if mode != G2P_MUSL_DEFORM:
                if apic:
                    v[i, 0], v[i, 1] = vx, vy
                    C[i, 0, 0], C[i, 0, 1] = c[0], c[1]
                    C[i, 1, 0], C[i, 1, 1] = c[2], c[3]
                else:
                    v[i, 0] = flip_pic(flip, v[i, 0], dvx, vx)
                    v[i, 1] = flip_pic(flip, v[i, 1], dvy, vy)
                if mode == G2P_MUSL_MOTION:
                    dx[i, 0] = dt * vx
                    dx[i, 1] = dt * vy
                    continue
                x[i, 0] = xx + dt * vx
                x[i, 1] = xy + dt * vy
            else:
                x[i, 0] = xx + dx[i, 0]
                x[i, 1] = xy + dx[i, 1]
            follow(i, dt, extra, fields)
            pid = next_patch_2d(x[i, 0], x[i, 1], boxes.origin, boxes.inv_h, where, p, sp)
            moved, first_out = note_patch(new_patch, np.int64(i), pid, sp, moved, first_out)
            run = update_F_stress(run, i, dtl, (F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1]),
                                  v, F, stress, mat, params, damage, cfl)
    return run[0], moved, first_out
