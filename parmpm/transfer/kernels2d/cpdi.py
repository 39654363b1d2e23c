"""2D CPDI1 transfers, corner by corner (Sadeghirad, Brannon & Burghardt 2011).

A particle's domain ``R = F·R0`` (columns ``r1``, ``r2``; capped at ``l_cr`` by
:func:`domain` when domain scaling is on) has corners ``x_α = x_p + s1 r1 + s2 r2``
(``s = ±1``). With ``V = 4 det R`` and cofactor columns ``c1 = (r2_y, −r2_x)``,
``c2 = (−r1_y, r1_x)``: ``φ_ip = ¼ Σ_α S_i(x_α)`` and ``∇φ_ip = (1/V) Σ_α S_i(x_α) g_α`` with
``g_α = s1 c1 + s2 c2``. So P2G scatters, per corner, ``¼ m_p`` (mass), ``¼ m_p v_p`` (momentum)
and ``−(V_p/V) σ_p g_α (+ ¼ m_p b_p)`` (force) into the four nodes of ``x_α``'s cell with the
bilinear weights ``S_i(x_α)``; G2P gathers ``v(x_α)`` and ``Δv(x_α)`` the same way and forms
``v_p = ¼ Σ v(x_α)``, ``Δv_p = ¼ Σ Δv(x_α)`` and ``L_p = (1/V) Σ_α v(x_α) ⊗ g_α``.
Corners in the generic kernel's order: ``(−,−), (+,−), (−,+), (+,+)``; since ``g`` of opposite
corners are opposite, two stress products serve all four.

Every corner's cell is located (and checked against the patch's box) before anything is
scattered, so a particle that reaches past the ghost layer contributes nothing and sets ``err``.
"""
import numpy as np

from parmpm.core.jit import inline_kernel, loop_kernel
from parmpm.core.records import NO_SCALING
from parmpm.transfer.kernels2d.cells import cells_of4, frame_2d, note_patch, slot_2d
from parmpm.transfer.kernels2d.material import update_F_stress
from parmpm.materials.kinematics import det_2d, flip_pic
from parmpm.grid.patch_index import next_patch_2d
from parmpm.shapes.cpdi import cofactor_2d
from parmpm.shapes.scaling import cap_2d
from parmpm.transfer.update_order import G2P_MUSL_DEFORM, G2P_MUSL_MOTION


@inline_kernel
def domain(lcr, f00, f01, f10, f11, q00, q01, q10, q11):
    """``R = F·R0`` as (r1x, r1y, r2x, r2y), capped by :func:`parmpm.shapes.scaling.cap_2d`
    when domain scaling is on."""
    r1x = f00 * q00 + f01 * q10
    r1y = f10 * q00 + f11 * q10
    r2x = f00 * q01 + f01 * q11
    r2y = f10 * q01 + f11 * q11
    if lcr < NO_SCALING:  # a cap no vector reaches changes nothing: skip it
        r1x, r1y, r2x, r2y, _ = cap_2d(lcr, r1x, r1y, r2x, r2y)
    return r1x, r1y, r2x, r2y


@inline_kernel
def corner_gradients(r1x, r1y, r2x, r2y):
    """``g`` of corners (+,+) and (+,−) (their opposites have ``−g``) from the cofactor columns,
    and ``det R``: ``(gax, gay, gbx, gby, det)``."""
    c1x, c1y, c2x, c2y, det = cofactor_2d(r1x, r1y, r2x, r2y)
    return c1x + c2x, c1y + c2y, c1x - c2x, c1y - c2y, det


@inline_kernel
def corners(xx, xy, r1x, r1y, r2x, r2y, ihx, ihy, bx, by, jlx, jly, jhx, jhy):
    """Local cells and fractions of the four corners (grid coordinates ``xx, xy`` of the centre):
    ``(jx0..3, jy0..3, fx0..3, fy0..3, ok)``."""
    a00, a01, a10, a11 = r1x * ihx, r2x * ihx, r1y * ihy, r2y * ihy
    jx0, jx1, jx2, jx3, fx0, fx1, fx2, fx3, okx = cells_of4(
        (xx - a00) - a01, (xx + a00) - a01, (xx - a00) + a01, (xx + a00) + a01, bx, jlx, jhx)
    jy0, jy1, jy2, jy3, fy0, fy1, fy2, fy3, oky = cells_of4(
        (xy - a10) - a11, (xy + a10) - a11, (xy - a10) + a11, (xy + a10) + a11, by, jly, jhy)
    return (jx0, jx1, jx2, jx3, jy0, jy1, jy2, jy3, fx0, fx1, fx2, fx3, fy0, fy1, fy2, fy3,
            okx and oky)


@inline_kernel
def scatter5(g, L0, jx, jy, fx, fy, a0, a1, a2, a3, a4):
    """``g[c, node] += S_node(f) · a_c`` over the four nodes of local cell ``(jx, jy)``."""
    n0 = jx + L0 * jy
    n2 = n0 + L0
    s0 = (1.0 - fx) * (1.0 - fy)
    s1 = fx * (1.0 - fy)
    s2 = (1.0 - fx) * fy
    s3 = fx * fy
    g[0, n0] += a0 * s0
    g[1, n0] += a1 * s0
    g[2, n0] += a2 * s0
    g[3, n0] += a3 * s0
    g[4, n0] += a4 * s0
    g[0, n0 + 1] += a0 * s1
    g[1, n0 + 1] += a1 * s1
    g[2, n0 + 1] += a2 * s1
    g[3, n0 + 1] += a3 * s1
    g[4, n0 + 1] += a4 * s1
    g[0, n2] += a0 * s2
    g[1, n2] += a1 * s2
    g[2, n2] += a2 * s2
    g[3, n2] += a3 * s2
    g[4, n2] += a4 * s2
    g[0, n2 + 1] += a0 * s3
    g[1, n2 + 1] += a1 * s3
    g[2, n2 + 1] += a2 * s3
    g[3, n2 + 1] += a3 * s3
    g[4, n2 + 1] += a4 * s3


@inline_kernel
def scatter_momentum(g, L0, jx, jy, fx, fy, a1, a2):
    """Rows 1 and 2 (momentum) of :func:`scatter5`."""
    n0 = jx + L0 * jy
    n2 = n0 + L0
    s0 = (1.0 - fx) * (1.0 - fy)
    s1 = fx * (1.0 - fy)
    s2 = (1.0 - fx) * fy
    s3 = fx * fy
    g[1, n0] += a1 * s0
    g[2, n0] += a2 * s0
    g[1, n0 + 1] += a1 * s1
    g[2, n0 + 1] += a2 * s1
    g[1, n2] += a1 * s2
    g[2, n2] += a2 * s2
    g[1, n2 + 1] += a1 * s3
    g[2, n2 + 1] += a2 * s3


@inline_kernel
def gather4(g, L0, jx, jy, fx, fy):
    """Bilinear interpolation of rows 0..3 of ``g`` at fractions ``(fx, fy)`` of a local cell."""
    n0 = jx + L0 * jy
    n2 = n0 + L0
    s0 = (1.0 - fx) * (1.0 - fy)
    s1 = fx * (1.0 - fy)
    s2 = (1.0 - fx) * fy
    s3 = fx * fy
    return (s0 * g[0, n0] + s1 * g[0, n0 + 1] + s2 * g[0, n2] + s3 * g[0, n2 + 1],
            s0 * g[1, n0] + s1 * g[1, n0 + 1] + s2 * g[1, n2] + s3 * g[1, n2 + 1],
            s0 * g[2, n0] + s1 * g[2, n0 + 1] + s2 * g[2, n2] + s3 * g[2, n2 + 1],
            s0 * g[3, n0] + s1 * g[3, n0 + 1] + s2 * g[3, n2] + s3 * g[3, n2 + 1])


@loop_kernel
def p2g_cpdi(lcr, boxes, order, fields, bforce, gsum, err):
    """Mass, momentum and force rows of ``gsum[slot]`` from every slot's particles."""
    start = boxes.start
    x, v, F, r0, mass, vol0, stress = (fields.x, fields.v, fields.F, fields.r0, fields.mass,
                                       fields.vol0, fields.stress)
    forced = bforce.shape[0] > 0
    gsum[:] = 0.0
    ox, oy, ihx, ihy, L0 = frame_2d(boxes)
    for p in range(start.size - 1):
        g = gsum[p]
        bx, by, jlx, jly, jhx, jhy = slot_2d(boxes, p)
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            if order is None:  # rows in canonical order (compiled apart: no load)
                i = kk
            else:
                i = order[kk]  # the physical row (Particles.order)
            f00, f01, f10, f11 = F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1]
            r1x, r1y, r2x, r2y = domain(lcr, f00, f01, f10, f11,
                                        r0[i, 0, 0], r0[i, 0, 1], r0[i, 1, 0], r0[i, 1, 1])
            (jx0, jx1, jx2, jx3, jy0, jy1, jy2, jy3, fx0, fx1, fx2, fx3, fy0, fy1, fy2, fy3,
             ok) = corners((x[i, 0] - ox) * ihx, (x[i, 1] - oy) * ihy, r1x, r1y, r2x, r2y,
                           ihx, ihy, bx, by, jlx, jly, jhx, jhy)
            if not ok:
                if err[0] < 0:
                    err[0] = i
                continue
            gax, gay, gbx, gby, det = corner_gradients(r1x, r1y, r2x, r2y)
            q = det_2d(f00, f01, f10, f11) * vol0[i] / (4.0 * det)
            t00, t01, t10, t11 = stress[i, 0, 0], stress[i, 0, 1], stress[i, 1, 0], stress[i, 1, 1]
            mq = mass[i] * 0.25
            mvx, mvy = mq * v[i, 0], mq * v[i, 1]
            bfx = mq * bforce[i, 0] if forced else 0.0
            bfy = mq * bforce[i, 1] if forced else 0.0
            tax, tay = q * (t00 * gax + t01 * gay), q * (t10 * gax + t11 * gay)
            tbx, tby = q * (t00 * gbx + t01 * gby), q * (t10 * gbx + t11 * gby)
            scatter5(g, L0, jx0, jy0, fx0, fy0, mq, mvx, mvy, bfx + tax, bfy + tay)
            scatter5(g, L0, jx1, jy1, fx1, fy1, mq, mvx, mvy, bfx - tbx, bfy - tby)
            scatter5(g, L0, jx2, jy2, fx2, fy2, mq, mvx, mvy, bfx + tbx, bfy + tby)
            scatter5(g, L0, jx3, jy3, fx3, fy3, mq, mvx, mvy, bfx - tax, bfy - tay)


@loop_kernel
def p2g_momentum_cpdi(lcr, boxes, order, fields, gsum, err):
    """The MUSL re-map: momentum rows (1, 2) of ``gsum`` only."""
    start = boxes.start
    x, v, F, r0, mass = fields.x, fields.v, fields.F, fields.r0, fields.mass
    gsum[:, 1:3, :] = 0.0
    ox, oy, ihx, ihy, L0 = frame_2d(boxes)
    for p in range(start.size - 1):
        g = gsum[p]
        bx, by, jlx, jly, jhx, jhy = slot_2d(boxes, p)
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            if order is None:  # rows in canonical order (compiled apart: no load)
                i = kk
            else:
                i = order[kk]  # the physical row (Particles.order)
            r1x, r1y, r2x, r2y = domain(lcr, F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1],
                                        r0[i, 0, 0], r0[i, 0, 1], r0[i, 1, 0], r0[i, 1, 1])
            (jx0, jx1, jx2, jx3, jy0, jy1, jy2, jy3, fx0, fx1, fx2, fx3, fy0, fy1, fy2, fy3,
             ok) = corners((x[i, 0] - ox) * ihx, (x[i, 1] - oy) * ihy, r1x, r1y, r2x, r2y,
                           ihx, ihy, bx, by, jlx, jly, jhx, jhy)
            if not ok:
                if err[0] < 0:
                    err[0] = i
                continue
            mq = mass[i] * 0.25
            mvx, mvy = mq * v[i, 0], mq * v[i, 1]
            scatter_momentum(g, L0, jx0, jy0, fx0, fy0, mvx, mvy)
            scatter_momentum(g, L0, jx1, jy1, fx1, fy1, mvx, mvy)
            scatter_momentum(g, L0, jx2, jy2, fx2, fy2, mvx, mvy)
            scatter_momentum(g, L0, jx3, jy3, fx3, fy3, mvx, mvy)


@loop_kernel
def g2p_cpdi(mode, lcr, boxes, order, dt, flip, fields, material, gnew, err, locate):
    """G2P in one of the three modes (USL; MUSL motion; MUSL deformation) from
    ``gnew[slot] = (v_x, v_y, Δv_x, Δv_y)`` rows; returns the largest ``c_p + |v_p|`` in the
    modes that update the stress."""
    start = boxes.start
    x, v, F, r0, stress, dx = fields.x, fields.v, fields.F, fields.r0, fields.stress, fields.dx
    mat, params, damage = material
    slot_patch, new_patch = locate.slot_patch, locate.new_patch
    vmax = 0.0
    moved = 0
    first_out = -1
    ox, oy, ihx, ihy, L0 = frame_2d(boxes)
    for p in range(start.size - 1):
        g = gnew[p]
        sp = slot_patch[p]
        bx, by, jlx, jly, jhx, jhy = slot_2d(boxes, p)
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            if order is None:  # rows in canonical order (compiled apart: no load)
                i = kk
            else:
                i = order[kk]  # the physical row (Particles.order)
            f00, f01, f10, f11 = F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1]
            r1x, r1y, r2x, r2y = domain(lcr, f00, f01, f10, f11,
                                        r0[i, 0, 0], r0[i, 0, 1], r0[i, 1, 0], r0[i, 1, 1])
            xx, xy = x[i, 0], x[i, 1]
            vpx, vpy = v[i, 0], v[i, 1]
            (jx0, jx1, jx2, jx3, jy0, jy1, jy2, jy3, fx0, fx1, fx2, fx3, fy0, fy1, fy2, fy3,
             ok) = corners((xx - ox) * ihx, (xy - oy) * ihy, r1x, r1y, r2x, r2y,
                           ihx, ihy, bx, by, jlx, jly, jhx, jhy)
            if not ok:
                if err[0] < 0:
                    err[0] = i
                new_patch[i] = sp
                continue
            u0x, u0y, d0x, d0y = gather4(g, L0, jx0, jy0, fx0, fy0)
            u1x, u1y, d1x, d1y = gather4(g, L0, jx1, jy1, fx1, fy1)
            u2x, u2y, d2x, d2y = gather4(g, L0, jx2, jy2, fx2, fy2)
            u3x, u3y, d3x, d3y = gather4(g, L0, jx3, jy3, fx3, fy3)
            if mode != G2P_MUSL_DEFORM:
                vx = 0.25 * (u0x + u1x + u2x + u3x)
                vy = 0.25 * (u0y + u1y + u2y + u3y)
                v[i, 0] = flip_pic(flip, vpx, 0.25 * (d0x + d1x + d2x + d3x), vx)
                v[i, 1] = flip_pic(flip, vpy, 0.25 * (d0y + d1y + d2y + d3y), vy)
                if mode == G2P_MUSL_MOTION:
                    dx[i, 0] = dt * vx
                    dx[i, 1] = dt * vy
                    continue
                x[i, 0] = xx + dt * vx
                x[i, 1] = xy + dt * vy
            else:
                x[i, 0] = xx + dx[i, 0]
                x[i, 1] = xy + dx[i, 1]
            # where it goes next
            pid = next_patch_2d(x[i, 0], x[i, 1], boxes.origin, boxes.inv_h, locate, p, sp)
            moved, first_out = note_patch(new_patch, np.int64(i), pid, sp, moved, first_out)
            # L = (1/V) Σ v(x_α) ⊗ g_α with g = −ga, gb, −gb, ga for corners 0..3
            gax, gay, gbx, gby, det = corner_gradients(r1x, r1y, r2x, r2y)
            wax, way = u3x - u0x, u3y - u0y
            wbx, wby = u1x - u2x, u1y - u2y
            k = dt / (4.0 * det)
            l00 = k * (wax * gax + wbx * gbx)
            l01 = k * (wax * gay + wbx * gby)
            l10 = k * (way * gax + wby * gbx)
            l11 = k * (way * gay + wby * gby)
            vmax = update_F_stress(vmax, i, (l00, l01, l10, l11), (f00, f01, f10, f11), v, F,
                                   stress, mat, params, damage)
    return vmax, moved, first_out
