"""The explicit step as ordered phases (USL or MUSL); the kernels say *what*, this says *when*.

USL:  p2g → accumulate → grid update → fill → g2p (velocity, position, L, F, stress)
MUSL: p2g → accumulate → grid update → fill → g2p motion (velocity, position increment)
      → p2g momentum re-map → accumulate → grid velocity → fill → g2p deformation (L, F, stress)
then every particle is re-assigned to the patch that holds its new position (migration).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from decomposition import HaloPlan, PatchLayout, accumulate, fill
from parmpm.errors import SimulationError
from parmpm.grid import grid_update
from parmpm.particles import Particles, locate_patches
from parmpm.transfer import G2P_MUSL_DEFORM, G2P_MUSL_MOTION, G2P_USL, g2p, p2g, p2g_momentum


@dataclass
class Discretisation:
    """Everything the kernels need to know about the grid, method and patches (3-axis padded)."""

    dim: int
    method: int
    lcr: float            # 0.0 = no domain scaling
    origin: np.ndarray
    h: np.ndarray
    layout: PatchLayout

    def __post_init__(self):
        lay = self.layout
        pad = 3 - self.dim
        self.origin3 = np.concatenate([self.origin, np.zeros(pad)])
        self.h3 = np.concatenate([self.h, np.ones(pad)])
        self.inv_h3 = 1.0 / self.h3
        self.base = lay.local_base()
        self.nloc = lay.local_nodes3
        self.nglob = lay.global_nodes3
        coords = lay.patch_coords()
        owned = [lay.owned_box(c) for c in coords]
        self.own_lo = np.array([lo for lo, _ in owned]) - self.base
        self.own_hi = np.array([hi for _, hi in owned]) - self.base


class Stepper:
    """Owns the grid buffers (allocated once) and advances particles by one step."""

    def __init__(self, disc: Discretisation, particles: Particles, params: np.ndarray,
                 bc: np.ndarray, regions: np.ndarray, update: str, flip: float, damping: float):
        self.disc, self.P, self.params, self.bc, self.regions = disc, particles, params, bc, regions
        self.update, self.flip, self.damping = update, flip, damping
        self.plan = HaloPlan(disc.layout)
        npatch, nn, d = disc.layout.n_patches, disc.layout.n_local_nodes, disc.dim
        self.gm = np.zeros((npatch, nn, 1))
        self.gmv, self.gf, self.gvel, self.gdv = (np.zeros((npatch, nn, d)) for _ in range(4))
        self.err = np.full(1, -1, np.int64)
        self.mass_eps = 1e-12 * float(particles.mass.min(initial=1.0))
        self._patch = np.zeros(particles.n, np.int64)
        self.migrate()

    def _args(self):
        D = self.disc
        return (D.method, D.dim, D.lcr, self.P.start, D.base, D.nloc, D.nglob, D.origin3, D.inv_h3)

    def _check(self, phase: str) -> None:
        i = int(self.err[0])
        if i >= 0:
            self.err[0] = -1
            raise SimulationError(reach_message(self, i, phase))

    def _grid_update(self, dt: float, gravity: np.ndarray, momentum_only: bool) -> None:
        D = self.disc
        grid_update(D.dim, D.own_lo, D.own_hi, D.base, D.nloc, D.nglob, self.bc, self.regions,
                    D.origin3, D.h3, dt, gravity, self.damping, self.mass_eps, self.gm, self.gmv,
                    self.gf, self.gvel, self.gdv, momentum_only)

    def step(self, dt: float, gravity: np.ndarray) -> float:
        """Advance by ``dt``; returns the largest ``c + |v|`` for the next CFL step."""
        P, D, plan = self.P, self.disc, self.plan
        args = self._args()
        p2g(*args, P.x, P.v, P.F, P.r0, P.lh0, P.mass, P.vol0, P.stress,
            self.gm, self.gmv, self.gf, self.err)
        self._check("p2g")
        accumulate(plan, self.gm, self.gmv, self.gf)
        self._grid_update(dt, gravity, momentum_only=False)
        fill(plan, self.gvel, self.gdv)
        g2p_tail = (P.x, P.v, P.F, P.r0, P.lh0, P.stress, P.dx, P.mat, self.params, P.damage,
                    self.gvel, self.gdv, self.err)
        if self.update == "usl":
            vmax = g2p(G2P_USL, *args, dt, self.flip, *g2p_tail)
        else:
            g2p(G2P_MUSL_MOTION, *args, dt, self.flip, *g2p_tail)
            p2g_momentum(*args, P.x, P.v, P.F, P.r0, P.lh0, P.mass, self.gmv, self.err)
            self._check("p2g")
            accumulate(plan, self.gmv)
            self._grid_update(dt, gravity, momentum_only=True)
            fill(plan, self.gvel)
            vmax = g2p(G2P_MUSL_DEFORM, *args, dt, self.flip, *g2p_tail)
        self._check("g2p")
        self.migrate()
        return vmax

    def migrate(self) -> None:
        """Assign every particle to the patch that holds its position; regroup if any moved."""
        D, P = self.disc, self.P
        lay = D.layout
        if self._patch.size != P.n:
            self._patch = np.zeros(P.n, np.int64)
        bad = locate_patches(D.dim, P.x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                             lay.patches_per_axis, self._patch)
        if bad >= 0:
            raise SimulationError(
                f"particle {P.gid[bad]} at {fmt_vec(P.x[bad])} left the grid "
                f"(origin {fmt_vec(D.origin)}, extent {fmt_vec(D.origin + D.h * lay.cells)}); "
                "enlarge grid.cells or move grid.origin")
        if P.group_by_patch(self._patch, lay.n_patches):
            self._patch = np.zeros(P.n, np.int64)


def fmt_vec(v) -> str:
    return "(" + ", ".join(f"{float(c):.4g}" for c in np.atleast_1d(v)) + ")"


def reach_message(stepper: Stepper, i: int, phase: str) -> str:
    """The one-line explanation of a particle whose support leaves its patch's ghost layer."""
    from parmpm.shapes import CPDI, CPGIMP
    from parmpm.shapes.scaling import longest_corner
    from parmpm.shapes.support import domain_matrix

    D, P = stepper.disc, stepper.P
    g, dmin = D.layout.ghost, float(D.h.min())
    if D.method == CPDI:
        R = np.zeros((3, 3))
        domain_matrix(D.dim, D.method, D.lcr, P.F[i], P.r0[i], R)
        reach = longest_corner(D.dim, R)
    elif D.method == CPGIMP:
        reach = float(np.max(P.lh0[i] * np.abs(np.diag(P.F[i]))))
    else:
        reach = float(np.max(P.lh0[i]))
    x = P.x[i]
    inside = np.all(x - reach >= D.origin) and np.all(x + reach <= D.origin + D.h * D.layout.cells)
    where = "beyond the ghost layer of its patch" if inside else "outside the grid"
    hint = (f"use method.lcr <= {g}dx ({g * dmin:.4g} m) or a larger grid.ghost"
            if inside else "enlarge the grid")
    return (f"particle {P.gid[i]} at {fmt_vec(x)} reaches {where} in {phase} "
            f"(domain reach {reach:.4g} m = {reach / dmin:.3g} cells, ghost width {g} cells); {hint}")
