"""The explicit step as ordered phases (USL or MUSL); the kernels say *what*, this says *when*.

USL:  p2g → accumulate → grid update → fill → g2p (velocity, position, L, F, stress)
MUSL: p2g → accumulate → grid update → fill → g2p motion (velocity, position increment)
      → p2g momentum re-map → accumulate → grid velocity → fill → g2p deformation (L, F, stress)
then every particle goes to the patch (and rank) that holds its new position (migration), and
:meth:`Stepper.finish` agrees with all ranks on the next step: the largest wave speed, errors,
changes of the patch set, load balance.

Errors found inside a step (a support reaching past the ghost layer, a particle leaving the grid)
are remembered, not raised: the step runs to its end on every rank, so no rank is left waiting in
an exchange, and :meth:`Stepper.finish` raises the first rank's message on every rank at once.
"""
from __future__ import annotations

import math
import time

import numpy as np

from decomposition import PatchSet, accumulate, allreduce_max, exchange, fill, is_parallel, migrate
from parmpm.transfer.affine import AFFINE_TRANSFERS, inertia_diagonal
from parmpm.core.collective import agree
from parmpm.transfer.discretisation import Discretisation
from parmpm.core.errors import SimulationError
from parmpm.grid.update import grid_block, grid_update, region_node_ranges
from parmpm.core.records import Boxes, Constraints, Fields, Locate, Material, Method, OwnedNodes
from parmpm.transfer.kernels2d import KERNELS_2D, MLS_KERNELS_2D
from parmpm.transfer.kernels3d import KERNELS_3D, MLS_KERNELS_3D
from parmpm.materials import COL_DAMAGE
from parmpm.particles.store import Particles, locate_patches
from parmpm.transfer.reach import fmt_vec, grid_extent, inverted_message, reach_message
from parmpm.shapes import CAPPED
from parmpm.shapes.cpdi2 import INVERTED
from parmpm.shapes.freeze import freeze_domains
from parmpm.grid.symmetry import fold_sums, mirror_faces, row_signs
from parmpm.transfer.generic import g2p, p2g, p2g_momentum
from parmpm.transfer.update_order import G2P_MUSL_DEFORM, G2P_MUSL_MOTION, G2P_USL

#: dimension → {interpolator code → (p2g, p2g_momentum, g2p)} of the hand-specialised kernels
SPECIALISED = {2: KERNELS_2D, 3: KERNELS_3D}
#: dimension → the MLS transfers' (p2g, p2g_momentum, g2p) (bspline; its P2G takes the step)
SPECIALISED_MLS = {2: MLS_KERNELS_2D, 3: MLS_KERNELS_3D}

PHASES = ("p2g", "accumulate", "grid", "fill", "g2p", "migrate", "sort", "reduce")
#: the phases in which a rank only computes (the others exchange with, or wait for, other ranks)
WORK_PHASES = ("p2g", "grid", "g2p", "sort")


class Stepper:
    """Owns the grid buffers of this rank's patches and advances its particles by one step."""

    def __init__(self, disc: Discretisation, particles: Particles, patches: PatchSet,
                 params: np.ndarray, bc: np.ndarray, regions: np.ndarray, update: str,
                 flip: float, damping: float, n_total: int, region_normal: np.ndarray | None = None,
                 transfer: str = "flip"):
        self.disc, self.P, self.patches = disc, particles, patches
        self.params, self.bc, self.regions = params, bc, regions
        self.region_normal = (np.full(regions.shape[0], -1, np.int64) if region_normal is None
                              else np.asarray(region_normal, np.int64))
        self.update, self.flip, self.damping = update, flip, damping
        #: affine transfers (APIC or MLS, :mod:`parmpm.transfer.affine`) instead of FLIP/PIC
        self.apic = transfer in AFFINE_TRANSFERS
        #: MLS: the moving-least-squares gradient, Δt f folded into P2G's momentum
        self.mls = transfer == "mls"
        #: diag D_p of the affine transfers (zeros under FLIP): the affine angular momentum
        self.inertia = inertia_diagonal(disc.method, disc.h, self.apic)
        self.region_ranges = region_node_ranges(regions, disc.origin3, disc.h3, disc.dim)
        #: mirror (symmetry or clamped) faces (3, 2) when there are any (:mod:`parmpm.grid.symmetry`),
        #: else None
        sym = mirror_faces(bc)
        self.symmetry = sym if sym.any() else None
        self._signs = row_signs(disc.dim, bc)
        self.comm = patches.comm
        self.n_total = n_total
        self.err = np.full(2, -1, np.int64)  # (first particle in error, its support's code)
        mmin = float(particles.mass.min(initial=np.inf))
        mmin = float(allreduce_max(self.comm, np.array([-mmin]))[0])
        self.mass_eps = 1e-12 * (-mmin if math.isfinite(mmin) else 1.0)
        self.error: str | None = None
        self.error_key: tuple[int, int] | None = None  # (patch, id) of the particle it names
        self.stop_flag = False          # set by a signal handler
        self.stop_requested = False     # some rank got a signal (agreed at the end of a step)
        self.timers = dict.fromkeys(PHASES, 0.0)
        self.migrated = 0
        self._new_patch = np.zeros(0, np.int64)
        self._located = None                # (first particle off the grid, moved) from G2P
        self._moved = -1                    # particles that changed patch (-1: not counted)
        #: damage-triggered CPDI domain freeze (parmpm.shapes.freeze): CPDI or CPDI2 and a
        #: damage model
        self.freezing = bool(disc.method in CAPPED and np.any(params[:, COL_DAMAGE] != 0))
        self.frozen = 0
        lay = disc.layout
        self._loc, self._inv_psize = lay.locator()
        self.forcing = None                 # f(t, particles, out): per-particle body force
        self.ledger = None                  # an EnergyLedger fed after each force update
        self._bforce = np.zeros((0, particles.dim))
        #: hand-specialised (p2g, p2g_momentum, g2p) for this dimension and method, if any
        self.kernels = None
        self._empty_boxes = False
        self.use_kernels("specialised")
        self._patches_changed(force=True)

    def use_kernels(self, kind: str) -> None:
        """``"specialised"``: the hand-specialised 2D/3D kernels where this dimension and method
        have them (the default); ``"generic"``: the dimension-generic ones of
        :mod:`parmpm.transfer.generic` (the reference the specialised ones are tested against)."""
        if kind == "specialised":
            # APIC and MLS runs are bspline runs (the scene and inertia_diagonal refuse
            # others), whose kernels see the affine field; MLS has kernels of its own
            if self.mls:
                self.kernels = SPECIALISED_MLS.get(self.disc.dim)
            else:
                self.kernels = SPECIALISED.get(self.disc.dim, {}).get(self.disc.method)
        elif kind == "generic":
            self.kernels = None
        else:
            raise ValueError(f'kernels: expected "specialised" or "generic", got {kind!r}')

    def compile_lazy_order(self) -> None:
        """Compile (or load from numba's cache) the specialised transfers' variant for a lazy
        particle order (:meth:`parmpm.particles.store.Particles.lazy_order`: an index array instead of
        None; the generic loops always take an index, see :meth:`records`) now, with
        no patch slot to visit, rather than when particles first change patch. The benchmark's
        and ``parmpm compile``'s warm-up runs call it (a timed step must not compile); a run
        that needs the variant loads it from the cache then, and one that never does (no
        particle changes patch) loads nothing (with every stepper calling it, the test suite's
        fresh-clone run took 14 min 19 s instead of 10 min 10 s)."""
        self._empty_boxes = True
        try:
            self._p2g(self._bforce[:0], 0.0)
            self._p2g_momentum()
            self._g2p(G2P_USL, 0.0)
        finally:
            self._empty_boxes = False
            self._located = None
            self.err[:] = -1

    # --- patch set ------------------------------------------------------------------------------
    def _patches_changed(self, force: bool = False) -> None:
        """(Re)build the grid buffers and particle grouping for the current local patches."""
        ps, D, P = self.patches, self.disc, self.P
        D.set_patches(ps.local_ids)
        n, nn, d = ps.n_local, D.layout.n_local_nodes, D.dim
        self.plan = ps.plan
        # two blocks (see parmpm.grid.update.grid_block): P2G sums (m, mv, f) and grid-update results
        # (v, Δv); the specialised kernels (kernels2d/3d) take the blocks, all else the node-major views
        # views of two slots at least (spares never visited): numba types an array of 0 or 1 slot
        # as contiguous, and a rank with no or one patch compiled kernels of its own mid-run
        self.gsum_block, self.gsum = grid_block(max(n, 2), 1 + 2 * d, nn)
        self.gnew_block, self.gnew = grid_block(max(n, 2), 2 * d, nn)
        self.gsum_block, self.gnew_block = self.gsum_block[:n], self.gnew_block[:n]
        self.gm, self.gmv, self.gf = (self.gsum[:, :, :1], self.gsum[:, :, 1:1 + d],
                                      self.gsum[:, :, 1 + d:])
        self.gvel, self.gdv = self.gnew[:, :, :d], self.gnew[:, :, d:]
        # each slot's patch cells in grid coordinates, for G2P's stay-in-patch test (Locate)
        lo, hi = D.layout.patch_cells(D.layout.patch_coords()[ps.local_ids])
        self._inside = np.stack([lo, hi], axis=1).astype(np.float64)
        P.group_by_patch(P.rows.patch, ps.slot_of, n, force=True)  # no copy: see _reslot

    # --- the step -------------------------------------------------------------------------------
    def records(self):
        """The kernels' records (:mod:`parmpm.core.records`) of the current patches and
        particle arrays (rebuilt per call: migration replaces the arrays)."""
        D, P = self.disc, self.P
        R = P.rows  # physical rows, visited in P.order(): no copy of the fields per step
        # the specialised loops are compiled twice, for rows in canonical order (None: no index
        # load) and for a lazy order; the generic ones, slower anyway, once (an index always):
        # every compile of a generic loop is seconds, and a fresh clone's tests pay each
        order = P.lazy_order() if self.kernels is not None else P.order()
        boxes = Boxes(P.start, order, D.base, D.jlo, D.jhi, D.nloc, D.nglob, D.origin3,
                      D.inv_h3)
        if self._empty_boxes:  # no slot, an index order: see compile_lazy_order
            boxes = boxes._replace(start=np.zeros(1, np.int64), order=np.zeros(0, np.uint64))
        fields = Fields(R.x, R.v, R.F, R.r0, R.lh0, R.mass, R.vol0, R.stress, R.dx, R.affine,
                        R.corners, R.rf)
        return Method(D.method, D.dim, D.lcr, self.apic, self.mls), boxes, fields

    def _fail(self, i: int, message: str) -> None:
        """Note the first problem of this step (particle ``i``); :meth:`finish` raises it."""
        if self.error is None:
            self.error = message
            R = self.P.rows  # ``i`` is a physical row
            self.error_key = (int(R.patch[i]), int(R.gid[i]))

    def _check(self, phase: str) -> None:
        i, code = (int(c) for c in self.err)
        if i >= 0:
            self.err[:] = -1
            rows = self.P.rows
            self._fail(i, inverted_message(self.disc, rows, i, phase) if code == INVERTED
                       else reach_message(self.disc, rows, self.bc, i, phase))

    def grid_records(self) -> tuple[OwnedNodes, Constraints]:
        """The grid update's records: the owned nodes of every patch slot, the constraints."""
        D = self.disc
        nodes = OwnedNodes(D.own_lo, D.own_hi, D.base, D.nloc, D.face_lo3, D.face_hi3)
        constraints = Constraints(self.bc, self.regions, self.region_normal, self.region_ranges,
                                  D.origin3, D.h3)
        return nodes, constraints

    def _grid_update(self, dt: float, gravity: np.ndarray, momentum_only: bool) -> None:
        D = self.disc
        nodes, constraints = self.grid_records()
        grid_update(D.dim, nodes, constraints, dt, gravity, self.damping, self.mass_eps,
                    self.gsum_block, self.gnew_block, momentum_only, self.mls)

    def _sum_rows(self) -> int:
        """The P2G rows a step fills: mass, momentum and force, or under MLS without an energy
        ledger mass and momentum alone (Δt f is in the momentum, and nothing reads the force)."""
        d = self.disc.dim
        return 1 + d if self.mls and self.ledger is None else 1 + 2 * d

    def _fold(self, momentum_only: bool) -> None:
        """Mirror faces: fold the mirror images into this rank's partial sums (the rows P2G
        filled, or the momentum alone in a MUSL re-map) before the ghost accumulation
        (:mod:`parmpm.grid.symmetry`)."""
        if self.symmetry is None:
            return
        D = self.disc
        d = D.dim
        fold_sums(d, D.nloc, D.base, D.face_lo3, D.face_hi3, self.symmetry, self._signs,
                  1 if momentum_only else 0, 1 + d if momentum_only else self._sum_rows(),
                  self.gsum_block)

    def _lap(self, phase: str, t0: float) -> float:
        t = time.perf_counter()
        self.timers[phase] += t - t0
        return t

    def _p2g(self, bforce: np.ndarray, dt: float) -> None:
        """P2G of the step ``dt`` (MLS folds ``Δt f`` into the momentum; its specialised kernel
        writes the force rows only for the energy ledger)."""
        how, boxes, fields = self.records()
        if self.kernels is not None and self.mls:
            self.kernels[0](dt, self.ledger is not None, boxes, boxes.order, fields, bforce,
                            self.gsum_block, self.err)
        elif self.kernels is not None:
            self.kernels[0](how.lcr, boxes, boxes.order, fields, bforce, self.gsum_block, self.err)
        else:
            p2g(how, boxes, fields, bforce, dt, (self.gm, self.gmv, self.gf), self.err)
        self._check("p2g")

    def _p2g_momentum(self) -> None:
        how, boxes, fields = self.records()
        if self.kernels is not None:
            self.kernels[1](how.lcr, boxes, boxes.order, fields, self.gsum_block, self.err)
        else:
            p2g_momentum(how, boxes, fields, self.gmv, self.err)
        self._check("p2g")

    def _g2p(self, mode: int, dt: float) -> float:
        """G2P; the specialised kernels also find each particle's next patch once its position
        is final (``_located``: one pass over the particles fewer than :meth:`locate_and_send`)."""
        P = self.P
        how, boxes, fields = self.records()
        material = Material(P.rows.mat, self.params, P.rows.damage)
        if self.kernels is not None:
            if self._new_patch.size != P.n:
                self._new_patch = np.zeros(P.n, np.int64)
            locate = Locate(self._loc, self._inv_psize, self.patches.local_ids, self._new_patch,
                            self._inside)
            vmax, moved, first_out = self.kernels[2](mode, how.lcr, boxes, boxes.order, dt,
                                                     self.flip, fields, material,
                                                     self.gnew_block, self.err, locate)
            if mode != G2P_MUSL_MOTION:
                self._located = (first_out, moved)
            return vmax
        return g2p(mode, how, boxes, dt, self.flip, fields, material, (self.gvel, self.gdv),
                   self.err)

    def step(self, dt: float, gravity: np.ndarray, time_now: float = 0.0) -> float:
        """Advance this rank's particles from ``time_now`` by ``dt`` (collective: every rank
        calls it); returns the largest ``c + |v|`` over all ranks for the next CFL step."""
        P, plan = self.P, self.plan
        t = time.perf_counter()
        bforce = self._bforce[:0]
        if self.forcing is not None:
            if self._bforce.shape[0] != P.n:
                self._bforce = np.zeros((P.n, P.dim))
            bforce = self._bforce
            self.forcing(time_now, P.rows, bforce)  # per physical row, as P2G reads it
        self._p2g(bforce, dt)
        self._fold(momentum_only=False)
        t = self._lap("p2g", t)
        accumulate(plan, self.gsum[:, :, :self._sum_rows()])
        t = self._lap("accumulate", t)
        self._grid_update(dt, gravity, momentum_only=False)
        if self.ledger is not None:
            self.ledger.add(self, dt, gravity)
        t = self._lap("grid", t)
        fill(plan, self.gvel if self.apic else self.gnew)  # APIC and MLS read no Δv
        t = self._lap("fill", t)
        if self.update == "usl":
            vmax = self._g2p(G2P_USL, dt)
        else:
            self._g2p(G2P_MUSL_MOTION, dt)
            self._check("g2p")
            t = self._lap("g2p", t)
            self._p2g_momentum()
            self._fold(momentum_only=True)
            t = self._lap("p2g", t)
            accumulate(plan, self.gmv)
            t = self._lap("accumulate", t)
            self._grid_update(dt, gravity, momentum_only=True)
            t = self._lap("grid", t)
            fill(plan, self.gvel)
            t = self._lap("fill", t)
            vmax = self._g2p(G2P_MUSL_DEFORM, dt)
        self._check("g2p")
        if self.freezing:
            R = self.P.rows
            self.frozen = freeze_domains(self.P.dim, R.F, R.r0, R.rf, R.damage, R.mat,
                                         self.params)
        t = self._lap("g2p", t)
        moves = self.locate_and_send()
        t = self._lap("migrate", t)
        self.regroup(*moves)
        t = self._lap("sort", t)
        vmax = self.finish(vmax)
        self._lap("reduce", t)
        return vmax

    # --- migration --------------------------------------------------------------------------------
    def migrate(self) -> None:
        """Send every particle to the patch (on whichever rank) that holds its new position."""
        self.regroup(*self.locate_and_send())

    def locate_and_send(self):
        """Find every particle's new patch and exchange the particles that change rank; returns
        what :meth:`regroup` needs (None when no particle changed patch on a single rank)."""
        D, P, ps = self.disc, self.P, self.patches
        R = P.rows  # indices here are physical rows
        lay = D.layout
        if self._new_patch.size != P.n:
            self._new_patch = np.zeros(P.n, np.int64)
        new = self._new_patch
        if self._located is not None:  # G2P did it
            bad, moved = self._located
            self._located = None
        else:
            bad, moved = locate_patches(D.dim, R.x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                                        lay.patches_per_axis, R.patch, new, P.order())
        self._moved = int(moved)
        parallel = is_parallel(self.comm)
        if bad >= 0:  # before any early return: the same on any rank count
            self._fail(bad, f"particle {R.gid[bad]} at {fmt_vec(R.x[bad])} left the grid at "
                       f"{math.hypot(*R.v[bad]):.4g} m/s ({grid_extent(D)}); enlarge grid.cells "
                       "or move grid.origin, or check what drives it (gravity, velocities)")
        if moved == 0 and not parallel:  # nothing to regroup, nothing to send
            return None, None, None
        if moved == 0:  # every particle stays in its patch, so on this rank
            keep, received = (exchange(P.raw_fields(), None, self.comm, ps.peers) if parallel
                              else (None, None))
            return new, keep, received
        dest = ps.rank_of[new]
        lost = dest < 0
        if np.any(lost):  # moved past a neighbour patch in one step (CFL > 1): stay, and stop
            order = P.order()
            i = int(order[np.flatnonzero(lost[order])[0]])  # the first in (patch, id) order
            self._fail(i, f"particle {R.gid[i]} at {fmt_vec(R.x[i])} moved more than one patch "
                       "in one step; reduce time.cfl")
            new[lost] = R.patch[lost]
            dest[lost] = ps.rank
        keep, received = None, None
        if parallel:
            self.migrated += int(np.count_nonzero(dest != ps.rank))
            fields = P.raw_fields()
            fields["patch"] = new
            keep, received = exchange(fields, dest, self.comm, ps.peers)
        return new, keep, received

    def regroup(self, new, keep, received) -> None:
        """Sort the particles into (patch, id) order after :meth:`locate_and_send` (merging the
        kept and received rows after an exchange); notes whether a patch became (un)occupied."""
        P, ps = self.P, self.patches
        if new is None:
            self._occupancy_changed = False
            return
        occupied_before = np.diff(P.start) > 0
        if keep is not None or received is not None:  # some left or came
            P.group_by_patch(new, ps.slot_of, ps.n_local, keep=keep, received=received)
            self._new_patch = np.zeros(0, np.int64)  # P's patch rows may lie in it now
        else:
            old = P.rows.patch
            if P.group_by_patch(new, ps.slot_of, ps.n_local, moved=self._moved):
                self._new_patch = old  # the next step's buffer (P.patch is ``new`` now)
        self._occupancy_changed = bool(np.any((np.diff(P.start) > 0) != occupied_before))

    # --- agreement between ranks ----------------------------------------------------------------
    def finish(self, vmax: float) -> float:
        """End-of-step collective: one ``Allreduce(MAX)`` of (speed, error, patch-set change,
        particles per rank, stop signal); raises a run-stopping error on every rank at once."""
        ps, P = self.patches, self.P
        local = np.array([vmax if math.isfinite(vmax) else math.inf,
                          ps.rank + 1.0 if self.error else 0.0,
                          1.0 if self._occupancy_changed else 0.0, float(P.n),
                          1.0 if self.stop_flag else 0.0])
        g = allreduce_max(self.comm, local)
        self.stop_requested = bool(g[4] > 0)
        if g[1] > 0:  # the error of the first particle in (patch, id) order, as on one rank
            agree(self.comm, self.error, root=None, error=SimulationError, key=self.error_key)
        if g[2] > 0:
            if ps.update(ps.gather_counts(np.diff(P.start))):
                self._patches_changed()
        mean = self.n_total / ps.size
        if ps.size > 1 and g[3] > (1.0 + ps.threshold) * mean and ps.ready_to_rebalance():
            old = ps.rebalance(ps.gather_counts(np.diff(P.start)))
            if old is not None:
                self._rebalance_moves()
        return float(g[0])

    def _rebalance_moves(self) -> None:
        """Whole patches changed owner: send their particles to the new owners."""
        P, ps = self.P, self.patches
        dest = ps.rank_of[P.patch]
        self.migrated += int(np.sum(dest != ps.rank))
        P.replace(migrate(P.fields(), dest, self.comm, None))
        self._patches_changed()
