"""3D MLS-MPM transfers: the 3D counterpart of :mod:`parmpm.transfer.kernels2d.mls` (APIC's momentum with
``Δt f`` folded in, four sums per node instead of seven; the force rows only for the energy
ledger). G2P is :func:`parmpm.transfer.kernels3d.bspline.spline_gather`'s with ``L_p = C_p``; the MUSL
re-map is APIC's.
"""
from parmpm.core.jit import helper_kernel, loop_kernel
from parmpm.materials.kinematics import det_3d
from parmpm.shapes.bspline import spline_weights
from parmpm.transfer.kernels2d.loops import stays
from parmpm.transfer.kernels3d.bspline import pick, spline_gather, support
from parmpm.transfer.kernels3d.hat import body_force
from parmpm.transfer.kernels3d.loops import each_particle, each_particle_g2p


@helper_kernel
def scatter(i, g, frame, st, fields, args):
    """Mass and momentum with ``Δt f`` folded in (and the force rows when ``account``) of particle
    ``i`` into its 3×3×3 nodes."""
    v, F, mass, vol0, stress = fields.v, fields.F, fields.mass, fields.vol0, fields.stress
    C = fields.affine
    dt, account, bforce, forced, hx, hy, hz, dx4, dy4, dz4 = args
    _, _, _, ihx, ihy, ihz, L0, L01 = frame
    kx, ky, kz, tx, ty, tz = st
    wx0, wx1, wx2, _, _, _ = spline_weights(tx, ihx)
    wy0, wy1, wy2, _, _, _ = spline_weights(ty, ihy)
    wz0, wz1, wz2, _, _, _ = spline_weights(tz, ihz)
    V = det_3d(F[i, 0, 0], F[i, 0, 1], F[i, 0, 2], F[i, 1, 0], F[i, 1, 1], F[i, 1, 2],
               F[i, 2, 0], F[i, 2, 1], F[i, 2, 2]) * vol0[i]
    m = mass[i]
    # the force's affine field K = −V σ D⁻¹ and the momentum's A = m C + Δt K
    sig = stress[i]
    k00, k01, k02 = -V * sig[0, 0] * dx4, -V * sig[0, 1] * dy4, -V * sig[0, 2] * dz4
    k10, k11, k12 = -V * sig[1, 0] * dx4, -V * sig[1, 1] * dy4, -V * sig[1, 2] * dz4
    k20, k21, k22 = -V * sig[2, 0] * dx4, -V * sig[2, 1] * dy4, -V * sig[2, 2] * dz4
    cp = C[i]
    a00, a01, a02 = m * cp[0, 0] + dt * k00, m * cp[0, 1] + dt * k01, m * cp[0, 2] + dt * k02
    a10, a11, a12 = m * cp[1, 0] + dt * k10, m * cp[1, 1] + dt * k11, m * cp[1, 2] + dt * k12
    a20, a21, a22 = m * cp[2, 0] + dt * k20, m * cp[2, 1] + dt * k21, m * cp[2, 2] + dt * k22
    bfx, bfy, bfz = body_force(bforce, forced, i, m)
    qx, qy, qz = m * v[i, 0], m * v[i, 1], m * v[i, 2]
    if forced:
        qx += dt * bfx
        qy += dt * bfy
        qz += dt * bfz
    for c in range(3):
        wz = pick(c, wz0, wz1, wz2)
        rz = (c - 1 - tz) * hz
        for b in range(3):
            wyz = pick(b, wy0, wy1, wy2) * wz
            ry = (b - 1 - ty) * hy
            qxr = qx + a01 * ry + a02 * rz
            qyr = qy + a11 * ry + a12 * rz
            qzr = qz + a21 * ry + a22 * rz
            row = kx + L0 * (ky + b) + L01 * (kz + c)
            for a in range(3):
                S = pick(a, wx0, wx1, wx2) * wyz
                rx = (a - 1 - tx) * hx
                node = row + a
                g[0, node] += m * S
                g[1, node] += S * (qxr + a00 * rx)
                g[2, node] += S * (qyr + a10 * rx)
                g[3, node] += S * (qzr + a20 * rx)
                if account:
                    g[4, node] += S * (bfx + k00 * rx + k01 * ry + k02 * rz)
                    g[5, node] += S * (bfy + k10 * rx + k11 * ry + k12 * rz)
                    g[6, node] += S * (bfz + k20 * rx + k21 * ry + k22 * rz)


@helper_kernel
def gather(step, i, g, frame, st, shape, fields):
    """:func:`~parmpm.transfer.kernels3d.bspline.spline_gather` with ``L_p = C_p``."""
    return spline_gather(step, i, g, frame, st, True)


@loop_kernel
def p2g_mls(dt, account, boxes, order, fields, bforce, gsum, err):
    """Mass and momentum with ``Δt f`` folded in (and the force rows when ``account``) of every
    patch slot from its particles, for the step ``dt``."""
    if account:
        gsum[:] = 0.0
    else:  # the force rows are neither written nor read (nor exchanged: the stepper)
        gsum[:, :4, :] = 0.0
    ihx, ihy, ihz = boxes.inv_h[0], boxes.inv_h[1], boxes.inv_h[2]
    each_particle(support, scatter, boxes, order, gsum, err, 0.0, fields,
                  (dt, account, bforce, bforce.shape[0] > 0, 1.0 / ihx, 1.0 / ihy, 1.0 / ihz,
                   4.0 * ihx * ihx, 4.0 * ihy * ihy, 4.0 * ihz * ihz))


@loop_kernel
def g2p_mls(mode, lcr, boxes, order, dt, flip, fields, material, gnew, err, locate):
    """APIC's G2P with ``L_p = C_p`` (``lcr``, ``flip`` unused: the signature is the others')."""
    return each_particle_g2p(support, gather, stays,
                             (mode, dt, flip, fields.affine.shape[0] > 0), boxes, order, gnew,
                             err, locate, lcr, fields, material)
