"""2D standard-MPM transfers: the bilinear hat at the particle centre.

With ``ξ = (x_p − origin)/Δx`` in cell ``(j_x, j_y)`` at fractions ``(f_x, f_y)`` the four nodes
get ``φ = S_x S_y`` (``S = 1 − f`` or ``f``) and ``∇φ = (S'_x S_y, S_x S'_y)`` with
``S' = ∓1/Δx``. P2G scatters ``φ m_p``, ``φ m_p v_p`` and ``−V_p σ_p ∇φ (+ φ m_p b_p)``; G2P
gathers ``v_p = Σ φ v_i``, ``Δv_p = Σ φ Δv_i`` and ``L_p = Σ v_i ⊗ ∇φ``
(:mod:`parmpm.transfer.generic` has the full step). The loops are
:mod:`parmpm.transfer.kernels2d.loops`'; this module supplies the stencil and its sums.
"""
from parmpm.core.jit import helper_kernel, loop_kernel
from parmpm.materials.kinematics import det_2d
from parmpm.transfer.kernels2d.cells import cell_nodes, hat_cell_of
from parmpm.transfer.kernels2d.loops import (NO_AFFINE, centre_support, each_particle,
                                             each_particle_g2p, stays)
from parmpm.transfer.sided import sided_node


@helper_kernel
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


@helper_kernel
def support(i, frame, slot, lcr, fields):
    """Particle ``i``'s local cell and fractions ``(jx, jy, fx, fy)`` (``lcr`` unused)."""
    return centre_support(hat_cell_of, i, frame, slot, fields)


@helper_kernel
def volume_stress(i, fields):
    """``t = V_p σ_p`` (row by row) with ``V_p = J_p V0_p``."""
    F, stress = fields.F, fields.stress
    V = det_2d(F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1]) * fields.vol0[i]
    return V * stress[i, 0, 0], V * stress[i, 0, 1], V * stress[i, 1, 0], V * stress[i, 1, 1]


@helper_kernel
def body_force(bforce, forced, i, m):
    """``m b_p`` of particle ``i`` (zeros when no body force acts)."""
    return (m * bforce[i, 0] if forced else 0.0), (m * bforce[i, 1] if forced else 0.0)


@helper_kernel
def scatter(i, g, frame, st, fields, args, side):
    """Mass, momentum and force of particle ``i`` into its cell's four nodes."""
    v, mass = fields.v, fields.mass
    bforce, forced = args
    _, _, ihx, ihy, L0 = frame
    jx, jy, fx, fy = st
    t = volume_stress(i, fields)
    m = mass[i]
    mvx, mvy = m * v[i, 0], m * v[i, 1]
    bfx, bfy = body_force(bforce, forced, i, m)
    n0 = jx + L0 * jy
    for e in range(4):
        sx = fx if e & 1 else 1.0 - fx
        sy = fy if e & 2 else 1.0 - fy
        gx = (ihx if e & 1 else -ihx) * sy
        gy = sx * (ihy if e & 2 else -ihy)
        S = sx * sy
        node = sided_node(side, i, n0 + (e & 1) + (L0 if e & 2 else 0))
        g[0, node] += m * S
        g[1, node] += mvx * S
        g[2, node] += mvy * S
        add_force(g, node, S, gx, gy, bfx, bfy, t, forced)


@helper_kernel
def scatter_momentum(i, g, frame, st, fields, args, side):
    """Momentum of particle ``i`` into its cell's four nodes."""
    v, mass = fields.v, fields.mass
    L0 = frame[4]
    jx, jy, fx, fy = st
    mvx, mvy = mass[i] * v[i, 0], mass[i] * v[i, 1]
    n0 = jx + L0 * jy
    for e in range(4):
        S = (fx if e & 1 else 1.0 - fx) * (fy if e & 2 else 1.0 - fy)
        node = sided_node(side, i, n0 + (e & 1) + (L0 if e & 2 else 0))
        g[1, node] += mvx * S
        g[2, node] += mvy * S


@helper_kernel
def gather(step, i, g, frame, st, shape, fields, side):
    """``v``, ``Δv`` and ``Δt L`` at particle ``i`` from its cell's four nodes."""
    dt = step[1]
    _, _, ihx, ihy, L0 = frame
    jx, jy, fx, fy = st
    n0, n1, n2, n3 = cell_nodes(side, i, L0, jx, jy)
    ux0, ux1, ux2, ux3 = g[0, n0], g[0, n1], g[0, n2], g[0, n3]
    uy0, uy1, uy2, uy3 = g[1, n0], g[1, n1], g[1, n2], g[1, n3]
    gx, gy = 1.0 - fx, 1.0 - fy
    s0, s1, s2, s3 = gx * gy, fx * gy, gx * fy, fx * fy
    vx = s0 * ux0 + s1 * ux1 + s2 * ux2 + s3 * ux3
    vy = s0 * uy0 + s1 * uy1 + s2 * uy2 + s3 * uy3
    dvx = s0 * g[2, n0] + s1 * g[2, n1] + s2 * g[2, n2] + s3 * g[2, n3]
    dvy = s0 * g[3, n0] + s1 * g[3, n1] + s2 * g[3, n2] + s3 * g[3, n3]
    # L = Σ v_i ⊗ ∇φ_i with ∇φ = (±S_y/Δx, ±S_x/Δy), factored per axis
    l00 = ihx * (gy * (ux1 - ux0) + fy * (ux3 - ux2))
    l01 = ihy * (gx * (ux2 - ux0) + fx * (ux3 - ux1))
    l10 = ihx * (gy * (uy1 - uy0) + fy * (uy3 - uy2))
    l11 = ihy * (gx * (uy2 - uy0) + fx * (uy3 - uy1))
    return (vx, vy), (dvx, dvy), NO_AFFINE, (dt * l00, dt * l01, dt * l10, dt * l11), ()


@loop_kernel
def p2g_hat(lcr, boxes, order, fields, bforce, gsum, err):
    """Mass, momentum and force (``gsum``) of every patch slot from its particles (``lcr`` unused:
    the signature is the CPDI kernel's)."""
    gsum[:] = 0.0
    each_particle(support, scatter, boxes, order, gsum, err, lcr, fields,
                  (bforce, bforce.shape[0] > 0))


@loop_kernel
def p2g_momentum_hat(lcr, boxes, order, fields, gsum, err):
    """The MUSL re-map: momentum only, into ``gsum[..., 1:3]``."""
    gsum[:, 1:3, :] = 0.0
    each_particle(support, scatter_momentum, boxes, order, gsum, err, lcr, fields, None)


@loop_kernel
def g2p_hat(mode, lcr, boxes, order, dt, flip, fields, material, gnew, err, locate):
    """G2P in one of the three modes; returns the largest ``c_p + |v_p|`` when the stress is
    updated, the particles that changed patch and the first that left the grid."""
    return each_particle_g2p(support, gather, stays, (mode, dt, flip, False), boxes, order, gnew,
                             err, locate, lcr, fields, material)

