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
The loops are :mod:`parmpm.transfer.kernels2d.loops`'.
"""
from parmpm.core.jit import helper_kernel, loop_kernel
from parmpm.core.records import NO_SCALING
from parmpm.materials.kinematics import det_2d
from parmpm.shapes.cpdi import cofactor_2d
from parmpm.shapes.scaling import cap_2d
from parmpm.transfer.kernels2d.cells import cell_nodes, cells_of4
from parmpm.transfer.kernels2d.hat import body_force
from parmpm.transfer.kernels2d.loops import NO_AFFINE, each_particle, each_particle_g2p, stays
from parmpm.transfer.update_order import G2P_MUSL_MOTION


@helper_kernel
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


@helper_kernel
def corner_gradients(r1x, r1y, r2x, r2y):
    """``g`` of corners (+,+) and (+,−) (their opposites have ``−g``) from the cofactor columns,
    and ``det R``: ``(gax, gay, gbx, gby, det)``."""
    c1x, c1y, c2x, c2y, det = cofactor_2d(r1x, r1y, r2x, r2y)
    return c1x + c2x, c1y + c2y, c1x - c2x, c1y - c2y, det


@helper_kernel
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


@helper_kernel
def add5(g, n, s, a0, a1, a2, a3, a4):
    """``g[c, n] += a_c · s`` for the five rows (mass, momentum, force)."""
    g[0, n] += a0 * s
    g[1, n] += a1 * s
    g[2, n] += a2 * s
    g[3, n] += a3 * s
    g[4, n] += a4 * s


@helper_kernel
def add_momentum(g, n, s, a1, a2):
    """``g[c, n] += a_c · s`` for the momentum rows 1 and 2."""
    g[1, n] += a1 * s
    g[2, n] += a2 * s


@helper_kernel
def scatter5(g, side, i, L0, jx, jy, fx, fy, a0, a1, a2, a3, a4):
    """``g[c, node] += S_node(f) · a_c`` over the four nodes of local cell ``(jx, jy)``."""
    n0, n1, n2, n3 = cell_nodes(side, i, L0, jx, jy)
    s0 = (1.0 - fx) * (1.0 - fy)
    s1 = fx * (1.0 - fy)
    s2 = (1.0 - fx) * fy
    s3 = fx * fy
    add5(g, n0, s0, a0, a1, a2, a3, a4)
    add5(g, n1, s1, a0, a1, a2, a3, a4)
    add5(g, n2, s2, a0, a1, a2, a3, a4)
    add5(g, n3, s3, a0, a1, a2, a3, a4)


@helper_kernel
def scatter_mv(g, side, i, L0, jx, jy, fx, fy, a1, a2):
    """Rows 1 and 2 (momentum) of :func:`scatter5`."""
    n0, n1, n2, n3 = cell_nodes(side, i, L0, jx, jy)
    s0 = (1.0 - fx) * (1.0 - fy)
    s1 = fx * (1.0 - fy)
    s2 = (1.0 - fx) * fy
    s3 = fx * fy
    add_momentum(g, n0, s0, a1, a2)
    add_momentum(g, n1, s1, a1, a2)
    add_momentum(g, n2, s2, a1, a2)
    add_momentum(g, n3, s3, a1, a2)


@helper_kernel
def gather4(g, side, i, L0, jx, jy, fx, fy):
    """Bilinear interpolation of rows 0..3 of ``g`` at fractions ``(fx, fy)`` of a local cell."""
    n0, n1, n2, n3 = cell_nodes(side, i, L0, jx, jy)
    s0 = (1.0 - fx) * (1.0 - fy)
    s1 = fx * (1.0 - fy)
    s2 = (1.0 - fx) * fy
    s3 = fx * fy
    return (s0 * g[0, n0] + s1 * g[0, n1] + s2 * g[0, n2] + s3 * g[0, n3],
            s0 * g[1, n0] + s1 * g[1, n1] + s2 * g[1, n2] + s3 * g[1, n3],
            s0 * g[2, n0] + s1 * g[2, n1] + s2 * g[2, n2] + s3 * g[2, n3],
            s0 * g[3, n0] + s1 * g[3, n1] + s2 * g[3, n2] + s3 * g[3, n3])


@helper_kernel
def support(i, frame, slot, lcr, fields):
    """Particle ``i``'s domain ``(r1x, r1y, r2x, r2y)`` and its corners' local cells and fractions
    ``(jx0..3, jy0..3, fx0..3, fy0..3)``."""
    x, F, r0 = fields.x, fields.F, fields.r0
    ox, oy, ihx, ihy, _ = frame
    bx, by, jlx, jly, jhx, jhy = slot
    r1x, r1y, r2x, r2y = domain(lcr, F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1],
                                r0[i, 0, 0], r0[i, 0, 1], r0[i, 1, 0], r0[i, 1, 1])
    (jx0, jx1, jx2, jx3, jy0, jy1, jy2, jy3, fx0, fx1, fx2, fx3, fy0, fy1, fy2, fy3,
     ok) = corners((x[i, 0] - ox) * ihx, (x[i, 1] - oy) * ihy, r1x, r1y, r2x, r2y,
                   ihx, ihy, bx, by, jlx, jly, jhx, jhy)
    return (0 if ok else -1), ((r1x, r1y, r2x, r2y), (jx0, jx1, jx2, jx3), (jy0, jy1, jy2, jy3),
                               (fx0, fx1, fx2, fx3), (fy0, fy1, fy2, fy3))


@helper_kernel
def scatter(i, g, frame, st, fields, args, side):
    """Mass, momentum and force of particle ``i``, corner by corner."""
    v, F, mass, vol0, stress = fields.v, fields.F, fields.mass, fields.vol0, fields.stress
    bforce, forced = args
    L0 = frame[4]
    (r1x, r1y, r2x, r2y), (jx0, jx1, jx2, jx3), (jy0, jy1, jy2, jy3), fx, fy = st
    gax, gay, gbx, gby, det = corner_gradients(r1x, r1y, r2x, r2y)
    q = det_2d(F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1]) * vol0[i] / (4.0 * det)
    t00, t01, t10, t11 = stress[i, 0, 0], stress[i, 0, 1], stress[i, 1, 0], stress[i, 1, 1]
    mq = mass[i] * 0.25
    mvx, mvy = mq * v[i, 0], mq * v[i, 1]
    bfx, bfy = body_force(bforce, forced, i, mq)
    tax, tay = q * (t00 * gax + t01 * gay), q * (t10 * gax + t11 * gay)
    tbx, tby = q * (t00 * gbx + t01 * gby), q * (t10 * gbx + t11 * gby)
    scatter5(g, side, i, L0, jx0, jy0, fx[0], fy[0], mq, mvx, mvy, bfx + tax, bfy + tay)
    scatter5(g, side, i, L0, jx1, jy1, fx[1], fy[1], mq, mvx, mvy, bfx - tbx, bfy - tby)
    scatter5(g, side, i, L0, jx2, jy2, fx[2], fy[2], mq, mvx, mvy, bfx + tbx, bfy + tby)
    scatter5(g, side, i, L0, jx3, jy3, fx[3], fy[3], mq, mvx, mvy, bfx - tax, bfy - tay)


@helper_kernel
def scatter_momentum(i, g, frame, st, fields, args, side):
    """Momentum of particle ``i``, corner by corner."""
    v, mass = fields.v, fields.mass
    L0 = frame[4]
    _, (jx0, jx1, jx2, jx3), (jy0, jy1, jy2, jy3), fx, fy = st
    mq = mass[i] * 0.25
    mvx, mvy = mq * v[i, 0], mq * v[i, 1]
    scatter_mv(g, side, i, L0, jx0, jy0, fx[0], fy[0], mvx, mvy)
    scatter_mv(g, side, i, L0, jx1, jy1, fx[1], fy[1], mvx, mvy)
    scatter_mv(g, side, i, L0, jx2, jy2, fx[2], fy[2], mvx, mvy)
    scatter_mv(g, side, i, L0, jx3, jy3, fx[3], fy[3], mvx, mvy)


@helper_kernel
def gather(step, i, g, frame, st, shape, fields, side):
    """``v_p = ¼ Σ v(x_α)``, ``Δv_p`` alike and ``Δt L`` (not in MUSL's motion pass, which stops
    before it) at particle ``i`` from its four corners."""
    mode, dt = step[0], step[1]
    L0 = frame[4]
    (r1x, r1y, r2x, r2y), (jx0, jx1, jx2, jx3), (jy0, jy1, jy2, jy3), fx, fy = st
    u0x, u0y, d0x, d0y = gather4(g, side, i, L0, jx0, jy0, fx[0], fy[0])
    u1x, u1y, d1x, d1y = gather4(g, side, i, L0, jx1, jy1, fx[1], fy[1])
    u2x, u2y, d2x, d2y = gather4(g, side, i, L0, jx2, jy2, fx[2], fy[2])
    u3x, u3y, d3x, d3y = gather4(g, side, i, L0, jx3, jy3, fx[3], fy[3])
    vx = 0.25 * (u0x + u1x + u2x + u3x)
    vy = 0.25 * (u0y + u1y + u2y + u3y)
    dvx = 0.25 * (d0x + d1x + d2x + d3x)
    dvy = 0.25 * (d0y + d1y + d2y + d3y)
    dtl = (0.0, 0.0, 0.0, 0.0)
    if mode != G2P_MUSL_MOTION:
        # L = (1/V) Σ v(x_α) ⊗ g_α with g = −ga, gb, −gb, ga for corners 0..3
        gax, gay, gbx, gby, det = corner_gradients(r1x, r1y, r2x, r2y)
        wax, way = u3x - u0x, u3y - u0y
        wbx, wby = u1x - u2x, u1y - u2y
        k = dt / (4.0 * det)
        dtl = (k * (wax * gax + wbx * gbx), k * (wax * gay + wbx * gby),
               k * (way * gax + wby * gbx), k * (way * gay + wby * gby))
    return (vx, vy), (dvx, dvy), NO_AFFINE, dtl, ()


@loop_kernel
def p2g_cpdi(lcr, boxes, order, fields, bforce, gsum, err):
    """Mass, momentum and force rows of ``gsum[slot]`` from every slot's particles."""
    gsum[:] = 0.0
    each_particle(support, scatter, boxes, order, gsum, err, lcr, fields,
                  (bforce, bforce.shape[0] > 0))


@loop_kernel
def p2g_momentum_cpdi(lcr, boxes, order, fields, gsum, err):
    """The MUSL re-map: momentum rows (1, 2) of ``gsum`` only."""
    gsum[:, 1:3, :] = 0.0
    each_particle(support, scatter_momentum, boxes, order, gsum, err, lcr, fields, None)


@loop_kernel
def g2p_cpdi(mode, lcr, boxes, order, dt, flip, fields, material, gnew, err, locate):
    """G2P in one of the three modes (USL; MUSL motion; MUSL deformation) from
    ``gnew[slot] = (v_x, v_y, Δv_x, Δv_y)`` rows; returns the largest ``c_p + |v_p|`` in the
    modes that update the stress, the particles that changed patch and the first that left the
    grid."""
    return each_particle_g2p(support, gather, stays, (mode, dt, flip, False), boxes, order, gnew,
                             err, locate, lcr, fields, material)

