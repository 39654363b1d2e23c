"""2D MLS-MPM transfers (quadratic B-splines; Hu et al. 2018): APIC's momentum with the
force folded in, so P2G scatters three sums per node instead of five.

With ``r = x_i − x_p``, ``D⁻¹ = diag(4/Δx², 4/Δy²)`` and the MLS gradient ``∇̃φ = φ D⁻¹ r``
(:mod:`parmpm.transfer.affine`), the momentum the grid update would form is

    (mv)_i + Δt f_i = Σ_p φ_ip [m_p (v_p + Δt b_p) + A_p r],
    A_p = m_p C_p − Δt V_p σ_p D⁻¹,

one affine field per particle, scattered like APIC's. The force rows
``f_i = Σ φ (m b − V σ D⁻¹ r)`` are written only when ``account`` is set (the energy ledger reads
them; the grid update does not). G2P is :func:`parmpm.transfer.kernels2d.bspline.spline_gather`'s
with ``L_p = C_p``, and the MUSL re-map is APIC's
(:func:`~parmpm.transfer.kernels2d.bspline.p2g_momentum_bspline`).
"""
from parmpm.core.jit import helper_kernel, loop_kernel
from parmpm.materials.kinematics import det_2d
from parmpm.shapes.bspline import spline_weights
from parmpm.transfer.kernels2d.bspline import spline_gather, support
from parmpm.transfer.kernels2d.hat import body_force
from parmpm.transfer.kernels2d.loops import each_particle, each_particle_g2p, stays
from parmpm.transfer.sided import sided_node


@helper_kernel
def scatter(i, g, frame, st, fields, args, side):
    """Mass and momentum with ``Δt f`` folded in (and the force rows when ``account``) of particle
    ``i`` into its 3×3 nodes."""
    v, F, mass, vol0, stress = fields.v, fields.F, fields.mass, fields.vol0, fields.stress
    C = fields.affine
    dt, account, bforce, forced, hx, hy, dx4, dy4 = args
    _, _, ihx, ihy, L0 = frame
    kx, ky, tx, ty = st
    wx0, wx1, wx2, _, _, _ = spline_weights(tx, ihx)
    wy0, wy1, wy2, _, _, _ = spline_weights(ty, ihy)
    V = det_2d(F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1]) * vol0[i]
    m = mass[i]
    # the force's affine field K = −V σ D⁻¹ and the momentum's A = m C + Δt K
    k00, k01 = -V * stress[i, 0, 0] * dx4, -V * stress[i, 0, 1] * dy4
    k10, k11 = -V * stress[i, 1, 0] * dx4, -V * stress[i, 1, 1] * dy4
    a00, a01 = m * C[i, 0, 0] + dt * k00, m * C[i, 0, 1] + dt * k01
    a10, a11 = m * C[i, 1, 0] + dt * k10, m * C[i, 1, 1] + dt * k11
    bfx, bfy = body_force(bforce, forced, i, m)
    qx, qy = m * v[i, 0], m * v[i, 1]
    if forced:
        qx += dt * bfx
        qy += dt * bfy
    for b in range(3):
        wy = wy0 if b == 0 else (wy1 if b == 1 else wy2)
        ry = (b - 1 - ty) * hy
        qxb, qyb = qx + a01 * ry, qy + a11 * ry
        fxb, fyb = bfx + k01 * ry, bfy + k11 * ry
        row = kx + L0 * (ky + b)
        for a in range(3):
            wx = wx0 if a == 0 else (wx1 if a == 1 else wx2)
            rx = (a - 1 - tx) * hx
            S = wx * wy
            node = sided_node(side, i, row + a)
            g[0, node] += m * S
            g[1, node] += S * (qxb + a00 * rx)
            g[2, node] += S * (qyb + a10 * rx)
            if account:
                g[3, node] += S * (fxb + k00 * rx)
                g[4, node] += S * (fyb + k10 * rx)


@helper_kernel
def gather(step, i, g, frame, st, shape, fields, side):
    """:func:`~parmpm.transfer.kernels2d.bspline.spline_gather` with ``L_p = C_p``."""
    return spline_gather(step, i, g, frame, st, True, side)


@loop_kernel
def p2g_mls(dt, account, boxes, order, fields, bforce, gsum, err):
    """Mass and momentum with ``Δt f`` folded in (and the force rows when ``account``) of every
    patch slot from its particles, for the step ``dt``."""
    if account:
        gsum[:] = 0.0
    else:  # the force rows are neither written nor read (nor exchanged: the stepper)
        gsum[:, :3, :] = 0.0
    ihx, ihy = boxes.inv_h[0], boxes.inv_h[1]
    each_particle(support, scatter, boxes, order, gsum, err, 0.0, fields,
                  (dt, account, bforce, bforce.shape[0] > 0, 1.0 / ihx, 1.0 / ihy,
                   4.0 * ihx * ihx, 4.0 * ihy * ihy))


@loop_kernel
def g2p_mls(mode, lcr, boxes, order, dt, flip, fields, material, gnew, err, locate):
    """APIC's G2P with ``L_p = C_p`` (``lcr``, ``flip`` unused: the signature is the others')."""
    return each_particle_g2p(support, gather, stays,
                             (mode, dt, flip, fields.affine.shape[0] > 0), boxes, order, gnew,
                             err, locate, lcr, fields, material)
