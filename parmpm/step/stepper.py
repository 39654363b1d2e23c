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

from decomposition import PatchSet, accumulate, allreduce_max, fill, max_and_patch_sum
from parmpm.core.collective import agree
from parmpm.core.errors import SimulationError
from parmpm.materials import COL_DAMAGE
from parmpm.materials.plasticity.update import plastic_pass
from parmpm.particles.store import Particles
from parmpm.shapes import CAPPED
from parmpm.shapes.freeze import freeze_domains
from parmpm.step.faults import StepFaults
from parmpm.step.field_transfers import g2p_fields, p2g_fields, p2g_momentum_fields
from parmpm.step.grid_buffers import GridBuffers
from parmpm.step.grid_phase import GridPhase
from parmpm.step.migration import Migration
from parmpm.step.speed_watch import SpeedWatch
from parmpm.step.transfers import Transfers
from parmpm.transfer.discretisation import Discretisation
from parmpm.transfer.update_order import G2P_MUSL_DEFORM, G2P_MUSL_MOTION, G2P_USL

PHASES = ("p2g", "accumulate", "grid", "fill", "g2p", "migrate", "sort", "reduce")
#: the phases in which a rank only computes (the others exchange with, or wait for, other ranks)
WORK_PHASES = ("p2g", "grid", "g2p", "sort")


class Stepper:
    """Advances this rank's particles by one step: the phases in order, each done by a part —
    ``transfers`` (:class:`~parmpm.step.transfers.Transfers`: which kernels, one call per kind),
    ``grid`` (:class:`~parmpm.step.grid_buffers.GridBuffers`, rebuilt with the patch set),
    ``grid_phase`` (:class:`~parmpm.step.grid_phase.GridPhase`: constraints, fold, nodal update),
    ``moves`` (:class:`~parmpm.step.migration.Migration`), ``faults``
    (:class:`~parmpm.step.faults.StepFaults`) — then agrees with every rank on the next step."""

    def __init__(self, disc: Discretisation, particles: Particles, patches: PatchSet,
                 params: np.ndarray, bc: np.ndarray, regions: np.ndarray, update: str,
                 flip: float, damping: float, n_total: int, region_normal: np.ndarray | None = None,
                 transfer: str = "flip"):
        self.disc, self.P, self.patches, self.params = disc, particles, patches, params
        self.update = update
        self.comm = patches.comm
        self.n_total = n_total
        self.transfers = Transfers(disc, particles, params, flip, transfer)
        self.grid_phase = GridPhase(disc, bc, regions, region_normal, damping,
                                    self.transfers.mls, self.comm, particles.mass)
        self.faults = StepFaults()
        self.moves = Migration(disc, particles, patches, self.faults)
        self.stop_flag = False          # set by a signal handler
        self.stop_requested = False     # some rank got a signal (agreed at the end of a step)
        self.timers = dict.fromkeys(PHASES, 0.0)
        #: damage-triggered CPDI domain freeze (parmpm.shapes.freeze): CPDI or CPDI2 and a
        #: damage model
        self.freezing = bool(disc.method in CAPPED and np.any(params[:, COL_DAMAGE] != 0))
        self.frozen = 0
        self.forcing = None                 # f(t, particles, out): per-particle body force
        self.ledger = None                  # an EnergyLedger fed after each force update
        self.walls = None                   # a WallPhase (parmpm.step.walls) when the scene has walls
        self.contact = None                 # a ContactPhase (parmpm.step.contact): [contact]
        #: the contact phase this step runs (:meth:`_fields_this_step`): ``contact``, or None
        self.fields_now = None
        self._kernels = "specialised"       # the kernels asked for (use_kernels)
        #: the plastic table (:mod:`parmpm.materials.plasticity.table`) of a scene with a plastic
        #: material, whose pass follows G2P's deformation update; None: no pass
        self.plastic: np.ndarray | None = None
        self.load_work = False              # the ledger counts the forcing's work (scene loads)
        #: None: G2P measures the CFL speed every step; with a fixed step (:meth:`fix_step`)
        #: a SpeedWatch
        self.speed_watch: SpeedWatch | None = None
        #: whether the last step's result is the CFL speed (else only 0, or ``inf`` on a blow-up)
        self.speed_measured = True
        self._v_start = np.zeros((0, particles.dim))
        self._bforce = np.zeros((0, particles.dim))
        self.grid: GridBuffers | None = None
        self.patches_changed()

    # what other layers read of the parts
    @property
    def apic(self) -> bool:
        return self.transfers.apic

    @property
    def mls(self) -> bool:
        return self.transfers.mls

    @property
    def inertia(self) -> np.ndarray:
        return self.transfers.inertia

    def use_kernels(self, kind: str) -> None:
        """``"specialised"`` (the default) or ``"generic"`` transfer kernels (:meth:`Transfers.use
        <parmpm.step.transfers.Transfers.use>`)."""
        self.transfers.use(kind)
        self._kernels = kind

    def fix_step(self) -> None:
        """A fixed step (``time.dt``): G2P's kernels without the CFL speed, which a pass of its
        own measures every few steps (:mod:`parmpm.step.speed_watch`)."""
        self.transfers.cfl = False
        self.speed_watch = SpeedWatch()

    def compile_lazy_order(self) -> None:
        """Compile (or load from numba's cache) the specialised transfers' variant for a lazy
        particle order (:meth:`parmpm.particles.store.Particles.lazy_order`: an index array
        instead of None; the generic loops always take an index) now, with no patch slot to
        visit, rather than when particles first change patch. The benchmark's and ``parmpm
        compile``'s warm-up runs call it (a timed step must not compile); a run that needs the
        variant loads it from the cache then, and one that never does (no particle changes patch)
        loads nothing (with every stepper calling it, the test suite's fresh-clone run took
        14 min 19 s instead of 10 min 10 s)."""
        self.transfers.empty_boxes = True
        try:
            self.p2g(self._bforce[:0], 0.0)
            self.p2g_momentum()
            self.g2p(G2P_USL, 0.0)
        finally:
            self.transfers.empty_boxes = False
            self.moves.located = None
            self.faults.err[:] = -1

    def patches_changed(self) -> None:
        """(Re)build the grid buffers and particle grouping for the current local patches."""
        ps, P = self.patches, self.P
        self.disc.set_patches(ps.local_ids)
        self.plan = ps.plan
        self.grid = GridBuffers(self.disc, ps.local_ids)
        if self.contact is not None:
            self.contact.rebuild(self.disc, self.grid)
        P.group_by_patch(P.rows.patch, ps.slot_of, ps.n_local, force=True)

    def use_contact(self, contact) -> None:
        """Separate velocity fields from now on (a :class:`~parmpm.step.contact.ContactPhase`)."""
        self.contact = contact
        contact.rebuild(self.disc, self.grid)
        self._fields_this_step()

    def _fields_this_step(self) -> None:
        """Which fields this step runs, into :attr:`fields_now`: the contact phase's, or none —
        one field on the specialised kernels — where :meth:`ContactPhase.whole
        <parmpm.step.contact.ContactPhase.whole>` says a crack scene has no crack yet. A crack's
        sides are per node: the generic loops."""
        C = self.contact
        if C is not None and C.whole(self.P.rows.damage, self.comm):
            C = None
        self.fields_now = C
        self.transfers.use("generic" if C is not None and C.crack is not None
                           else self._kernels)

    @property
    def field_grids(self) -> list:
        """The grids the transfers fill: the one grid, or every contact field's."""
        return [self.grid] if self.fields_now is None else self.fields_now.grids

    # --- the phases -----------------------------------------------------------------------------
    def _check(self, phase: str) -> None:
        self.faults.check(phase, self.disc, self.P.rows, self.grid_phase.bc)

    def _sum_rows(self) -> int:
        """The P2G rows a step fills: mass, momentum and force, or under MLS without an energy
        ledger mass and momentum alone (Δt f is in the momentum, and nothing reads the force)."""
        d = self.disc.dim
        return 1 + d if self.mls and self.ledger is None else 1 + 2 * d

    def _lap(self, phase: str, t0: float) -> float:
        t = time.perf_counter()
        self.timers[phase] += t - t0
        return t

    def p2g(self, bforce: np.ndarray, dt: float) -> None:
        """P2G of the step ``dt`` into the grid sums (with contact: every field's,
        :func:`~parmpm.step.field_transfers.p2g_fields`)."""
        C, T, err = self.fields_now, self.transfers, self.faults.err
        if C is None:
            T.p2g(self.grid, bforce, dt, err, self.ledger is not None)
        else:
            p2g_fields(C, T, self.P, self.plan, self.grid_phase, self._kernels, bforce, dt, err,
                       self.ledger is not None)
        self._check("p2g")

    def p2g_momentum(self) -> None:
        """MUSL's momentum re-map into the grid sums (every field's)."""
        C, T = self.fields_now, self.transfers
        if C is None:
            T.p2g_momentum(self.grid, self.faults.err)
        else:
            p2g_momentum_fields(C, T, self._kernels, self.disc.dim, self.faults.err)
        self._check("p2g")

    def g2p(self, mode: int, dt: float) -> float:
        """G2P in ``mode``; keeps the next patches the specialised kernels found (the final
        positions only: not after MUSL's motion pass, which the deformation pass follows)."""
        locate = self.moves.locate_record(self.grid.inside)
        C, T = self.fields_now, self.transfers
        if C is not None:
            return g2p_fields(C, T, self.moves, self._kernels, mode, dt, self.faults.err, locate,
                              mode != G2P_MUSL_MOTION)
        vmax, located = T.g2p(self.grid, mode, dt, self.faults.err, locate)
        if located is not None and mode != G2P_MUSL_MOTION:
            self.moves.located = located
        return vmax

    def _body_force(self, time_now: float) -> np.ndarray:
        """Per physical row, as P2G reads it: the forcing's body force, or no rows."""
        P = self.P
        if self.forcing is None:
            return self._bforce[:0]
        if self._bforce.shape[0] != P.n:
            self._bforce = np.zeros((P.n, P.dim))
        self.forcing(time_now, P.rows, self._bforce)
        return self._bforce

    def _grid(self, dt: float, gravity: np.ndarray, t: float, momentum_only: bool,
              t_end: float = 0.0) -> float:
        """Fold, accumulate over the ghost layers, update the nodes (then the walls, as they are
        at the step's end ``t_end``) and fill the ghosts: the grid between P2G and G2P; returns
        the lap clock."""
        plan, phase, C = self.plan, self.grid_phase, self.fields_now
        grids = self.field_grids
        rows = self._sum_rows()
        if C is not None and not momentum_only:  # the images' moments, from the unfolded mass
            for moments, grid in zip(C.moments, grids):
                phase.fold_moments(moments, grid)
        for grid in grids:
            phase.fold(grid, rows, momentum_only)
        t = self._lap("p2g", t)
        sums = [g.gmv if momentum_only else g.gsum[:, :, :rows] for g in grids]
        plans = C.field_plans(plan) if C is not None else [plan]
        if C is not None and not momentum_only and not C.late_moments:  # each with its field's
            sums = [(s, x) for s, x in zip(sums, C.node_views("x"))]
            if C.crack is not None and len(plans) == 2:  # the moments: where the sides meet
                sums = [sums[0][:1], (sums[0][1], *sums[1])]
        else:
            sums = [(s,) for s in sums]
        if len(plans) == 1:
            accumulate(plan, *(a for field in sums for a in field))
        else:  # each field over the pairs whose ghost copies its particles fill
            for field_plan, field in zip(plans, sums):
                accumulate(field_plan, *field)
        t = self._lap("accumulate", t)
        nodes = phase.records()[0]
        heavy = -1.0 if self.mls else phase.mass_eps
        if C is not None and not momentum_only:  # MUSL's re-map keeps the step's contacts
            if C.late_moments:
                C.moments_where_fields_meet(self.transfers, nodes, plan, phase.mass_eps,
                                            self.faults.err)
            C.detect(self.disc, self.P, nodes, plan, phase.mass_eps)
        owned = C.field_nodes(plans, nodes) if C is not None else [nodes]
        for k, grid in enumerate(grids):
            phase.update(grid, dt, gravity, momentum_only, owned[k])
            if self.walls is not None:
                self.walls.apply(self.disc, owned[k], grid, dt, gravity, heavy, t_end,
                                 momentum_only, add=k > 0)
        if C is not None:
            C.correct(self.disc, nodes, dt, gravity, heavy, phase.mass_eps, momentum_only)
            for grid in grids:
                phase.reflect_beyond(grid)
        elif self.contact is not None and not momentum_only:  # a whole crack scene's step
            self.contact.untouched(nodes.own_lo.shape[0])
        if self.ledger is not None and not momentum_only:
            self.ledger.add(self, dt, gravity)
        t = self._lap("grid", t)
        # APIC and MLS read no Δv, nor does MUSL's deformation pass
        views = [g.gvel if (self.apic or momentum_only) else g.gnew for g in grids]
        if len(plans) == 1:
            fill(plan, *views)
        else:  # each field's ghost copies where its particles read them
            for field_plan, view in zip(plans, views):
                fill(field_plan, view)
        return self._lap("fill", t)

    def step(self, dt: float, gravity: np.ndarray, time_now: float = 0.0) -> float:
        """Advance this rank's particles from ``time_now`` by ``dt`` (collective: every rank
        calls it); returns the largest ``c + |v|`` over all ranks for the next CFL step."""
        t = time.perf_counter()
        if self.contact is not None:
            self._fields_this_step()
        if self.walls is not None:
            self.walls.mark(self.disc, self.P, self.grid, self.plan, time_now)
        # scene loads at the step's midpoint (exact for a ramp), the manufactured forcing at its start
        bforce = self._body_force(time_now + 0.5 * dt if self.load_work else time_now)
        counted = self.load_work and self.ledger is not None
        if counted:
            if self._v_start.shape != self.P.rows.v.shape:
                self._v_start = np.zeros_like(self.P.rows.v)
            np.copyto(self._v_start, self.P.rows.v)
        self.p2g(bforce, dt)
        t = self._grid(dt, gravity, t, False, time_now + dt)
        if self.update == "usl":
            vmax = self.g2p(G2P_USL, dt)
        else:
            self.g2p(G2P_MUSL_MOTION, dt)
            self._check("g2p")
            t = self._lap("g2p", t)
            self.p2g_momentum()
            t = self._grid(dt, gravity, t, True, time_now + dt)
            vmax = self.g2p(G2P_MUSL_DEFORM, dt)
        self._check("g2p")
        if self.plastic is not None:  # G2P gave the plastic particles no stress and no speed
            R = self.P.rows
            vmax = max(vmax, plastic_pass(self.P.dim, R.F, R.mat, self.plastic, R.plastic,
                                          R.stress, R.v, dt))
        if self.speed_watch is not None:
            vmax, self.speed_measured = self.speed_watch.after_g2p(vmax, self.P.rows, self.params)
        if counted:
            self.ledger.add_loads(self, dt, bforce, self._v_start)
        if self.freezing:
            R = self.P.rows
            self.frozen = freeze_domains(self.P.dim, R.F, R.r0, R.rf, R.damage, R.mat,
                                         self.params)
        t = self._lap("g2p", t)
        moves = self.moves.locate_and_send()
        t = self._lap("migrate", t)
        self.moves.regroup(*moves)
        t = self._lap("sort", t)
        vmax = self.finish(vmax)
        self._lap("reduce", t)
        return vmax

    def migrate(self) -> None:
        """Send every particle to the patch (on whichever rank) that holds its new position."""
        self.moves.regroup(*self.moves.locate_and_send())

    # --- agreement between ranks ----------------------------------------------------------------
    def finish(self, vmax: float) -> float:
        """End-of-step collective: the maximum over the ranks of (speed, error, patch-set change,
        particles per rank, stop signal, largest damage) and, when a history is written, the
        energy ledger's per-patch sums, in one exchange (:func:`decomposition.max_and_patch_sum`);
        raises a run-stopping error on every rank at once."""
        ps, P, faults = self.patches, self.P, self.faults
        cracks = self.contact is not None and self.contact.crack is not None
        local = np.array([vmax if math.isfinite(vmax) else math.inf,
                          ps.rank + 1.0 if faults.error else 0.0,
                          1.0 if self.moves.occupancy_changed else 0.0, float(P.n),
                          1.0 if self.stop_flag else 0.0,
                          float(P.rows.damage.max(initial=0.0)) if cracks else 0.0])
        partials = self.ledger.partials() if self.ledger is not None else None
        if partials is None:
            g = allreduce_max(self.comm, local)
        else:
            g, sums = max_and_patch_sum(self.comm, local, partials, ps.owner)
            self.ledger.settle(sums)
        self.stop_requested = bool(g[4] > 0)
        if cracks:  # no crack anywhere: the next step's sides need no passes (ContactPhase)
            self.contact.max_damage = float(g[5])
        if g[1] > 0:  # the error of the first particle in (patch, id) order, as on one rank
            agree(self.comm, faults.error, root=None, error=SimulationError, key=faults.error_key)
        if g[2] > 0:
            if ps.update(ps.gather_counts(np.diff(P.start))):
                self.patches_changed()
        mean = self.n_total / ps.size
        if ps.size > 1 and g[3] > (1.0 + ps.threshold) * mean and ps.ready_to_rebalance():
            old = ps.rebalance(ps.gather_counts(np.diff(P.start)))
            if old is not None:
                self.moves.rebalance()
                self.patches_changed()
        return float(g[0])
