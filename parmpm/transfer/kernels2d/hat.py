"""2D standard-MPM transfers: the bilinear hat at the particle centre.

With ``ξ = (x_p − origin)/Δx`` in cell ``(j_x, j_y)`` at fractions ``(f_x, f_y)`` the four nodes
get ``φ = S_x S_y`` (``S = 1 − f`` or ``f``) and ``∇φ = (S'_x S_y, S_x S'_y)`` with
``S' = ∓1/Δx``. P2G scatters ``φ m_p``, ``φ m_p v_p`` and ``−V_p σ_p ∇φ (+ φ m_p b_p)``; G2P
gathers ``v_p = Σ φ v_i``, ``Δv_p = Σ φ Δv_i`` and ``L_p = Σ v_i ⊗ ∇φ``
(:mod:`parmpm.transfer.generic` has the full step).
"""
import numpy as np

from parmpm.core.jit import inline_kernel, loop_kernel
from parmpm.transfer.kernels2d.cells import frame_2d, hat_cell_of, note_patch, slot_2d
from parmpm.transfer.kernels2d.material import update_F_stress
from parmpm.materials.kinematics import det_2d, flip_pic
from parmpm.grid.patch_index import next_patch_2d
from parmpm.transfer.update_order import G2P_MUSL_DEFORM, G2P_USL


@inline_kernel
def add_force(g, node, S, gx, gy, bfx, bfy, t, forced):
    """P2G's force rows of one node: ``φ m b − V σ ∇φ`` (``t = V σ``, row by row), or ``− V σ ∇φ``
    alone when no body force acts (``forced`` False): the same sums without the ``0·φ`` terms,
    which strict IEEE arithmetic keeps (15 % of 2D MPM's P2G)."""
    t00, t01, t10, t11 = t
    if forced:
        g[3, node] += bfx * S - (t00 * gx + t01 * gy)
        g[4, node] += bfy * S - (t10 * gx + t11 * gy)
    else:
        g[3, node] -= t00 * gx + t01 * gy
        g[4, node] -= t10 * gx + t11 * gy


@loop_kernel
def p2g_hat(lcr, boxes, order, fields, bforce, gsum, err):
    """Mass, momentum and force (``gsum``) of every patch slot from its particles (``lcr`` unused:
    the signature is the CPDI kernel's)."""
    start = boxes.start
    x, v, F, mass, vol0, stress = (fields.x, fields.v, fields.F, fields.mass, fields.vol0,
                                   fields.stress)
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
            jx, fx = hat_cell_of((x[i, 0] - ox) * ihx, bx, jlx, jhx)
            jy, fy = hat_cell_of((x[i, 1] - oy) * ihy, by, jly, jhy)
            if jx < 0 or jy < 0:
                if err[0] < 0:
                    err[0] = i
                continue
            V = det_2d(F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1]) * vol0[i]
            t00, t01 = V * stress[i, 0, 0], V * stress[i, 0, 1]
            t10, t11 = V * stress[i, 1, 0], V * stress[i, 1, 1]
            m = mass[i]
            mvx, mvy = m * v[i, 0], m * v[i, 1]
            bfx = m * bforce[i, 0] if forced else 0.0
            bfy = m * bforce[i, 1] if forced else 0.0
            n0 = jx + L0 * jy
            for e in range(4):
                sx = fx if e & 1 else 1.0 - fx
                sy = fy if e & 2 else 1.0 - fy
                gx = (ihx if e & 1 else -ihx) * sy
                gy = sx * (ihy if e & 2 else -ihy)
                S = sx * sy
                node = n0 + (e & 1) + (L0 if e & 2 else 0)
                g[0, node] += m * S
                g[1, node] += mvx * S
                g[2, node] += mvy * S
                add_force(g, node, S, gx, gy, bfx, bfy, (t00, t01, t10, t11), forced)


@loop_kernel
def p2g_momentum_hat(lcr, boxes, order, fields, gsum, err):
    """The MUSL re-map: momentum only, into ``gsum[..., 1:3]``."""
    start = boxes.start
    x, v, mass = fields.x, fields.v, fields.mass
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
            jx, fx = hat_cell_of((x[i, 0] - ox) * ihx, bx, jlx, jhx)
            jy, fy = hat_cell_of((x[i, 1] - oy) * ihy, by, jly, jhy)
            if jx < 0 or jy < 0:
                if err[0] < 0:
                    err[0] = i
                continue
            mvx, mvy = mass[i] * v[i, 0], mass[i] * v[i, 1]
            n0 = jx + L0 * jy
            for e in range(4):
                S = (fx if e & 1 else 1.0 - fx) * (fy if e & 2 else 1.0 - fy)
                node = n0 + (e & 1) + (L0 if e & 2 else 0)
                g[1, node] += mvx * S
                g[2, node] += mvy * S


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
            xx, xy = x[i, 0], x[i, 1]
            jx, fx = hat_cell_of((xx - ox) * ihx, bx, jlx, jhx)
            jy, fy = hat_cell_of((xy - oy) * ihy, by, jly, jhy)
            if jx < 0 or jy < 0:
                if err[0] < 0:
                    err[0] = i
                new_patch[i] = sp
                continue
            n0 = jx + L0 * jy
            n2 = n0 + L0
            ux0, ux1, ux2, ux3 = g[0, n0], g[0, n0 + 1], g[0, n2], g[0, n2 + 1]
            uy0, uy1, uy2, uy3 = g[1, n0], g[1, n0 + 1], g[1, n2], g[1, n2 + 1]
            gx, gy = 1.0 - fx, 1.0 - fy
            s0, s1, s2, s3 = gx * gy, fx * gy, gx * fy, fx * fy
            vx = s0 * ux0 + s1 * ux1 + s2 * ux2 + s3 * ux3
            vy = s0 * uy0 + s1 * uy1 + s2 * uy2 + s3 * uy3
            dvx = s0 * g[2, n0] + s1 * g[2, n0 + 1] + s2 * g[2, n2] + s3 * g[2, n2 + 1]
            dvy = s0 * g[3, n0] + s1 * g[3, n0 + 1] + s2 * g[3, n2] + s3 * g[3, n2 + 1]
            # L = Σ v_i ⊗ ∇φ_i with ∇φ = (±S_y/Δx, ±S_x/Δy), factored per axis
            l00 = ihx * (gy * (ux1 - ux0) + fy * (ux3 - ux2))
            l01 = ihy * (gx * (ux2 - ux0) + fx * (ux3 - ux1))
            l10 = ihx * (gy * (uy1 - uy0) + fy * (uy3 - uy2))
            l11 = ihy * (gx * (uy2 - uy0) + fx * (uy3 - uy1))
            if mode != G2P_MUSL_DEFORM:
                vpx, vpy = v[i, 0], v[i, 1]
                v[i, 0] = flip_pic(flip, vpx, dvx, vx)
                v[i, 1] = flip_pic(flip, vpy, dvy, vy)
                if mode == G2P_USL:
                    x[i, 0] = xx + dt * vx
                    x[i, 1] = xy + dt * vy
                else:
                    dx[i, 0] = dt * vx
                    dx[i, 1] = dt * vy
                    continue
            else:
                x[i, 0] = xx + dx[i, 0]
                x[i, 1] = xy + dx[i, 1]
            # where it goes next
            pid = next_patch_2d(x[i, 0], x[i, 1], boxes.origin, boxes.inv_h, locate, p, sp)
            moved, first_out = note_patch(new_patch, np.int64(i), pid, sp, moved, first_out)
            f00, f01, f10, f11 = F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1]
            l00, l01, l10, l11 = dt * l00, dt * l01, dt * l10, dt * l11
            vmax = update_F_stress(vmax, i, (l00, l01, l10, l11), (f00, f01, f10, f11), v, F,
                                   stress, mat, params, damage)
    return vmax, moved, first_out
