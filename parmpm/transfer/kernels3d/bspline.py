"""3D quadratic B-spline transfers, FLIP or APIC: the 3×3×3 nodes around the nearest node.

The 3D counterpart of :mod:`parmpm.transfer.kernels2d.bspline` (same per-axis weights and rounding,
:func:`parmpm.transfer.kernels2d.bspline.spline_of` and :func:`parmpm.shapes.bspline.spline_weights`), on the
3D grid rows ``gsum[s, :, node] = (m, mv, f)`` and ``gnew[s, :, node] = (v, Δv)`` with
``node = i0 + L0 (i1 + L1 i2)``. APIC (``C_p`` in ``fields.affine``, :mod:`parmpm.transfer.affine`) is on
when the particles carry the affine field. MLS (:mod:`parmpm.transfer.kernels3d.mls`) shares this G2P with
``L_p = C_p`` in place of the gradient sums.
"""
import numpy as np

from parmpm.core.jit import inline_kernel, loop_kernel
from parmpm.transfer.kernels2d.bspline import spline_of
from parmpm.transfer.kernels2d.cells import note_patch
from parmpm.transfer.kernels3d.cells import frame_3d, slot_3d
from parmpm.transfer.kernels3d.hat import add_force
from parmpm.transfer.kernels3d.material import update_F_stress
from parmpm.materials.kinematics import det_3d, flip_pic
from parmpm.grid.patch_index import next_patch_3d
from parmpm.shapes.bspline import spline_weights
from parmpm.transfer.update_order import G2P_MUSL_DEFORM, G2P_USL


@inline_kernel
def pick(k, a, b, c):
    """``(a, b, c)[k]`` for a loop index ``k`` in 0..2 (tuples cannot be indexed by it)."""
    return a if k == 0 else (b if k == 1 else c)


@inline_kernel
def locate3(x, i, o, ih, boxes, p):
    """Per axis (node c − 1 local index, t) of particle ``i``; a negative index: out of reach."""
    bx, by, bz, jlx, jly, jlz, jhx, jhy, jhz = slot_3d(boxes, p)
    kx, tx = spline_of((x[i, 0] - o[0]) * ih[0], bx, jlx, jhx)
    ky, ty = spline_of((x[i, 1] - o[1]) * ih[1], by, jly, jhy)
    kz, tz = spline_of((x[i, 2] - o[2]) * ih[2], bz, jlz, jhz)
    return kx, ky, kz, tx, ty, tz


@loop_kernel
def p2g_bspline(lcr, boxes, order, fields, bforce, gsum, err):
    """Mass, momentum (FLIP or APIC) and force of every patch slot from its particles (``lcr``
    unused: the signature is the CPDI kernel's)."""
    start = boxes.start
    x, v, F, mass, vol0, stress = (fields.x, fields.v, fields.F, fields.mass, fields.vol0,
                                   fields.stress)
    C = fields.affine
    apic = C.shape[0] > 0
    forced = bforce.shape[0] > 0
    gsum[:] = 0.0
    ox, oy, oz, ihx, ihy, ihz, L0, L01 = frame_3d(boxes)
    o, ih = (ox, oy, oz), (ihx, ihy, ihz)
    hx, hy, hz = 1.0 / ihx, 1.0 / ihy, 1.0 / ihz
    for p in range(start.size - 1):
        g = gsum[p]
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            if order is None:  # rows in canonical order (compiled apart: no load)
                i = kk
            else:
                i = order[kk]  # the physical row (Particles.order)
            kx, ky, kz, tx, ty, tz = locate3(x, i, o, ih, boxes, p)
            if kx < 0 or ky < 0 or kz < 0:
                if err[0] < 0:
                    err[0] = i
                continue
            wx0, wx1, wx2, dx0, dx1, dx2 = spline_weights(tx, ihx)
            wy0, wy1, wy2, dy0, dy1, dy2 = spline_weights(ty, ihy)
            wz0, wz1, wz2, dz0, dz1, dz2 = spline_weights(tz, ihz)
            f00, f01, f02 = F[i, 0, 0], F[i, 0, 1], F[i, 0, 2]
            f10, f11, f12 = F[i, 1, 0], F[i, 1, 1], F[i, 1, 2]
            f20, f21, f22 = F[i, 2, 0], F[i, 2, 1], F[i, 2, 2]
            V = det_3d(f00, f01, f02, f10, f11, f12, f20, f21, f22) * vol0[i]
            t00, t01, t02 = V * stress[i, 0, 0], V * stress[i, 0, 1], V * stress[i, 0, 2]
            t10, t11, t12 = V * stress[i, 1, 0], V * stress[i, 1, 1], V * stress[i, 1, 2]
            t20, t21, t22 = V * stress[i, 2, 0], V * stress[i, 2, 1], V * stress[i, 2, 2]
            m = mass[i]
            vx, vy, vz = v[i, 0], v[i, 1], v[i, 2]
            bfx = m * bforce[i, 0] if forced else 0.0
            bfy = m * bforce[i, 1] if forced else 0.0
            bfz = m * bforce[i, 2] if forced else 0.0
            for c in range(3):
                wz, dz = pick(c, wz0, wz1, wz2), pick(c, dz0, dz1, dz2)
                rz = (c - 1 - tz) * hz
                for b in range(3):
                    wy, dy = pick(b, wy0, wy1, wy2), pick(b, dy0, dy1, dy2)
                    ry = (b - 1 - ty) * hy
                    wyz, dyz, wdz = wy * wz, dy * wz, wy * dz
                    row = kx + L0 * (ky + b) + L01 * (kz + c)
                    for a in range(3):
                        wx, dx = pick(a, wx0, wx1, wx2), pick(a, dx0, dx1, dx2)
                        S = wx * wyz
                        gx, gy, gz = dx * wyz, wx * dyz, wx * wdz
                        mS = m * S
                        ux, uy, uz = vx, vy, vz
                        if apic:
                            rx = (a - 1 - tx) * hx
                            ux = vx + C[i, 0, 0] * rx + C[i, 0, 1] * ry + C[i, 0, 2] * rz
                            uy = vy + C[i, 1, 0] * rx + C[i, 1, 1] * ry + C[i, 1, 2] * rz
                            uz = vz + C[i, 2, 0] * rx + C[i, 2, 1] * ry + C[i, 2, 2] * rz
                        node = row + a
                        g[0, node] += mS
                        g[1, node] += mS * ux
                        g[2, node] += mS * uy
                        g[3, node] += mS * uz
                        add_force(g, node, S, gx, gy, gz, (bfx, bfy, bfz),
                                  (t00, t01, t02, t10, t11, t12, t20, t21, t22), forced)


@loop_kernel
def p2g_momentum_bspline(lcr, boxes, order, fields, gsum, err):
    """The MUSL re-map: momentum rows (1, 2, 3) of ``gsum`` only (FLIP or APIC)."""
    start = boxes.start
    x, v, mass = fields.x, fields.v, fields.mass
    C = fields.affine
    apic = C.shape[0] > 0
    gsum[:, 1:4, :] = 0.0
    ox, oy, oz, ihx, ihy, ihz, L0, L01 = frame_3d(boxes)
    o, ih = (ox, oy, oz), (ihx, ihy, ihz)
    hx, hy, hz = 1.0 / ihx, 1.0 / ihy, 1.0 / ihz
    for p in range(start.size - 1):
        g = gsum[p]
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            if order is None:  # rows in canonical order (compiled apart: no load)
                i = kk
            else:
                i = order[kk]  # the physical row (Particles.order)
            kx, ky, kz, tx, ty, tz = locate3(x, i, o, ih, boxes, p)
            if kx < 0 or ky < 0 or kz < 0:
                if err[0] < 0:
                    err[0] = i
                continue
            wx0, wx1, wx2, _, _, _ = spline_weights(tx, ihx)
            wy0, wy1, wy2, _, _, _ = spline_weights(ty, ihy)
            wz0, wz1, wz2, _, _, _ = spline_weights(tz, ihz)
            m = mass[i]
            vx, vy, vz = v[i, 0], v[i, 1], v[i, 2]
            for c in range(3):
                wz = pick(c, wz0, wz1, wz2)
                rz = (c - 1 - tz) * hz
                for b in range(3):
                    wyz = pick(b, wy0, wy1, wy2) * wz
                    ry = (b - 1 - ty) * hy
                    row = kx + L0 * (ky + b) + L01 * (kz + c)
                    for a in range(3):
                        mS = m * (pick(a, wx0, wx1, wx2) * wyz)
                        ux, uy, uz = vx, vy, vz
                        if apic:
                            rx = (a - 1 - tx) * hx
                            ux = vx + C[i, 0, 0] * rx + C[i, 0, 1] * ry + C[i, 0, 2] * rz
                            uy = vy + C[i, 1, 0] * rx + C[i, 1, 1] * ry + C[i, 1, 2] * rz
                            uz = vz + C[i, 2, 0] * rx + C[i, 2, 1] * ry + C[i, 2, 2] * rz
                        g[1, row + a] += mS * ux
                        g[2, row + a] += mS * uy
                        g[3, row + a] += mS * uz


@loop_kernel
def g2p_bspline(mode, lcr, boxes, order, dt, flip, fields, material, gnew, err, locate):
    """G2P in one of the three modes (FLIP/PIC blend or APIC); returns the largest
    ``c_p + |v_p|`` when the stress is updated, the particles that changed patch and the first
    that left the grid."""
    return g2p_spline(mode, boxes, order, dt, flip, fields, material, gnew, err, locate, False)


@loop_kernel
def g2p_spline(mode, boxes, order, dt, flip, fields, material, gnew, err, locate, mls):
    """:func:`g2p_bspline`'s loop; ``mls``: the velocity gradient is the affine matrix of the
    field G2P reads, ``L_p = Σ φ v_i ⊗ r D⁻¹`` (:mod:`parmpm.transfer.affine`), not ``Σ v_i ⊗ ∇φ``."""
    start = boxes.start
    x, v, F, stress, dxs = fields.x, fields.v, fields.F, fields.stress, fields.dx
    C = fields.affine
    apic = C.shape[0] > 0
    mat, params, damage = material
    slot_patch, new_patch = locate.slot_patch, locate.new_patch
    vmax = 0.0
    moved = 0
    first_out = -1
    ox, oy, oz, ihx, ihy, ihz, L0, L01 = frame_3d(boxes)
    o, ih = (ox, oy, oz), (ihx, ihy, ihz)
    for p in range(start.size - 1):
        g = gnew[p]
        sp = slot_patch[p]
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            if order is None:  # rows in canonical order (compiled apart: no load)
                i = kk
            else:
                i = order[kk]  # the physical row (Particles.order)
            kx, ky, kz, tx, ty, tz = locate3(x, i, o, ih, boxes, p)
            if kx < 0 or ky < 0 or kz < 0:
                if err[0] < 0:
                    err[0] = i
                new_patch[i] = sp
                continue
            wx0, wx1, wx2, dx0, dx1, dx2 = spline_weights(tx, ihx)
            wy0, wy1, wy2, dy0, dy1, dy2 = spline_weights(ty, ihy)
            wz0, wz1, wz2, dz0, dz1, dz2 = spline_weights(tz, ihz)
            # the sums factor by rows of three x-nodes: Σ_abc w_c w_b w_a u = Σ_bc w_c w_b (Σ_a w_a u)
            wr0, wr1, wr2 = wx0 * (-1.0 - tx), wx1 * (-tx), wx2 * (1.0 - tx)
            vx = vy = vz = dvx = dvy = dvz = 0.0
            l00 = l01 = l02 = l10 = l11 = l12 = l20 = l21 = l22 = 0.0
            # APIC: Σ φ v_i ⊗ (k − 1 − t) (grid units), row by row
            b00 = b01 = b02 = b10 = b11 = b12 = b20 = b21 = b22 = 0.0
            for c in range(3):
                wz, dz = pick(c, wz0, wz1, wz2), pick(c, dz0, dz1, dz2)
                rz = c - 1 - tz
                for b in range(3):
                    wy, dy = pick(b, wy0, wy1, wy2), pick(b, dy0, dy1, dy2)
                    ry = b - 1 - ty
                    wyz, dyz, wdz = wy * wz, dy * wz, wy * dz
                    n = kx + L0 * (ky + b) + L01 * (kz + c)
                    u0, u1, u2 = g[0, n], g[0, n + 1], g[0, n + 2]
                    s0, s1, s2 = g[1, n], g[1, n + 1], g[1, n + 2]
                    q0, q1, q2 = g[2, n], g[2, n + 1], g[2, n + 2]
                    sx = wx0 * u0 + wx1 * u1 + wx2 * u2
                    sy = wx0 * s0 + wx1 * s1 + wx2 * s2
                    sz = wx0 * q0 + wx1 * q1 + wx2 * q2
                    vx += wyz * sx
                    vy += wyz * sy
                    vz += wyz * sz
                    if not mls:
                        l00 += wyz * (dx0 * u0 + dx1 * u1 + dx2 * u2)
                        l10 += wyz * (dx0 * s0 + dx1 * s1 + dx2 * s2)
                        l20 += wyz * (dx0 * q0 + dx1 * q1 + dx2 * q2)
                        l01 += dyz * sx
                        l11 += dyz * sy
                        l21 += dyz * sz
                        l02 += wdz * sx
                        l12 += wdz * sy
                        l22 += wdz * sz
                    if apic:
                        wry, wrz = wyz * ry, wyz * rz
                        b00 += wyz * (wr0 * u0 + wr1 * u1 + wr2 * u2)
                        b10 += wyz * (wr0 * s0 + wr1 * s1 + wr2 * s2)
                        b20 += wyz * (wr0 * q0 + wr1 * q1 + wr2 * q2)
                        b01 += wry * sx
                        b11 += wry * sy
                        b21 += wry * sz
                        b02 += wrz * sx
                        b12 += wrz * sy
                        b22 += wrz * sz
                    else:
                        dvx += wyz * (wx0 * g[3, n] + wx1 * g[3, n + 1] + wx2 * g[3, n + 2])
                        dvy += wyz * (wx0 * g[4, n] + wx1 * g[4, n + 1] + wx2 * g[4, n + 2])
                        dvz += wyz * (wx0 * g[5, n] + wx1 * g[5, n + 1] + wx2 * g[5, n + 2])
            xx, xy, xz = x[i, 0], x[i, 1], x[i, 2]
            kx4, ky4, kz4 = 4.0 * ihx, 4.0 * ihy, 4.0 * ihz
            c00, c01, c02 = kx4 * b00, ky4 * b01, kz4 * b02
            c10, c11, c12 = kx4 * b10, ky4 * b11, kz4 * b12
            c20, c21, c22 = kx4 * b20, ky4 * b21, kz4 * b22
            if mls:
                l00, l01, l02, l10, l11, l12 = c00, c01, c02, c10, c11, c12
                l20, l21, l22 = c20, c21, c22
            if mode != G2P_MUSL_DEFORM:
                if apic:
                    v[i, 0], v[i, 1], v[i, 2] = vx, vy, vz
                    C[i, 0, 0], C[i, 0, 1], C[i, 0, 2] = c00, c01, c02
                    C[i, 1, 0], C[i, 1, 1], C[i, 1, 2] = c10, c11, c12
                    C[i, 2, 0], C[i, 2, 1], C[i, 2, 2] = c20, c21, c22
                else:
                    v[i, 0] = flip_pic(flip, v[i, 0], dvx, vx)
                    v[i, 1] = flip_pic(flip, v[i, 1], dvy, vy)
                    v[i, 2] = flip_pic(flip, v[i, 2], dvz, vz)
                if mode != G2P_USL:
                    dxs[i, 0], dxs[i, 1], dxs[i, 2] = dt * vx, dt * vy, dt * vz
                    continue
                x[i, 0], x[i, 1], x[i, 2] = xx + dt * vx, xy + dt * vy, xz + dt * vz
            else:
                x[i, 0], x[i, 1], x[i, 2] = xx + dxs[i, 0], xy + dxs[i, 1], xz + dxs[i, 2]
            pid = next_patch_3d(x[i, 0], x[i, 1], x[i, 2], boxes.origin, boxes.inv_h, locate, p,
                                sp)
            moved, first_out = note_patch(new_patch, np.int64(i), pid, sp, moved, first_out)
            vmax = update_F_stress(vmax, i, (dt * l00, dt * l01, dt * l02, dt * l10, dt * l11,
                                             dt * l12, dt * l20, dt * l21, dt * l22),
                                   (F[i, 0, 0], F[i, 0, 1], F[i, 0, 2], F[i, 1, 0], F[i, 1, 1],
                                    F[i, 1, 2], F[i, 2, 0], F[i, 2, 1], F[i, 2, 2]),
                                   v, F, stress, mat, params, damage)
    return vmax, moved, first_out
