"""The 3D kernels' particle loops, written once; each interpolator supplies its numba functions.

:mod:`parmpm.transfer.kernels2d.loops` in 3D, with the same hooks (``support``, ``scatter``,
``gather``, ``follow``) and the same contract; ``frame = (ox, oy, oz, 1/Δx, 1/Δy, 1/Δz, L0,
L0·L1)`` and ``slot = (bx, by, bz, jlx, jly, jlz, jhx, jhy, jhz)``
(:func:`~parmpm.transfer.kernels3d.cells.frame_3d`,
:func:`~parmpm.transfer.kernels3d.cells.slot_3d`). Velocities, ``Δv`` and the affine field are
tuples of 3 and 9 components, ``Δt L`` of 9 (row by row).
"""
import numpy as np

from parmpm.core.jit import hook_helper_kernel
from parmpm.grid.patch_index import next_patch_3d
from parmpm.materials.kinematics import flip_pic
from parmpm.transfer.kernels2d.cells import note_patch
from parmpm.transfer.kernels2d.loops import particle_at
from parmpm.transfer.kernels3d.cells import frame_3d, slot_3d
from parmpm.transfer.kernels3d.material import update_F_stress
from parmpm.transfer.running_speed import NO_SPEED
from parmpm.transfer.update_order import G2P_MUSL_DEFORM, G2P_USL

#: a 3×3 matrix of zeros, row by row: the affine field of a gather whose transfer is not APIC
#: (never written), or ``Δt L`` where a gather skips it
ZERO9 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@hook_helper_kernel
def centre_support(axis, i, frame, slot, fields):
    """:func:`parmpm.transfer.kernels2d.loops.centre_support` in 3D: ``(jx, jy, jz, fx, fy,
    fz)``."""
    x = fields.x
    ox, oy, oz, ihx, ihy, ihz, _, _ = frame
    bx, by, bz, jlx, jly, jlz, jhx, jhy, jhz = slot
    jx, fx = axis((x[i, 0] - ox) * ihx, bx, jlx, jhx)
    jy, fy = axis((x[i, 1] - oy) * ihy, by, jly, jhy)
    jz, fz = axis((x[i, 2] - oz) * ihz, bz, jlz, jhz)
    return (-1 if jx < 0 or jy < 0 or jz < 0 else 0), (jx, jy, jz, fx, fy, fz)


@hook_helper_kernel
def each_particle(support, scatter, boxes, order, grid, err, shape, fields, args):
    """:func:`parmpm.transfer.kernels2d.loops.each_particle` in 3D."""
    start = boxes.start
    frame = frame_3d(boxes)
    for p in range(start.size - 1):
        g = grid[p]
        slot = slot_3d(boxes, p)
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            i, code, st = particle_at(support, order, kk, frame, slot, shape, fields, err)
            if code >= 0:
                scatter(i, g, frame, st, fields, args)


@hook_helper_kernel
def each_particle_g2p(support, gather, follow, step, boxes, order, grid, err, where, shape,
                      fields, material):
    """:func:`parmpm.transfer.kernels2d.loops.each_particle_g2p` in 3D."""
    mode, dt, flip, apic = step
    x, v, F, stress, dx, C = fields.x, fields.v, fields.F, fields.stress, fields.dx, fields.affine
    mat, params, damage, cfl = material
    start, slot_patch, new_patch = boxes.start, where.slot_patch, where.new_patch
    run = NO_SPEED  # (the largest c_p + |v_p|, what it needs: running_speed)
    moved = 0
    first_out = -1
    frame = frame_3d(boxes)
    for p in range(start.size - 1):
        g = grid[p]
        sp = slot_patch[p]
        slot = slot_3d(boxes, p)
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            i, code, st = particle_at(support, order, kk, frame, slot, shape, fields, err)
            if code < 0:
                new_patch[i] = sp
                continue
            xx, xy, xz = x[i, 0], x[i, 1], x[i, 2]
            (vx, vy, vz), (dvx, dvy, dvz), c, dtl, extra = gather(step, i, g, frame, st, shape,
                                                                  fields)
            if mode != G2P_MUSL_DEFORM:
                if apic:
                    v[i, 0], v[i, 1], v[i, 2] = vx, vy, vz
                    C[i, 0, 0], C[i, 0, 1], C[i, 0, 2] = c[0], c[1], c[2]
                    C[i, 1, 0], C[i, 1, 1], C[i, 1, 2] = c[3], c[4], c[5]
                    C[i, 2, 0], C[i, 2, 1], C[i, 2, 2] = c[6], c[7], c[8]
                else:
                    v[i, 0] = flip_pic(flip, v[i, 0], dvx, vx)
                    v[i, 1] = flip_pic(flip, v[i, 1], dvy, vy)
                    v[i, 2] = flip_pic(flip, v[i, 2], dvz, vz)
                if mode != G2P_USL:
                    dx[i, 0], dx[i, 1], dx[i, 2] = dt * vx, dt * vy, dt * vz
                    continue
                x[i, 0], x[i, 1], x[i, 2] = xx + dt * vx, xy + dt * vy, xz + dt * vz
            else:
                x[i, 0], x[i, 1], x[i, 2] = xx + dx[i, 0], xy + dx[i, 1], xz + dx[i, 2]
            follow(i, dt, extra, fields)
            pid = next_patch_3d(x[i, 0], x[i, 1], x[i, 2], boxes.origin, boxes.inv_h, where, p,
                                sp)
            moved, first_out = note_patch(new_patch, np.int64(i), pid, sp, moved, first_out)
            run = update_F_stress(run, i, dtl,
                                  (F[i, 0, 0], F[i, 0, 1], F[i, 0, 2], F[i, 1, 0], F[i, 1, 1],
                                   F[i, 1, 2], F[i, 2, 0], F[i, 2, 1], F[i, 2, 2]),
                                  v, F, stress, mat, params, damage, cfl)
    return run[0], moved, first_out
