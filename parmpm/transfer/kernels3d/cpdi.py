"""3D CPDI1 transfers, corner by corner (Sadeghirad, Brannon & Burghardt 2011).

A particle's domain ``R = F·R0`` (columns ``r1, r2, r3``; capped at ``l_cr`` by :func:`domain` when
domain scaling is on) has eight corners ``x_α = x_p + s1 r1 + s2 r2 + s3 r3`` (``s = ±1``; corner
``α`` has ``s_m = +1`` where bit ``m − 1`` of ``α`` is set, the generic kernel's order). With the
cofactor columns ``c1 = r2 × r3``, ``c2 = r3 × r1``, ``c3 = r1 × r2`` and ``V = 8 det R``:
``φ_ip = ⅛ Σ_α S_i(x_α)`` and ``∇φ_ip = (1/V) Σ_α S_i(x_α) g_α`` with ``g_α = s1 c1 + s2 c2 + s3 c3``.
So P2G scatters, per corner, ``⅛ m_p`` (mass), ``⅛ m_p v_p`` (momentum) and
``−(V_p/V) σ_p g_α (+ ⅛ m_p b_p)`` (force, ``V_p = J_p V0_p``) into the eight nodes of ``x_α``'s
cell with the trilinear weights ``S_i(x_α)``; G2P gathers ``v(x_α)`` and ``Δv(x_α)`` the same way
and forms ``v_p = ⅛ Σ v(x_α)``, ``Δv_p = ⅛ Σ Δv(x_α)`` and ``L_p = (1/V) Σ_α v(x_α) ⊗ g_α``.
Opposite corners (``α``, ``7 − α``) have opposite ``g``, so four stress products (P2G) and four
outer products (G2P) serve all eight corners.

Every corner's cell is located (and checked against the patch's box) before anything is
scattered, so a particle that reaches past the ghost layer contributes nothing and sets ``err``.
Grid rows: ``gsum[s] = (m, mv_x, mv_y, mv_z, f_x, f_y, f_z)``, ``gnew[s] = (v_x, v_y, v_z, Δv_x,
Δv_y, Δv_z)``, node ``i0 + L0 (i1 + L1 i2)`` of the patch's ghost-inclusive box. The loops are
:mod:`parmpm.transfer.kernels3d.loops`'.
"""
import numpy as np

from parmpm.core.jit import helper_kernel, loop_kernel
from parmpm.core.records import NO_SCALING
from parmpm.materials.kinematics import det_3d
from parmpm.shapes.cpdi import cofactor_3d
from parmpm.shapes.scaling import cap_3d
from parmpm.transfer.kernels2d.loops import stays
from parmpm.transfer.kernels3d.cells import cells_of8
from parmpm.transfer.kernels3d.hat import body_force
from parmpm.transfer.kernels3d.loops import ZERO9, each_particle, each_particle_g2p
from parmpm.transfer.update_order import G2P_MUSL_DEFORM, G2P_MUSL_MOTION


@helper_kernel
def domain(lcr, f00, f01, f02, f10, f11, f12, f20, f21, f22,
           q00, q01, q02, q10, q11, q12, q20, q21, q22):
    """``R = F·R0`` as ``(R00, R01, R02, R10, …, R22)`` (column ``m`` is ``r_{m+1}``), capped by
    :func:`parmpm.shapes.scaling.cap_3d` when domain scaling is on."""
    R00 = f00 * q00 + f01 * q10 + f02 * q20
    R01 = f00 * q01 + f01 * q11 + f02 * q21
    R02 = f00 * q02 + f01 * q12 + f02 * q22
    R10 = f10 * q00 + f11 * q10 + f12 * q20
    R11 = f10 * q01 + f11 * q11 + f12 * q21
    R12 = f10 * q02 + f11 * q12 + f12 * q22
    R20 = f20 * q00 + f21 * q10 + f22 * q20
    R21 = f20 * q01 + f21 * q11 + f22 * q21
    R22 = f20 * q02 + f21 * q12 + f22 * q22
    if lcr < NO_SCALING:  # a cap no vector reaches changes nothing: skip it
        R00, R01, R02, R10, R11, R12, R20, R21, R22, _ = cap_3d(lcr, R00, R01, R02, R10, R11, R12,
                                                                R20, R21, R22)
    return R00, R01, R02, R10, R11, R12, R20, R21, R22


@helper_kernel
def axis_corners(xk, a0, a1, a2, b, jl, jh):
    """Local cells and fractions along one axis of the eight corners ``xk + s1 a0 + s2 a1 + s3 a2``
    (grid units): ``(j0..7, f0..7, ok)``."""
    p0, p1 = (xk - a0) - a1, (xk + a0) - a1
    p2, p3 = (xk - a0) + a1, (xk + a0) + a1
    return cells_of8(p0 - a2, p1 - a2, p2 - a2, p3 - a2, p0 + a2, p1 + a2, p2 + a2, p3 + a2,
                     b, jl, jh)


@helper_kernel
def cell_nodes(L0, L01, jx, jy, jz, fx, fy, fz):
    """The eight ``(node, S_node(f))`` of local cell ``(jx, jy, jz)`` at fractions ``(fx, fy, fz)``,
    x fastest. Node indices are unsigned: they are never negative (the cell was checked), and
    numba then indexes without a wrap-around test (~8 % fewer instructions in P2G)."""
    gx, gy, gz = 1.0 - fx, 1.0 - fy, 1.0 - fz
    w00, w10, w01, w11 = gy * gz, fy * gz, gy * fz, fy * fz
    n0 = np.uint64(jx + L0 * jy + L01 * jz)
    n2, n4, one = n0 + np.uint64(L0), n0 + np.uint64(L01), np.uint64(1)
    n6 = n4 + np.uint64(L0)
    return ((n0, gx * w00), (n0 + one, fx * w00), (n2, gx * w10), (n2 + one, fx * w10),
            (n4, gx * w01), (n4 + one, fx * w01), (n6, gx * w11), (n6 + one, fx * w11))


@helper_kernel
def scatter7(g, L0, L01, jx, jy, jz, fx, fy, fz, a0, a1, a2, a3, a4, a5, a6):
    """``g[c, node] += S_node(f) · a_c`` (rows 0..6) over the eight nodes of local cell
    ``(jx, jy, jz)``."""
    for n, s in cell_nodes(L0, L01, jx, jy, jz, fx, fy, fz):
        g[0, n] += a0 * s
        g[1, n] += a1 * s
        g[2, n] += a2 * s
        g[3, n] += a3 * s
        g[4, n] += a4 * s
        g[5, n] += a5 * s
        g[6, n] += a6 * s


@helper_kernel
def scatter_mv(g, L0, L01, jx, jy, jz, fx, fy, fz, a1, a2, a3):
    """Rows 1..3 (momentum) of :func:`scatter7`."""
    for n, s in cell_nodes(L0, L01, jx, jy, jz, fx, fy, fz):
        g[1, n] += a1 * s
        g[2, n] += a2 * s
        g[3, n] += a3 * s


@helper_kernel
def gather6(g, L0, L01, jx, jy, jz, fx, fy, fz):
    """Trilinear interpolation of rows 0..5 of ``g`` at fractions ``(fx, fy, fz)`` of a local
    cell."""
    u0 = u1 = u2 = u3 = u4 = u5 = 0.0
    for n, s in cell_nodes(L0, L01, jx, jy, jz, fx, fy, fz):
        u0 += s * g[0, n]
        u1 += s * g[1, n]
        u2 += s * g[2, n]
        u3 += s * g[3, n]
        u4 += s * g[4, n]
        u5 += s * g[5, n]
    return u0, u1, u2, u3, u4, u5


@helper_kernel
def gather3(g, L0, L01, jx, jy, jz, fx, fy, fz):
    """Rows 0..2 (velocity) of :func:`gather6`."""
    u0 = u1 = u2 = 0.0
    for n, s in cell_nodes(L0, L01, jx, jy, jz, fx, fy, fz):
        u0 += s * g[0, n]
        u1 += s * g[1, n]
        u2 += s * g[2, n]
    return u0, u1, u2


@helper_kernel
def corner_gradients(R00, R01, R02, R10, R11, R12, R20, R21, R22):
    """``g`` of the corners ``(+,+,+)``, ``(+,−,−)``, ``(−,+,−)``, ``(+,+,−)`` (the other four are
    their negatives) from the cofactor columns of :func:`parmpm.shapes.cpdi.cofactor_3d`, and
    ``det R``: ``(gA, gB, gC, gD as 12 scalars, det R)``."""
    c1x, c1y, c1z, c2x, c2y, c2z, c3x, c3y, c3z, det = cofactor_3d(R00, R01, R02, R10, R11, R12,
                                                                   R20, R21, R22)
    return (c1x + c2x + c3x, c1y + c2y + c3y, c1z + c2z + c3z,
            c1x - c2x - c3x, c1y - c2y - c3y, c1z - c2z - c3z,
            c2x - c1x - c3x, c2y - c1y - c3y, c2z - c1z - c3z,
            c1x + c2x - c3x, c1y + c2y - c3y, c1z + c2z - c3z, det)


@helper_kernel
def sigma_dot(q, s00, s01, s02, s10, s11, s12, s20, s21, s22, gx, gy, gz):
    """``q σ g``."""
    return (q * (s00 * gx + s01 * gy + s02 * gz), q * (s10 * gx + s11 * gy + s12 * gz),
            q * (s20 * gx + s21 * gy + s22 * gz))


@helper_kernel
def support(i, frame, slot, lcr, fields):
    """Particle ``i``'s domain ``R`` (row by row) and its eight corners' local cells and fractions
    per axis: ``(R, jx, jy, jz, fx, fy, fz)``, tuples of 9 and 8."""
    x, F, r0 = fields.x, fields.F, fields.r0
    ox, oy, oz, ihx, ihy, ihz, _, _ = frame
    bx, by, bz, jlx, jly, jlz, jhx, jhy, jhz = slot
    R00, R01, R02, R10, R11, R12, R20, R21, R22 = domain(
        lcr, F[i, 0, 0], F[i, 0, 1], F[i, 0, 2], F[i, 1, 0], F[i, 1, 1], F[i, 1, 2],
        F[i, 2, 0], F[i, 2, 1], F[i, 2, 2],
        r0[i, 0, 0], r0[i, 0, 1], r0[i, 0, 2], r0[i, 1, 0], r0[i, 1, 1], r0[i, 1, 2],
        r0[i, 2, 0], r0[i, 2, 1], r0[i, 2, 2])
    jx0, jx1, jx2, jx3, jx4, jx5, jx6, jx7, fx0, fx1, fx2, fx3, fx4, fx5, fx6, fx7, okx = \
        axis_corners((x[i, 0] - ox) * ihx, R00 * ihx, R01 * ihx, R02 * ihx, bx, jlx, jhx)
    jy0, jy1, jy2, jy3, jy4, jy5, jy6, jy7, fy0, fy1, fy2, fy3, fy4, fy5, fy6, fy7, oky = \
        axis_corners((x[i, 1] - oy) * ihy, R10 * ihy, R11 * ihy, R12 * ihy, by, jly, jhy)
    jz0, jz1, jz2, jz3, jz4, jz5, jz6, jz7, fz0, fz1, fz2, fz3, fz4, fz5, fz6, fz7, okz = \
        axis_corners((x[i, 2] - oz) * ihz, R20 * ihz, R21 * ihz, R22 * ihz, bz, jlz, jhz)
    return (0 if okx and oky and okz else -1), (
        (R00, R01, R02, R10, R11, R12, R20, R21, R22),
        (jx0, jx1, jx2, jx3, jx4, jx5, jx6, jx7), (jy0, jy1, jy2, jy3, jy4, jy5, jy6, jy7),
        (jz0, jz1, jz2, jz3, jz4, jz5, jz6, jz7), (fx0, fx1, fx2, fx3, fx4, fx5, fx6, fx7),
        (fy0, fy1, fy2, fy3, fy4, fy5, fy6, fy7), (fz0, fz1, fz2, fz3, fz4, fz5, fz6, fz7))


@helper_kernel
def scatter(i, g, frame, st, fields, args):
    """Mass, momentum and force of particle ``i``, corner by corner."""
    v, F, mass, vol0, stress = fields.v, fields.F, fields.mass, fields.vol0, fields.stress
    bforce, forced = args
    L0, L01 = frame[6], frame[7]
    (R00, R01, R02, R10, R11, R12, R20, R21, R22), jx, jy, jz, fx, fy, fz = st
    gAx, gAy, gAz, gBx, gBy, gBz, gCx, gCy, gCz, gDx, gDy, gDz, det = corner_gradients(
        R00, R01, R02, R10, R11, R12, R20, R21, R22)
    J = det_3d(F[i, 0, 0], F[i, 0, 1], F[i, 0, 2], F[i, 1, 0], F[i, 1, 1], F[i, 1, 2],
               F[i, 2, 0], F[i, 2, 1], F[i, 2, 2])
    q = J * vol0[i] / (8.0 * det)
    s00, s01, s02 = stress[i, 0, 0], stress[i, 0, 1], stress[i, 0, 2]
    s10, s11, s12 = stress[i, 1, 0], stress[i, 1, 1], stress[i, 1, 2]
    s20, s21, s22 = stress[i, 2, 0], stress[i, 2, 1], stress[i, 2, 2]
    tAx, tAy, tAz = sigma_dot(q, s00, s01, s02, s10, s11, s12, s20, s21, s22, gAx, gAy, gAz)
    tBx, tBy, tBz = sigma_dot(q, s00, s01, s02, s10, s11, s12, s20, s21, s22, gBx, gBy, gBz)
    tCx, tCy, tCz = sigma_dot(q, s00, s01, s02, s10, s11, s12, s20, s21, s22, gCx, gCy, gCz)
    tDx, tDy, tDz = sigma_dot(q, s00, s01, s02, s10, s11, s12, s20, s21, s22, gDx, gDy, gDz)
    mq = mass[i] * 0.125
    mvx, mvy, mvz = mq * v[i, 0], mq * v[i, 1], mq * v[i, 2]
    bfx, bfy, bfz = body_force(bforce, forced, i, mq)
    # corner α has g = −gA, gB, gC, gD, −gD, −gC, −gB, gA; force −q σ g
    scatter7(g, L0, L01, jx[0], jy[0], jz[0], fx[0], fy[0], fz[0], mq, mvx, mvy, mvz,
             bfx + tAx, bfy + tAy, bfz + tAz)
    scatter7(g, L0, L01, jx[1], jy[1], jz[1], fx[1], fy[1], fz[1], mq, mvx, mvy, mvz,
             bfx - tBx, bfy - tBy, bfz - tBz)
    scatter7(g, L0, L01, jx[2], jy[2], jz[2], fx[2], fy[2], fz[2], mq, mvx, mvy, mvz,
             bfx - tCx, bfy - tCy, bfz - tCz)
    scatter7(g, L0, L01, jx[3], jy[3], jz[3], fx[3], fy[3], fz[3], mq, mvx, mvy, mvz,
             bfx - tDx, bfy - tDy, bfz - tDz)
    scatter7(g, L0, L01, jx[4], jy[4], jz[4], fx[4], fy[4], fz[4], mq, mvx, mvy, mvz,
             bfx + tDx, bfy + tDy, bfz + tDz)
    scatter7(g, L0, L01, jx[5], jy[5], jz[5], fx[5], fy[5], fz[5], mq, mvx, mvy, mvz,
             bfx + tCx, bfy + tCy, bfz + tCz)
    scatter7(g, L0, L01, jx[6], jy[6], jz[6], fx[6], fy[6], fz[6], mq, mvx, mvy, mvz,
             bfx + tBx, bfy + tBy, bfz + tBz)
    scatter7(g, L0, L01, jx[7], jy[7], jz[7], fx[7], fy[7], fz[7], mq, mvx, mvy, mvz,
             bfx - tAx, bfy - tAy, bfz - tAz)


@helper_kernel
def scatter_momentum(i, g, frame, st, fields, args):
    """Momentum of particle ``i``, corner by corner."""
    v, mass = fields.v, fields.mass
    L0, L01 = frame[6], frame[7]
    _, jx, jy, jz, fx, fy, fz = st
    mq = mass[i] * 0.125
    mvx, mvy, mvz = mq * v[i, 0], mq * v[i, 1], mq * v[i, 2]
    scatter_mv(g, L0, L01, jx[0], jy[0], jz[0], fx[0], fy[0], fz[0], mvx, mvy, mvz)
    scatter_mv(g, L0, L01, jx[1], jy[1], jz[1], fx[1], fy[1], fz[1], mvx, mvy, mvz)
    scatter_mv(g, L0, L01, jx[2], jy[2], jz[2], fx[2], fy[2], fz[2], mvx, mvy, mvz)
    scatter_mv(g, L0, L01, jx[3], jy[3], jz[3], fx[3], fy[3], fz[3], mvx, mvy, mvz)
    scatter_mv(g, L0, L01, jx[4], jy[4], jz[4], fx[4], fy[4], fz[4], mvx, mvy, mvz)
    scatter_mv(g, L0, L01, jx[5], jy[5], jz[5], fx[5], fy[5], fz[5], mvx, mvy, mvz)
    scatter_mv(g, L0, L01, jx[6], jy[6], jz[6], fx[6], fy[6], fz[6], mvx, mvy, mvz)
    scatter_mv(g, L0, L01, jx[7], jy[7], jz[7], fx[7], fy[7], fz[7], mvx, mvy, mvz)


@helper_kernel
def gather(step, i, g, frame, st, shape, fields):
    """``v_p = ⅛ Σ v(x_α)``, ``Δv_p`` alike (the deformation pass reads ``v`` alone) and ``Δt L``
    (not in MUSL's motion pass) at particle ``i`` from its eight corners."""
    mode, dt = step[0], step[1]
    L0, L01 = frame[6], frame[7]
    (R00, R01, R02, R10, R11, R12, R20, R21, R22), jx, jy, jz, fx, fy, fz = st
    vx = vy = vz = dvx = dvy = dvz = 0.0
    if mode == G2P_MUSL_DEFORM:
        u0x, u0y, u0z = gather3(g, L0, L01, jx[0], jy[0], jz[0], fx[0], fy[0], fz[0])
        u1x, u1y, u1z = gather3(g, L0, L01, jx[1], jy[1], jz[1], fx[1], fy[1], fz[1])
        u2x, u2y, u2z = gather3(g, L0, L01, jx[2], jy[2], jz[2], fx[2], fy[2], fz[2])
        u3x, u3y, u3z = gather3(g, L0, L01, jx[3], jy[3], jz[3], fx[3], fy[3], fz[3])
        u4x, u4y, u4z = gather3(g, L0, L01, jx[4], jy[4], jz[4], fx[4], fy[4], fz[4])
        u5x, u5y, u5z = gather3(g, L0, L01, jx[5], jy[5], jz[5], fx[5], fy[5], fz[5])
        u6x, u6y, u6z = gather3(g, L0, L01, jx[6], jy[6], jz[6], fx[6], fy[6], fz[6])
        u7x, u7y, u7z = gather3(g, L0, L01, jx[7], jy[7], jz[7], fx[7], fy[7], fz[7])
    else:
        u0x, u0y, u0z, d0x, d0y, d0z = gather6(g, L0, L01, jx[0], jy[0], jz[0], fx[0], fy[0], fz[0])
        u1x, u1y, u1z, d1x, d1y, d1z = gather6(g, L0, L01, jx[1], jy[1], jz[1], fx[1], fy[1], fz[1])
        u2x, u2y, u2z, d2x, d2y, d2z = gather6(g, L0, L01, jx[2], jy[2], jz[2], fx[2], fy[2], fz[2])
        u3x, u3y, u3z, d3x, d3y, d3z = gather6(g, L0, L01, jx[3], jy[3], jz[3], fx[3], fy[3], fz[3])
        u4x, u4y, u4z, d4x, d4y, d4z = gather6(g, L0, L01, jx[4], jy[4], jz[4], fx[4], fy[4], fz[4])
        u5x, u5y, u5z, d5x, d5y, d5z = gather6(g, L0, L01, jx[5], jy[5], jz[5], fx[5], fy[5], fz[5])
        u6x, u6y, u6z, d6x, d6y, d6z = gather6(g, L0, L01, jx[6], jy[6], jz[6], fx[6], fy[6], fz[6])
        u7x, u7y, u7z, d7x, d7y, d7z = gather6(g, L0, L01, jx[7], jy[7], jz[7], fx[7], fy[7], fz[7])
        vx = 0.125 * (u0x + u1x + u2x + u3x + u4x + u5x + u6x + u7x)
        vy = 0.125 * (u0y + u1y + u2y + u3y + u4y + u5y + u6y + u7y)
        vz = 0.125 * (u0z + u1z + u2z + u3z + u4z + u5z + u6z + u7z)
        dvx = 0.125 * (d0x + d1x + d2x + d3x + d4x + d5x + d6x + d7x)
        dvy = 0.125 * (d0y + d1y + d2y + d3y + d4y + d5y + d6y + d7y)
        dvz = 0.125 * (d0z + d1z + d2z + d3z + d4z + d5z + d6z + d7z)
    dtl = ZERO9
    if mode != G2P_MUSL_MOTION:
        # Δt L = Δt/V Σ v(x_α) ⊗ g_α, opposite corners paired (g: see scatter)
        gAx, gAy, gAz, gBx, gBy, gBz, gCx, gCy, gCz, gDx, gDy, gDz, det = corner_gradients(
            R00, R01, R02, R10, R11, R12, R20, R21, R22)
        wAx, wAy, wAz = u7x - u0x, u7y - u0y, u7z - u0z
        wBx, wBy, wBz = u1x - u6x, u1y - u6y, u1z - u6z
        wCx, wCy, wCz = u2x - u5x, u2y - u5y, u2z - u5z
        wDx, wDy, wDz = u3x - u4x, u3y - u4y, u3z - u4z
        k = dt / (8.0 * det)
        dtl = (k * (wAx * gAx + wBx * gBx + wCx * gCx + wDx * gDx),
               k * (wAx * gAy + wBx * gBy + wCx * gCy + wDx * gDy),
               k * (wAx * gAz + wBx * gBz + wCx * gCz + wDx * gDz),
               k * (wAy * gAx + wBy * gBx + wCy * gCx + wDy * gDx),
               k * (wAy * gAy + wBy * gBy + wCy * gCy + wDy * gDy),
               k * (wAy * gAz + wBy * gBz + wCy * gCz + wDy * gDz),
               k * (wAz * gAx + wBz * gBx + wCz * gCx + wDz * gDx),
               k * (wAz * gAy + wBz * gBy + wCz * gCy + wDz * gDy),
               k * (wAz * gAz + wBz * gBz + wCz * gCz + wDz * gDz))
    return (vx, vy, vz), (dvx, dvy, dvz), ZERO9, dtl, ()


@loop_kernel
def p2g_cpdi(lcr, boxes, order, fields, bforce, gsum, err):
    """Mass, momentum and force rows of ``gsum[slot]`` from every slot's particles."""
    gsum[:] = 0.0
    each_particle(support, scatter, boxes, order, gsum, err, lcr, fields,
                  (bforce, bforce.shape[0] > 0))


@loop_kernel
def p2g_momentum_cpdi(lcr, boxes, order, fields, gsum, err):
    """The MUSL re-map: momentum rows (1, 2, 3) of ``gsum`` only."""
    gsum[:, 1:4, :] = 0.0
    each_particle(support, scatter_momentum, boxes, order, gsum, err, lcr, fields, None)


@loop_kernel
def g2p_cpdi(mode, lcr, boxes, order, dt, flip, fields, material, gnew, err, locate):
    """G2P in one of the three modes (USL; MUSL motion; MUSL deformation) from
    ``gnew[slot] = (v, Δv)`` rows (the deformation mode reads only ``v``); returns the largest
    ``c_p + |v_p|`` in the modes that update the stress, the particles that changed patch and the
    first that left the grid."""
    return each_particle_g2p(support, gather, stays, (mode, dt, flip, False), boxes, order, gnew,
                             err, locate, lcr, fields, material)

