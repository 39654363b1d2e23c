"""2D CPDI2 transfers over a particle's four tracked corners (Sadeghirad, Brannon & Guilkey 2013).

The corners ``c_α`` (relative to the particle, bit order of :mod:`parmpm.shapes.cpdi2`:
``(−,−), (+,−), (−,+), (+,+)``) are capped at ``l_cr`` one by one. For the bilinear
quadrilateral they span, with ``a1 = (−c0 + c1 − c2 + c3)/4``, ``a2 = (−c0 − c1 + c2 + c3)/4`` and
``a3 = (c0 − c1 − c2 + c3)/4`` (so ``∂x/∂ξ = a1 + a3 η``, ``∂x/∂η = a2 + a3 ξ``), ``det J`` is linear,
``j0 + j1 ξ + j2 η`` with ``j0 = a1 × a2``, ``j1 = a1 × a3``, ``j2 = a3 × a2``, and the integrals of
:mod:`parmpm.shapes.cpdi2` have closed forms:

    V = 4 j0,    wf_α = 1/4 + (s0 j1 + s1 j2) / (12 j0),
    wg_α = (s0 a2_y − s1 a1_y, s1 a1_x − s0 a2_x) / V,

CPDI1's weights for the parallelogram ``(a1, a2)`` plus the ``wf`` correction of a non-affine
quadrilateral (``a3 ≠ 0``). P2G scatters, per corner, ``wf_α m_p`` (mass), ``wf_α m_p v_p``
(momentum) and ``−V_p σ_p wg_α (+ wf_α m_p b_p)`` into the four nodes of the corner's cell;
G2P gathers ``v(x_α)`` and ``Δv(x_α)`` and forms ``v_p = Σ wf_α v(x_α)`` (FLIP blend with
``Δv``), ``L_p = Σ v(x_α) ⊗ wg_α``, and moves each tracked corner with the velocity at its capped
position, ``c_α += Δt (v(x_α) − Σ wf v(x_α))`` (not a frozen particle's; under MUSL in the
deformation pass, with the re-mapped velocity: :mod:`parmpm.transfer.generic` says why).
A domain with ``V ≤ 0`` (or NaN) is reported as inverted (``err = (i, −2)``), one whose corners
leave the patch's box as out of reach (``err = (i, −1)``). The loops are
:mod:`parmpm.transfer.kernels2d.loops`'.
"""
import math

from parmpm.core.jit import helper_kernel, loop_kernel
from parmpm.core.records import NO_SCALING
from parmpm.materials.kinematics import det_2d
from parmpm.transfer.kernels2d.cells import cells_of4
from parmpm.transfer.kernels2d.cpdi import gather4, scatter5, scatter_mv
from parmpm.transfer.kernels2d.hat import body_force
from parmpm.transfer.kernels2d.loops import NO_AFFINE, each_particle, each_particle_g2p
from parmpm.transfer.update_order import G2P_MUSL_MOTION


@helper_kernel
def capped(lcr, cx, cy):
    """One corner shrunk to length ``lcr`` if longer (the same bits when it is not)."""
    if lcr < NO_SCALING:
        n = math.sqrt(cx * cx + cy * cy)
        if n > lcr:
            return cx * (lcr / n), cy * (lcr / n)
    return cx, cy


@helper_kernel
def quad(lcr, c, i):
    """Particle ``i``'s capped corners ``(x0, y0, …, x3, y3)``."""
    x0, y0 = capped(lcr, c[i, 0, 0], c[i, 0, 1])
    x1, y1 = capped(lcr, c[i, 1, 0], c[i, 1, 1])
    x2, y2 = capped(lcr, c[i, 2, 0], c[i, 2, 1])
    x3, y3 = capped(lcr, c[i, 3, 0], c[i, 3, 1])
    return x0, y0, x1, y1, x2, y2, x3, y3


@helper_kernel
def weights(x0, y0, x1, y1, x2, y2, x3, y3):
    """``(wf0..wf3, gx0, gy0, gx1, gy1, V)``: the corner weights, ``V·wg`` of corners 0 and 1
    (corners 3 and 2 have the opposite ``V·wg``) and the volume (module doc)."""
    a1x, a1y = 0.25 * ((x1 - x0) + (x3 - x2)), 0.25 * ((y1 - y0) + (y3 - y2))
    a2x, a2y = 0.25 * ((x2 - x0) + (x3 - x1)), 0.25 * ((y2 - y0) + (y3 - y1))
    a3x, a3y = 0.25 * ((x0 - x1) + (x3 - x2)), 0.25 * ((y0 - y1) + (y3 - y2))
    j0 = a1x * a2y - a1y * a2x
    j1 = a1x * a3y - a1y * a3x
    j2 = a3x * a2y - a3y * a2x
    e = 1.0 / (12.0 * j0)
    p, q = j1 * e, j2 * e
    # corner α = (s0, s1): 0 (−,−), 1 (+,−), 2 (−,+), 3 (+,+)
    wf0, wf1, wf2, wf3 = 0.25 - p - q, 0.25 + p - q, 0.25 - p + q, 0.25 + p + q
    # V·wg_α = (s0 a2y − s1 a1y, s1 a1x − s0 a2x)
    g0x, g0y = -a2y + a1y, -a1x + a2x
    g1x, g1y = a2y + a1y, -a1x - a2x
    return wf0, wf1, wf2, wf3, g0x, g0y, g1x, g1y, 4.0 * j0


@helper_kernel
def locate4(xx, xy, x0, y0, x1, y1, x2, y2, x3, y3, ihx, ihy, bx, by, jlx, jly, jhx, jhy):
    """Local cells and fractions of the four capped corners of a particle at grid coordinates
    ``(xx, xy)``: ``(jx0..3, jy0..3, fx0..3, fy0..3, ok)``."""
    jx0, jx1, jx2, jx3, fx0, fx1, fx2, fx3, okx = cells_of4(
        xx + x0 * ihx, xx + x1 * ihx, xx + x2 * ihx, xx + x3 * ihx, bx, jlx, jhx)
    jy0, jy1, jy2, jy3, fy0, fy1, fy2, fy3, oky = cells_of4(
        xy + y0 * ihy, xy + y1 * ihy, xy + y2 * ihy, xy + y3 * ihy, by, jly, jhy)
    return (jx0, jx1, jx2, jx3, jy0, jy1, jy2, jy3, fx0, fx1, fx2, fx3, fy0, fy1, fy2, fy3,
            okx and oky)


@helper_kernel
def support(i, frame, slot, lcr, fields):
    """Particle ``i``'s corner weights ``(wf0..3)``, ``V·wg`` of corners 0 and 1, ``V`` and its
    capped corners' local cells and fractions; code −2 when ``V ≤ 0`` (or NaN)."""
    x = fields.x
    ox, oy, ihx, ihy, _ = frame
    bx, by, jlx, jly, jhx, jhy = slot
    x0, y0, x1, y1, x2, y2, x3, y3 = quad(lcr, fields.corners, i)
    wf0, wf1, wf2, wf3, g0x, g0y, g1x, g1y, V = weights(x0, y0, x1, y1, x2, y2, x3, y3)
    (jx0, jx1, jx2, jx3, jy0, jy1, jy2, jy3, fx0, fx1, fx2, fx3, fy0, fy1, fy2, fy3,
     ok) = locate4((x[i, 0] - ox) * ihx, (x[i, 1] - oy) * ihy, x0, y0, x1, y1, x2, y2, x3, y3,
                   ihx, ihy, bx, by, jlx, jly, jhx, jhy)
    code = -2 if not V > 0.0 else (0 if ok else -1)
    return code, ((wf0, wf1, wf2, wf3), (g0x, g0y, g1x, g1y), V, (jx0, jx1, jx2, jx3),
                  (jy0, jy1, jy2, jy3), (fx0, fx1, fx2, fx3), (fy0, fy1, fy2, fy3))


@helper_kernel
def scatter(i, g, frame, st, fields, args, side):
    """Mass, momentum and force of particle ``i``, corner by corner."""
    v, F, mass, vol0, stress = fields.v, fields.F, fields.mass, fields.vol0, fields.stress
    bforce, forced = args
    L0 = frame[4]
    (wf0, wf1, wf2, wf3), (g0x, g0y, g1x, g1y), V, jx, jy, fx, fy = st
    q = det_2d(F[i, 0, 0], F[i, 0, 1], F[i, 1, 0], F[i, 1, 1]) * vol0[i] / V
    t00, t01, t10, t11 = stress[i, 0, 0], stress[i, 0, 1], stress[i, 1, 0], stress[i, 1, 1]
    m = mass[i]
    vx, vy = v[i, 0], v[i, 1]
    bfx, bfy = body_force(bforce, forced, i, m)
    # −V_p σ wg_α: corner 0 and 1, their opposites 3 and 2 with the other sign
    tax, tay = q * (t00 * g0x + t01 * g0y), q * (t10 * g0x + t11 * g0y)
    tbx, tby = q * (t00 * g1x + t01 * g1y), q * (t10 * g1x + t11 * g1y)
    if forced:
        f0x, f0y, f1x, f1y = bfx * wf0 - tax, bfy * wf0 - tay, bfx * wf1 - tbx, bfy * wf1 - tby
        f2x, f2y, f3x, f3y = bfx * wf2 + tbx, bfy * wf2 + tby, bfx * wf3 + tax, bfy * wf3 + tay
    else:  # no 0·φ terms: the same sums
        f0x, f0y, f1x, f1y, f2x, f2y, f3x, f3y = -tax, -tay, -tbx, -tby, tbx, tby, tax, tay
    scatter5(g, side, i, L0, jx[0], jy[0], fx[0], fy[0], m * wf0, m * wf0 * vx, m * wf0 * vy, f0x, f0y)
    scatter5(g, side, i, L0, jx[1], jy[1], fx[1], fy[1], m * wf1, m * wf1 * vx, m * wf1 * vy, f1x, f1y)
    scatter5(g, side, i, L0, jx[2], jy[2], fx[2], fy[2], m * wf2, m * wf2 * vx, m * wf2 * vy, f2x, f2y)
    scatter5(g, side, i, L0, jx[3], jy[3], fx[3], fy[3], m * wf3, m * wf3 * vx, m * wf3 * vy, f3x, f3y)


@helper_kernel
def scatter_momentum(i, g, frame, st, fields, args, side):
    """Momentum of particle ``i``, corner by corner."""
    v, mass = fields.v, fields.mass
    L0 = frame[4]
    (wf0, wf1, wf2, wf3), _, _, jx, jy, fx, fy = st
    mvx, mvy = mass[i] * v[i, 0], mass[i] * v[i, 1]
    scatter_mv(g, side, i, L0, jx[0], jy[0], fx[0], fy[0], mvx * wf0, mvy * wf0)
    scatter_mv(g, side, i, L0, jx[1], jy[1], fx[1], fy[1], mvx * wf1, mvy * wf1)
    scatter_mv(g, side, i, L0, jx[2], jy[2], fx[2], fy[2], mvx * wf2, mvy * wf2)
    scatter_mv(g, side, i, L0, jx[3], jy[3], fx[3], fy[3], mvx * wf3, mvy * wf3)


@helper_kernel
def gather(step, i, g, frame, st, shape, fields, side):
    """``v_p = Σ wf_α v(x_α)``, ``Δv_p`` alike and ``Δt L`` (not in MUSL's motion pass) at
    particle ``i``; the corners' velocities go on to :func:`follow`."""
    mode, dt = step[0], step[1]
    L0 = frame[4]
    (wf0, wf1, wf2, wf3), (g0x, g0y, g1x, g1y), V, jx, jy, fx, fy = st
    u0x, u0y, d0x, d0y = gather4(g, side, i, L0, jx[0], jy[0], fx[0], fy[0])
    u1x, u1y, d1x, d1y = gather4(g, side, i, L0, jx[1], jy[1], fx[1], fy[1])
    u2x, u2y, d2x, d2y = gather4(g, side, i, L0, jx[2], jy[2], fx[2], fy[2])
    u3x, u3y, d3x, d3y = gather4(g, side, i, L0, jx[3], jy[3], fx[3], fy[3])
    vx = wf0 * u0x + wf1 * u1x + wf2 * u2x + wf3 * u3x
    vy = wf0 * u0y + wf1 * u1y + wf2 * u2y + wf3 * u3y
    dvx = wf0 * d0x + wf1 * d1x + wf2 * d2x + wf3 * d3x
    dvy = wf0 * d0y + wf1 * d1y + wf2 * d2y + wf3 * d3y
    dtl = (0.0, 0.0, 0.0, 0.0)
    if mode != G2P_MUSL_MOTION:
        # L = Σ v(x_α) ⊗ wg_α, wg = (g0, g1, −g1, −g0)/V
        wax, way = u0x - u3x, u0y - u3y
        wbx, wby = u1x - u2x, u1y - u2y
        k = dt / V
        dtl = (k * (wax * g0x + wbx * g1x), k * (wax * g0y + wbx * g1y),
               k * (way * g0x + wby * g1x), k * (way * g0y + wby * g1y))
    return ((vx, vy), (dvx, dvy), NO_AFFINE, dtl,
            ((wf0, wf1, wf2, wf3), (u0x, u0y, u1x, u1y, u2x, u2y, u3x, u3y)))


@helper_kernel
def follow(i, dt, extra, fields):
    """Move particle ``i``'s tracked corners with the grid unless its domain is frozen (MUSL: in
    the deformation pass, with the re-mapped field; module doc)."""
    c, rf = fields.corners, fields.rf
    if rf[i, 0, 0] == 0.0 and rf[i, 1, 0] == 0.0:
        (wf0, wf1, wf2, wf3), (u0x, u0y, u1x, u1y, u2x, u2y, u3x, u3y) = extra
        ux = wf0 * u0x + wf1 * u1x + wf2 * u2x + wf3 * u3x
        uy = wf0 * u0y + wf1 * u1y + wf2 * u2y + wf3 * u3y
        c[i, 0, 0] += dt * (u0x - ux)
        c[i, 0, 1] += dt * (u0y - uy)
        c[i, 1, 0] += dt * (u1x - ux)
        c[i, 1, 1] += dt * (u1y - uy)
        c[i, 2, 0] += dt * (u2x - ux)
        c[i, 2, 1] += dt * (u2y - uy)
        c[i, 3, 0] += dt * (u3x - ux)
        c[i, 3, 1] += dt * (u3y - uy)


@loop_kernel
def p2g_cpdi2(lcr, boxes, order, fields, bforce, gsum, err):
    """Mass, momentum and force rows of ``gsum[slot]`` from every slot's particles."""
    gsum[:] = 0.0
    each_particle(support, scatter, boxes, order, gsum, err, lcr, fields,
                  (bforce, bforce.shape[0] > 0))


@loop_kernel
def p2g_momentum_cpdi2(lcr, boxes, order, fields, gsum, err):
    """The MUSL re-map: momentum rows (1, 2) of ``gsum`` only."""
    gsum[:, 1:3, :] = 0.0
    each_particle(support, scatter_momentum, boxes, order, gsum, err, lcr, fields, None)


@loop_kernel
def g2p_cpdi2(mode, lcr, boxes, order, dt, flip, fields, material, gnew, err, locate):
    """G2P in one of the three modes (USL; MUSL motion; MUSL deformation), moving the tracked
    corners in the modes that move the particle; returns the largest ``c_p + |v_p|`` in the
    modes that update the stress, the particles that changed patch and the first that left the
    grid."""
    return each_particle_g2p(support, gather, follow, (mode, dt, flip, False), boxes, order, gnew,
                             err, locate, lcr, fields, material)

