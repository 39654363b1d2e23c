"""3D standard-MPM transfers: the trilinear hat at the particle centre.

With ``ξ = (x_p − origin)/Δx`` in cell ``(j_x, j_y, j_z)`` at fractions ``(f_x, f_y, f_z)`` the
eight nodes get ``φ = S_x S_y S_z`` (``S = 1 − f`` or ``f``) and
``∇φ = (S'_x S_y S_z, S_x S'_y S_z, S_x S_y S'_z)`` with ``S' = ∓1/Δx``. P2G scatters ``φ m_p``,
``φ m_p v_p`` and ``−V_p σ_p ∇φ (+ φ m_p b_p)`` (``V_p = J_p V0_p``); G2P gathers
``v_p = Σ φ v_i``, ``Δv_p = Σ φ Δv_i`` and ``L_p = Σ v_i ⊗ ∇φ`` (:mod:`parmpm.transfer.generic` has the
full step). Grid rows as in :mod:`parmpm.transfer.kernels3d.cpdi`; node ``i0 + L0 (i1 + L1 i2)``.
The loops are :mod:`parmpm.transfer.kernels3d.loops`'.
"""
import numpy as np

from parmpm.core.jit import helper_kernel, loop_kernel
from parmpm.materials.kinematics import det_3d
from parmpm.transfer.kernels2d.cells import hat_cell_of
from parmpm.transfer.kernels2d.loops import stays
from parmpm.transfer.kernels3d.loops import ZERO9, centre_support, each_particle, each_particle_g2p
from parmpm.transfer.update_order import G2P_MUSL_DEFORM, G2P_MUSL_MOTION


@helper_kernel
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


@helper_kernel
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


@helper_kernel
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


@helper_kernel
def support(i, frame, slot, lcr, fields):
    """Particle ``i``'s local cell and fractions ``(jx, jy, jz, fx, fy, fz)`` (``lcr`` unused)."""
    return centre_support(hat_cell_of, i, frame, slot, fields)


@helper_kernel
def volume_stress(i, fields):
    """``t = V_p σ_p`` (row by row) with ``V_p = J_p V0_p``."""
    F, stress = fields.F, fields.stress
    V = det_3d(F[i, 0, 0], F[i, 0, 1], F[i, 0, 2], F[i, 1, 0], F[i, 1, 1], F[i, 1, 2],
               F[i, 2, 0], F[i, 2, 1], F[i, 2, 2]) * fields.vol0[i]
    return (V * stress[i, 0, 0], V * stress[i, 0, 1], V * stress[i, 0, 2],
            V * stress[i, 1, 0], V * stress[i, 1, 1], V * stress[i, 1, 2],
            V * stress[i, 2, 0], V * stress[i, 2, 1], V * stress[i, 2, 2])


@helper_kernel
def body_force(bforce, forced, i, m):
    """``m b_p`` of particle ``i`` (zeros when no body force acts)."""
    return ((m * bforce[i, 0] if forced else 0.0), (m * bforce[i, 1] if forced else 0.0),
            (m * bforce[i, 2] if forced else 0.0))


@helper_kernel
def scatter(i, g, frame, st, fields, args):
    """Mass, momentum and force of particle ``i`` into its cell's eight nodes."""
    v, mass = fields.v, fields.mass
    bforce, forced = args
    _, _, _, ihx, ihy, ihz, L0, L01 = frame
    jx, jy, jz, fx, fy, fz = st
    t = volume_stress(i, fields)
    m = mass[i]
    bfx, bfy, bfz = body_force(bforce, forced, i, m)
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


@helper_kernel
def scatter_momentum(i, g, frame, st, fields, args):
    """Momentum of particle ``i`` into its cell's eight nodes."""
    v, mass = fields.v, fields.mass
    _, _, _, ihx, ihy, ihz, L0, L01 = frame
    jx, jy, jz, fx, fy, fz = st
    m = mass[i]
    mvx, mvy, mvz = m * v[i, 0], m * v[i, 1], m * v[i, 2]
    n0 = jx + L0 * jy + L01 * jz
    for node, S, _, _, _ in nodes8(n0, L0, L01, fx, fy, fz, ihx, ihy, ihz):
        g[1, node] += mvx * S
        g[2, node] += mvy * S
        g[3, node] += mvz * S


@helper_kernel
def gather(step, i, g, frame, st, shape, fields):
    """``v``, ``Δv`` (not in MUSL's deformation pass, which reads neither) and ``Δt L`` at
    particle ``i`` from its cell's eight nodes."""
    mode, dt = step[0], step[1]
    _, _, _, ihx, ihy, ihz, L0, L01 = frame
    jx, jy, jz, fx, fy, fz = st
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
    dtl = ZERO9
    if mode != G2P_MUSL_MOTION:
        dtl = (dt * l00, dt * l01, dt * l02, dt * l10, dt * l11, dt * l12, dt * l20, dt * l21,
               dt * l22)
    return (vx, vy, vz), (dvx, dvy, dvz), ZERO9, dtl, ()


@loop_kernel
def p2g_hat(lcr, boxes, order, fields, bforce, gsum, err):
    """Mass, momentum and force (``gsum``) of every patch slot from its particles (``lcr`` unused:
    the signature is the CPDI kernel's)."""
    gsum[:] = 0.0
    each_particle(support, scatter, boxes, order, gsum, err, lcr, fields,
                  (bforce, bforce.shape[0] > 0))


@loop_kernel
def p2g_momentum_hat(lcr, boxes, order, fields, gsum, err):
    """The MUSL re-map: momentum rows (1, 2, 3) of ``gsum`` only."""
    gsum[:, 1:4, :] = 0.0
    each_particle(support, scatter_momentum, boxes, order, gsum, err, lcr, fields, None)


@loop_kernel
def g2p_hat(mode, lcr, boxes, order, dt, flip, fields, material, gnew, err, locate):
    """G2P in one of the three modes; returns the largest ``c_p + |v_p|`` when the stress is
    updated, the particles that changed patch and the first that left the grid."""
    return each_particle_g2p(support, gather, stays, (mode, dt, flip, False), boxes, order, gnew,
                             err, locate, lcr, fields, material)

