"""3D standard-MPM transfers: the trilinear hat at the particle centre.

With ``ξ = (x_p − origin)/Δx`` in cell ``(j_x, j_y, j_z)`` at fractions ``(f_x, f_y, f_z)`` the
eight nodes get ``φ = S_x S_y S_z`` (``S = 1 − f`` or ``f``) and
``∇φ = (S'_x S_y S_z, S_x S'_y S_z, S_x S_y S'_z)`` with ``S' = ∓1/Δx``. P2G scatters ``φ m_p``,
``φ m_p v_p`` and ``−V_p σ_p ∇φ (+ φ m_p b_p)`` (``V_p = J_p V0_p``); G2P gathers
``v_p = Σ φ v_i``, ``Δv_p = Σ φ Δv_i`` and ``L_p = Σ v_i ⊗ ∇φ`` (:mod:`parmpm.transfer.generic` has the
full step). Grid rows as in :mod:`parmpm.transfer.kernels3d.cpdi`; node ``i0 + L0 (i1 + L1 i2)``.
"""
import numpy as np

from parmpm.core.jit import inline_kernel, loop_kernel
from parmpm.transfer.kernels2d.cells import hat_cell_of, note_patch
from parmpm.transfer.kernels3d.cells import frame_3d, slot_3d
from parmpm.transfer.kernels3d.material import update_F_stress
from parmpm.materials.kinematics import det_3d, flip_pic
from parmpm.grid.patch_index import next_patch_3d
from parmpm.transfer.update_order import G2P_MUSL_DEFORM, G2P_USL


@inline_kernel
def nodes8(n0, L0, L01, fx, fy, fz, ihx, ihy, ihz):
    """The eight nodes of the cell whose first node is ``n0`` (x fastest): ``(node, φ, ∇φ)``;
    unsigned node indices as in :func:`parmpm.transfer.kernels3d.cpdi.cell_nodes`."""
    ax, ay, az = 1.0 - fx, 1.0 - fy, 1.0 - fz
    w00, w10, w01, w11 = ay * az, fy * az, ay * fz, fy * fz   # S_y S_z
    x00, x10, x01, x11 = ax * az, fx * az, ax * fz, fx * fz   # S_x S_z
    v00, v10, v01, v11 = ax * ay, fx * ay, ax * fy, fx * fy   # S_x S_y
    n0 = np.uint64(n0)
    n2, n4, one = n0 + np.uint64(L0), n0 + np.uint64(L01), np.uint64(1)
    n6 = n4 + np.uint64(L0)
    return ((n0, ax * w00, -ihx * w00, -ihy * x00, -ihz * v00),
            (n0 + one, fx * w00, ihx * w00, -ihy * x10, -ihz * v10),
            (n2, ax * w10, -ihx * w10, ihy * x00, -ihz * v01),
            (n2 + one, fx * w10, ihx * w10, ihy * x10, -ihz * v11),
            (n4, ax * w01, -ihx * w01, -ihy * x01, ihz * v00),
            (n4 + one, fx * w01, ihx * w01, -ihy * x11, ihz * v10),
            (n6, ax * w11, -ihx * w11, ihy * x01, ihz * v01),
            (n6 + one, fx * w11, ihx * w11, ihy * x11, ihz * v11))


@inline_kernel
def add_force(g, node, S, gx, gy, gz, bf, t, forced):
    """P2G's force rows of one node: ``φ m b − t ∇φ`` with ``bf = m b`` and ``t = V σ`` (row by
    row), or ``− t ∇φ`` alone when no body force acts (``forced`` False): the same sums without
    the ``0·φ`` terms, which strict IEEE arithmetic keeps."""
    bfx, bfy, bfz = bf
    t00, t01, t02, t10, t11, t12, t20, t21, t22 = t
    if forced:
        g[4, node] += bfx * S - (t00 * gx + t01 * gy + t02 * gz)
        g[5, node] += bfy * S - (t10 * gx + t11 * gy + t12 * gz)
        g[6, node] += bfz * S - (t20 * gx + t21 * gy + t22 * gz)
    else:
        g[4, node] -= t00 * gx + t01 * gy + t02 * gz
        g[5, node] -= t10 * gx + t11 * gy + t12 * gz
        g[6, node] -= t20 * gx + t21 * gy + t22 * gz


@inline_kernel
def scatter_node(g, e, a, t, forced):
    """P2G into one node ``e = (node, φ, ∇φ)`` of ``a = (m, m v, m b)`` and ``t = V σ`` (row by
    row): ``φ m``, ``φ m v`` and :func:`add_force`."""
    node, S, gx, gy, gz = e
    m, mvx, mvy, mvz, bfx, bfy, bfz = a
    g[0, node] += m * S
    g[1, node] += mvx * S
    g[2, node] += mvy * S
    g[3, node] += mvz * S
    add_force(g, node, S, gx, gy, gz, (bfx, bfy, bfz), t, forced)


@loop_kernel
def p2g_hat(lcr, boxes, order, fields, bforce, gsum, err):
    """Mass, momentum and force (``gsum``) of every patch slot from its particles (``lcr`` unused:
    the signature is the CPDI kernel's)."""
    start = boxes.start
    x, v, F, mass, vol0, stress = (fields.x, fields.v, fields.F, fields.mass, fields.vol0,
                                   fields.stress)
    forced = bforce.shape[0] > 0
    gsum[:] = 0.0
    ox, oy, oz, ihx, ihy, ihz, L0, L01 = frame_3d(boxes)
    for p in range(start.size - 1):
        g = gsum[p]
        bx, by, bz, jlx, jly, jlz, jhx, jhy, jhz = slot_3d(boxes, p)
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            if order is None:  # rows in canonical order (compiled apart: no load)
                i = kk
            else:
                i = order[kk]  # the physical row (Particles.order)
            jx, fx = hat_cell_of((x[i, 0] - ox) * ihx, bx, jlx, jhx)
            jy, fy = hat_cell_of((x[i, 1] - oy) * ihy, by, jly, jhy)
            jz, fz = hat_cell_of((x[i, 2] - oz) * ihz, bz, jlz, jhz)
            if jx < 0 or jy < 0 or jz < 0:
                if err[0] < 0:
                    err[0] = i
                continue
            f00, f01, f02 = F[i, 0, 0], F[i, 0, 1], F[i, 0, 2]
            f10, f11, f12 = F[i, 1, 0], F[i, 1, 1], F[i, 1, 2]
            f20, f21, f22 = F[i, 2, 0], F[i, 2, 1], F[i, 2, 2]
            V = det_3d(f00, f01, f02, f10, f11, f12, f20, f21, f22) * vol0[i]
            t = (V * stress[i, 0, 0], V * stress[i, 0, 1], V * stress[i, 0, 2],
                 V * stress[i, 1, 0], V * stress[i, 1, 1], V * stress[i, 1, 2],
                 V * stress[i, 2, 0], V * stress[i, 2, 1], V * stress[i, 2, 2])
            m = mass[i]
            bfx = m * bforce[i, 0] if forced else 0.0
            bfy = m * bforce[i, 1] if forced else 0.0
            bfz = m * bforce[i, 2] if forced else 0.0
            a = (m, m * v[i, 0], m * v[i, 1], m * v[i, 2], bfx, bfy, bfz)
            n0 = jx + L0 * jy + L01 * jz
            e0, e1, e2, e3, e4, e5, e6, e7 = nodes8(n0, L0, L01, fx, fy, fz, ihx, ihy, ihz)
            scatter_node(g, e0, a, t, forced)
            scatter_node(g, e1, a, t, forced)
            scatter_node(g, e2, a, t, forced)
            scatter_node(g, e3, a, t, forced)
            scatter_node(g, e4, a, t, forced)
            scatter_node(g, e5, a, t, forced)
            scatter_node(g, e6, a, t, forced)
            scatter_node(g, e7, a, t, forced)


@loop_kernel
def p2g_momentum_hat(lcr, boxes, order, fields, gsum, err):
    """The MUSL re-map: momentum rows (1, 2, 3) of ``gsum`` only."""
    start = boxes.start
    x, v, mass = fields.x, fields.v, fields.mass
    gsum[:, 1:4, :] = 0.0
    ox, oy, oz, ihx, ihy, ihz, L0, L01 = frame_3d(boxes)
    for p in range(start.size - 1):
        g = gsum[p]
        bx, by, bz, jlx, jly, jlz, jhx, jhy, jhz = slot_3d(boxes, p)
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            if order is None:  # rows in canonical order (compiled apart: no load)
                i = kk
            else:
                i = order[kk]  # the physical row (Particles.order)
            jx, fx = hat_cell_of((x[i, 0] - ox) * ihx, bx, jlx, jhx)
            jy, fy = hat_cell_of((x[i, 1] - oy) * ihy, by, jly, jhy)
            jz, fz = hat_cell_of((x[i, 2] - oz) * ihz, bz, jlz, jhz)
            if jx < 0 or jy < 0 or jz < 0:
                if err[0] < 0:
                    err[0] = i
                continue
            m = mass[i]
            mvx, mvy, mvz = m * v[i, 0], m * v[i, 1], m * v[i, 2]
            n0 = jx + L0 * jy + L01 * jz
            for node, S, _, _, _ in nodes8(n0, L0, L01, fx, fy, fz, ihx, ihy, ihz):
                g[1, node] += mvx * S
                g[2, node] += mvy * S
                g[3, node] += mvz * S


@loop_kernel
def g2p_hat(mode, lcr, boxes, order, dt, flip, fields, material, gnew, err, locate):
    """G2P in one of the three modes; returns the largest ``c_p + |v_p|`` when the stress is
    updated."""
    start = boxes.start
    x, v, F, stress, dx = fields.x, fields.v, fields.F, fields.stress, fields.dx
    mat, params, damage = material
    slot_patch, new_patch = locate.slot_patch, locate.new_patch
    vmax = 0.0
    moved = 0
    first_out = -1
    ox, oy, oz, ihx, ihy, ihz, L0, L01 = frame_3d(boxes)
    for p in range(start.size - 1):
        g = gnew[p]
        sp = slot_patch[p]
        bx, by, bz, jlx, jly, jlz, jhx, jhy, jhz = slot_3d(boxes, p)
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            if order is None:  # rows in canonical order (compiled apart: no load)
                i = kk
            else:
                i = order[kk]  # the physical row (Particles.order)
            xx, xy, xz = x[i, 0], x[i, 1], x[i, 2]
            jx, fx = hat_cell_of((xx - ox) * ihx, bx, jlx, jhx)
            jy, fy = hat_cell_of((xy - oy) * ihy, by, jly, jhy)
            jz, fz = hat_cell_of((xz - oz) * ihz, bz, jlz, jhz)
            if jx < 0 or jy < 0 or jz < 0:
                if err[0] < 0:
                    err[0] = i
                new_patch[i] = sp
                continue
            n0 = jx + L0 * jy + L01 * jz
            vx = vy = vz = dvx = dvy = dvz = 0.0
            l00 = l01 = l02 = l10 = l11 = l12 = l20 = l21 = l22 = 0.0
            for node, S, gx, gy, gz in nodes8(n0, L0, L01, fx, fy, fz, ihx, ihy, ihz):
                nvx, nvy, nvz = g[0, node], g[1, node], g[2, node]
                if mode != G2P_MUSL_DEFORM:
                    vx += S * nvx
                    vy += S * nvy
                    vz += S * nvz
                    dvx += S * g[3, node]
                    dvy += S * g[4, node]
                    dvz += S * g[5, node]
                l00 += nvx * gx
                l01 += nvx * gy
                l02 += nvx * gz
                l10 += nvy * gx
                l11 += nvy * gy
                l12 += nvy * gz
                l20 += nvz * gx
                l21 += nvz * gy
                l22 += nvz * gz
            if mode != G2P_MUSL_DEFORM:
                v[i, 0] = flip_pic(flip, v[i, 0], dvx, vx)
                v[i, 1] = flip_pic(flip, v[i, 1], dvy, vy)
                v[i, 2] = flip_pic(flip, v[i, 2], dvz, vz)
                if mode != G2P_USL:
                    dx[i, 0], dx[i, 1], dx[i, 2] = dt * vx, dt * vy, dt * vz
                    continue
                x[i, 0], x[i, 1], x[i, 2] = xx + dt * vx, xy + dt * vy, xz + dt * vz
            else:
                x[i, 0], x[i, 1], x[i, 2] = xx + dx[i, 0], xy + dx[i, 1], xz + dx[i, 2]
            pid = next_patch_3d(x[i, 0], x[i, 1], x[i, 2], boxes.origin, boxes.inv_h, locate, p,
                                sp)
            moved, first_out = note_patch(new_patch, i, pid, sp, moved, first_out)
            vmax = update_F_stress(vmax, i, (dt * l00, dt * l01, dt * l02, dt * l10, dt * l11,
                                             dt * l12, dt * l20, dt * l21, dt * l22),
                                   (F[i, 0, 0], F[i, 0, 1], F[i, 0, 2], F[i, 1, 0], F[i, 1, 1],
                                    F[i, 1, 2], F[i, 2, 0], F[i, 2, 1], F[i, 2, 2]),
                                   v, F, stress, mat, params, damage)
    return vmax, moved, first_out
