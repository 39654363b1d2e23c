"""The energy in the body, and a watch that stops a run which blows up.

An explicit MPM step beyond its stability limit (CFL too large for the update order, a stiff
material on a coarse step) does not always end in NaN: the vibrating bar under USL at CFL 0.99
gains fifteen times its energy and runs on. The cheap invariant that catches it is the energy
balance of an elastic body under gravity,

    K + Ψ = K₀ + Ψ₀ + W_g,      W_g = Σ_p m_p g · (x_p − X_p),

with ``K = Σ ½ m |v|²`` and ``Ψ = Σ V₀ (1 − D) ψ(F)`` (:func:`parmpm.materials.stored_energy`).
Damping, fixed supports and the dissipation of MPM's grid projections only take energy out, so
the residual ``R = K + Ψ − (K₀ + Ψ₀ + W_g)`` of a sound run stays at or below zero. A ramped
gravity makes ``W_g`` (evaluated with today's g) an overestimate of the work done, which only
lowers ``R``. The watch stops the run when ``R`` exceeds ``limit`` times the largest energy the
body has held or been given, ``S = max(K₀ + Ψ₀ + W_g)`` over the samples so far. Runs driven by a
body force that does work (the manufactured solution) are not watched.

Totals are per-patch partial sums added in patch order (:func:`decomposition.ordered_sum`), so
the decision is the same on any number of ranks.

:class:`EnergyLedger` keeps the full account a history needs (:mod:`parmpm.output.history`): the work
of gravity, of the boundary constraints and of damping, summed on the grid every step, exactly as
the grid update applies them; the step's per-patch sums ride on the step's one closing
collective (:meth:`parmpm.step.stepper.Stepper.finish`). ``docs/energy.md`` derives the balance and what its residual
measures.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from decomposition import ordered_sum
from parmpm.grid.update import apply_bc, apply_regions, beyond_mirror, is_mirror, near_region
from parmpm.core.jit import helper_kernel, kernel
from parmpm.materials.laws import stored_energy
from parmpm.materials.plasticity.update import plastic_energy_sums

#: steps between two samples of the watch: a blow-up grows geometrically, so a sample every few
#: steps catches it early, at a cost of one particle pass per ENERGY_EVERY steps
ENERGY_EVERY = 10


@helper_kernel
def particle_energy(d, i, mass, vol0, v, x, x0, F, mat, damage, params, g):
    """Particle ``i``'s ``(½ m|v|², V₀ ψ(F) (1 − D), m g·(x − X))``: the addends of the watch
    (:func:`energy_sums`) and of the history's first columns
    (:func:`parmpm.output.history.history_sums`), one definition for both."""
    ke = 0.0
    w = 0.0
    for a in range(d):
        ke += v[i, a] * v[i, a]
        w += g[a] * (x[i, a] - x0[i, a])
    return (0.5 * mass[i] * ke, vol0[i] * stored_energy(d, params[mat[i]], F[i], damage[i]),
            mass[i] * w)


@kernel
def energy_sums(d, start, order, mass, vol0, v, x, x0, F, mat, damage, params, g):
    """Per patch slot, over its particles ``order[start[p]:start[p + 1]]`` in that order:
    (kinetic energy, stored elastic energy, work of gravity ``m g·(x − X)``). Summed as it goes
    (no per-particle array, one pass): the same sums, in the same order, as per-particle terms
    added up by :func:`parmpm.output.metrics.sums.patch_sums`, in 0.7× their time (measured)."""
    out = np.zeros((start.size - 1, 3))
    for p in range(start.size - 1):
        o = out[p]
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):
            kinetic, stored, work = particle_energy(d, order[kk], mass, vol0, v, x, x0, F, mat,
                                                    damage, params, g)
            o[0] += kinetic
            o[1] += stored
            o[2] += work
    return out


def energy_totals(comm, patch_ids, P, params, g, plastic=None) -> np.ndarray:
    """(K, Ψ, W_g) over all ranks (collective), the same on any number of ranks. With a plastic
    table (:mod:`parmpm.materials.plasticity.table`) Ψ holds the plastic particles' stored energy
    and the plastic work done on them: energy the body was given and keeps or has dissipated,
    so the balance still reads ``K + Ψ ≤ K₀ + Ψ₀ + W_g``."""
    R = P.rows  # as they lie (no copy into canonical order): summed in P.order()
    sums = energy_sums(P.dim, P.start, P.order(), R.mass, R.vol0, R.v, R.x, R.x0, R.F, R.mat,
                       R.damage, params, np.ascontiguousarray(g[:P.dim], dtype=np.float64))
    if plastic is not None:
        extra = plastic_energy_sums(P.dim, P.start, P.order(), R.vol0, R.F, R.mat, plastic,
                                    R.plastic)
        sums[:, 1] += extra[:, 0] + extra[:, 1]
    return ordered_sum(comm, patch_ids, sums)


@kernel
def load_work(d, start, order, mass, bforce, v_start, v, dt):
    """Per patch slot: ``Δt Σ m_p b_p · (v_p + v_p')/2``, the work of the external loads' forces
    ``m_p b_p`` (:mod:`parmpm.loads.external`) over the step, at the particles' mean velocity."""
    out = np.zeros((start.size - 1, 1))
    for p in range(start.size - 1):
        acc = 0.0
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):
            i = order[kk]
            for a in range(d):
                acc += mass[i] * bforce[i, a] * 0.5 * (v_start[i, a] + v[i, a])
        out[p, 0] = dt * acc
    return out


@kernel
def grid_work(d, nodes, constraints, dt, gvec, damping, mass_eps, gsum, gnew, fused, keep):
    """Per patch slot: (work of internal and body forces, work of gravity, damping dissipation,
    work of the boundary constraints, the increment work, and the impulse (3) the held faces and
    regions gave the nodes: ``−m v⁺`` on each held component) of one grid update, over the
    slot's owned nodes.

    :func:`parmpm.grid.update.grid_update` forms ``v = (mv)/m`` and the free update
    ``v⁺ = [v + Δt(f/m + g)]/(1 + cΔt)``, then zeroes the constrained components of both. This
    kernel finds those components with the same helpers and recomputes ``v`` and ``v⁺`` with the
    same expressions (the same rounding). On a free component ``v_new − v = Δt(f/m + g) − cΔt v⁺``,
    so with ``v̄ = (v + v_new)/2`` the grid's kinetic energy changes by exactly
    ``Σ ½m(|v_new|² − |v|²) = W_f + W_g − D_c + W_bc``: ``W_f = Δt Σ f·v̄``,
    ``W_g = Δt Σ m g·v̄``, ``D_c = cΔt Σ m v⁺·v̄`` over free components, and
    ``W_bc = −Σ ½m v²`` over constrained ones (the momentum a support takes out; a held node
    does not move, so the forces on it do no work). Under MLS (``fused``: the momentum rows hold
    ``mv + Δt f``, the force rows ``f`` for this account alone) ``v = (mv + Δt f − Δt f)/m``,
    equal to the grid's up to round-off, and every node with mass takes its force.

    The support's impulse is what the particles lose to it, which depends on the transfer: a
    velocity transfer (PIC, APIC, MLS) hands them the held ``v⁺ = 0``, so they lose ``m v⁺`` of
    the free update; FLIP hands them the increment ``0 − 0`` of a held node (the update zeroes
    ``v`` too), so they keep the momentum ``m v`` they brought and lose only ``m (v⁺ − v)``, the
    force the support balances. ``keep`` is the FLIP fraction of the particle update (0 for the
    velocity transfers): the impulse is ``−m (v⁺ − keep·v)`` (an impact onto a held face under
    FLIP read 1.66 times the stress behind its wave with ``keep = 0``)."""
    own_lo, own_hi, base, nloc, face_lo, face_hi = nodes
    bc, regions, normal, ranges, origin, h = constraints
    out = np.zeros((gsum.shape[0], 8))
    L0, L1 = nloc[0], nloc[1]
    free = np.ones(3)
    # the faces that hold a node of their own: a mirror's face node is held too, but a mirror's
    # reaction comes from the momentum balance (parmpm.output.reactions.mirror_row), not here
    bc_held = bc.copy()
    for k in range(3):
        for side in range(2):
            if is_mirror(bc[k, side]):
                bc_held[k, side] = 0  # free
    held = np.ones(3)
    gidx = np.zeros(3, np.int64)
    nreg = ranges.shape[0]
    for p in range(gsum.shape[0]):
        G = gsum[p]
        wf = wg = dc = wbc = wx = 0.0
        for i2 in range(own_lo[p, 2], own_hi[p, 2]):
            for i1 in range(own_lo[p, 1], own_hi[p, 1]):
                row0 = L0 * (i1 + L1 * i2)
                for i0 in range(own_lo[p, 0], own_hi[p, 0]):
                    node = row0 + i0
                    m = G[0, node]
                    if not m > 0.0:
                        continue
                    gidx[0], gidx[1], gidx[2] = (base[p, 0] + i0, base[p, 1] + i1,
                                                 base[p, 2] + i2)
                    for a in range(3):
                        free[a] = 1.0
                    edge = False
                    for k in range(d):
                        if gidx[k] <= face_lo[k] or gidx[k] >= face_hi[k]:
                            edge = True
                    for a in range(3):
                        held[a] = 1.0
                    if edge:
                        if beyond_mirror(d, gidx, face_lo, face_hi, bc):
                            continue  # the mirror image's node (parmpm.grid.symmetry)
                        apply_bc(d, gidx, face_lo, face_hi, bc, free)
                        apply_bc(d, gidx, face_lo, face_hi, bc_held, held)
                    if nreg and near_region(gidx[0], gidx[1], gidx[2], ranges):
                        apply_regions(d, gidx, origin, h, regions, normal, free)
                        apply_regions(d, gidx, origin, h, regions, normal, held)
                    heavy = fused or m > mass_eps
                    for a in range(d):
                        vold = ((G[1 + a, node] - dt * G[1 + d + a, node]) / m if fused
                                else G[1 + a, node] / m)
                        fm = G[1 + d + a, node] / m if heavy else 0.0
                        vnew = (vold + dt * (fm + gvec[a])) / (1.0 + damping * dt)
                        if free[a] == 0.0:
                            wbc -= 0.5 * m * vold * vold
                            if held[a] == 0.0:  # a support's impulse (not a mirror's)
                                out[p, 5 + a] -= m * (vnew - keep * vold)
                            continue
                        vbar = 0.5 * (vold + vnew)
                        if heavy:
                            wf += dt * G[1 + d + a, node] * vbar
                            wx += dt * G[1 + d + a, node] * (vnew - vbar)
                        wg += dt * m * gvec[a] * vbar
                        dc += damping * dt * m * vnew * vbar
        out[p, 0], out[p, 1], out[p, 2], out[p, 3], out[p, 4] = wf, wg, dc, wbc, wx
    return out


@dataclass
class _StepRows:
    """One step's per-patch rows on this rank, until the step's closing collective sums them:
    the grid's work with the walls' and contact's columns, the loads' (None: no load worked),
    the step, and how many walls and contact fields the columns hold."""

    grid: np.ndarray
    loads: np.ndarray | None
    dt: float
    walls: int
    contact: int


class EnergyLedger:
    """The energy given to and taken from the body since the ledger started, summed every step
    on the grid (:func:`grid_work`): ``forces`` (internal and body forces), ``gravity``,
    ``damping`` (dissipated, ≥ 0) and ``boundary`` (the constraints' work, ≤ 0). Each step's
    per-patch sums are added in patch order (:func:`decomposition.max_and_patch_sum`), so every total
    is the same on any number of ranks. The stepper calls :meth:`add` after its force update
    when a history is written."""

    FIELDS = ("forces", "gravity", "damping", "boundary", "increment", "walls", "loads",
              "contact")

    def __init__(self):
        self.totals = np.zeros(len(self.FIELDS))
        #: per wall: the impulse it gave the bodies since the start (3), its work; and the last
        #: step's impulse (3) and length
        self.walls = np.zeros((0, 4))
        self.wall_step = np.zeros((0, 4))
        self.last_dt = 0.0
        #: the impulse the held faces and regions gave the bodies (3): since the start, last step
        self.support = np.zeros(3)
        self.support_step = np.zeros(3)
        #: per contact field: the contact impulse on it since the start (3), its work; and the
        #: last step's
        self.contact = np.zeros((0, 4))
        self.contact_step = np.zeros((0, 4))
        self.baseline = None   # (K₀, Ψ₀, step) where the ledger started
        #: ∫ g dt since the start (3): the gravity impulse per unit mass
        self.g_time = np.zeros(3)
        #: the bodies' momentum where the ledger started, and the mirror faces' impulse at the
        #: last history row with its time (:mod:`parmpm.output.reactions`)
        self.momentum0 = None
        self.mirror_last = None
        self.steps = 0
        self.power = None      # the last step's internal power −W_f/Δt
        self.estimate = 0.0    # ½ Σ Δt_k (P_k − P_{k−1}): the residual's leading term
        self._pending: _StepRows | None = None  # this step's rows until the step's end sums them

    def add(self, stepper, dt: float, gravity: np.ndarray) -> None:
        """This rank's per-patch work of one grid update (local: the step's end sums it over all
        ranks with the step's other agreements, :meth:`partials`, and books it, :meth:`settle`)."""
        phase = stepper.grid_phase
        nodes, constraints = phase.records()
        self.g_time = self.g_time + np.asarray(gravity[:3], float) * dt
        keep = 0.0 if stepper.apic else stepper.transfers.flip  # see grid_work
        per_patch = None
        for grid in stepper.field_grids:  # one grid, or a contact field's each
            work = grid_work(stepper.disc.dim, nodes, constraints, dt, gravity, phase.damping,
                             phase.mass_eps, grid.gsum_block, grid.gnew_block, stepper.mls, keep)
            per_patch = work if per_patch is None else per_patch + work
        blocks = [per_patch]
        walls, contact = stepper.walls, stepper.contact
        n_walls = 0 if walls is None else len(walls.names)
        n_contact = 0 if contact is None else contact.K
        if walls is not None:
            blocks.append(walls.sums.reshape(walls.sums.shape[0], 6 * n_walls))
        if contact is not None:
            blocks.append(contact.sums.reshape(contact.sums.shape[0], 6 * n_contact))
        self._pending = _StepRows(np.concatenate(blocks, axis=1), None, dt, n_walls, n_contact)

    def add_loads(self, stepper, dt: float, bforce: np.ndarray, v_start: np.ndarray) -> None:
        """This rank's per-patch work of the external loads over one step, from the step's start
        velocities ``v_start`` and the particles' velocities now (rows as they lie); local, summed
        and booked with the grid's work (:meth:`add`)."""
        P = stepper.P
        self._pending.loads = load_work(P.dim, P.start, P.order(), P.rows.mass, bforce, v_start,
                                     P.rows.v, dt)

    def partials(self) -> np.ndarray | None:
        """The step's per-patch rows to sum over all ranks (patch order), or None when
        :meth:`add` was not called this step."""
        if self._pending is None:
            return None
        rows = self._pending
        return rows.grid if rows.loads is None else np.concatenate([rows.grid, rows.loads], axis=1)

    def settle(self, sums: np.ndarray) -> None:
        """Book the step's totals: ``sums`` of :meth:`partials` over every patch, added in patch
        order (:func:`decomposition.max_and_patch_sum`), so every total is the same on any number
        of ranks. Columns: the grid's 8 (:func:`grid_work`), 6 per wall, 6 per contact field,
        then the loads' 1 when they work."""
        rows, self._pending = self._pending, None
        loads, dt, n, n_contact = rows.loads, rows.dt, rows.walls, rows.contact
        step, self.support_step = sums[:5], sums[5:8]
        self.support = self.support + self.support_step
        at = 8
        if n:
            both = sums[at:at + 6 * n].reshape(n, 6)
            at += 6 * n
            self.wall_step = both[:, :4]
            if self.walls.shape[0] != n:
                self.walls = np.zeros((n, 4))
            self.walls += self.wall_step
            step = step.copy()
            step[0] += both[:, 4].sum()  # the forces' and gravity's work at the walls' nodes
            step[1] += both[:, 5].sum()
            step = np.concatenate([step, [self.wall_step[:, 3].sum(), 0.0]])
        else:
            step = np.concatenate([step, [0.0, 0.0]])
        if n_contact:
            both = sums[at:at + 6 * n_contact].reshape(n_contact, 6)
            at += 6 * n_contact
            self.contact_step = both[:, :4]
            if self.contact.shape[0] != n_contact:
                self.contact = np.zeros((n_contact, 4))
            self.contact += self.contact_step
            step = step.copy()
            step[0] += both[:, 4].sum()  # the forces' and gravity's work at the contact nodes
            step[1] += both[:, 5].sum()
            step = np.concatenate([step, [self.contact_step[:, 3].sum()]])
        else:
            step = np.concatenate([step, [0.0]])
        self.last_dt = dt
        self.totals += step
        power = -float(step[0]) / dt  # power stored by the internal forces in this step
        if self.power is not None:
            self.estimate += 0.5 * dt * (power - self.power)
        self.power = power
        self.steps += 1
        if loads is not None:
            self.totals[self.FIELDS.index("loads")] += float(sums[at])

    def work(self) -> dict:
        return dict(zip(self.FIELDS, (float(v) for v in self.totals)))

    def state(self) -> dict:
        return {"totals": [float(v) for v in self.totals], "baseline": self.baseline,
                "steps": self.steps, "power": self.power, "estimate": self.estimate,
                "walls": self.walls.tolist(), "wall_step": self.wall_step.tolist(),
                "last_dt": self.last_dt, "support": self.support.tolist(),
                "support_step": self.support_step.tolist(), "contact": self.contact.tolist(),
                "contact_step": self.contact_step.tolist(), "g_time": self.g_time.tolist(),
                "momentum0": self.momentum0, "mirror_last": self.mirror_last}

    def restore(self, state: dict | None) -> None:
        if state:
            totals = np.array(state["totals"], float)
            self.totals = np.zeros(len(self.FIELDS))
            self.totals[:totals.size] = totals  # a checkpoint written before a column was added
            self.baseline = state["baseline"]
            self.steps = int(state["steps"])
            self.power, self.estimate = state["power"], float(state["estimate"])
            self.walls = np.array(state.get("walls", []), float).reshape(-1, 4)
            self.wall_step = np.array(state.get("wall_step", []), float).reshape(-1, 4)
            self.last_dt = float(state.get("last_dt", 0.0))
            self.support = np.array(state.get("support", [0.0] * 3), float)
            self.support_step = np.array(state.get("support_step", [0.0] * 3), float)
            self.contact = np.array(state.get("contact", []), float).reshape(-1, 4)
            self.contact_step = np.array(state.get("contact_step", []), float).reshape(-1, 4)
            self.g_time = np.array(state.get("g_time", [0.0] * 3), float)
            self.momentum0 = state.get("momentum0")
            self.mirror_last = state.get("mirror_last")


class EnergyWatch:
    """Residual of the energy balance over a run; :meth:`sample` says when it has blown up."""

    def __init__(self, limit: float | None):
        self.limit = limit
        self.initial = None       # K₀ + Ψ₀
        self.scale = 0.0          # max(K₀ + Ψ₀ + W_g) so far
        self.growth = 0.0         # max R / S so far
        self.last = None          # (K, Ψ, W_g) of the last sample
        self.ledger = EnergyLedger()  # fed by the stepper only while a history is written
        self.balance = None           # the history's last energy balance (parmpm.output.history)

    def state(self) -> dict:
        return {"initial": self.initial, "scale": self.scale, "growth": self.growth,
                "ledger": self.ledger.state()}

    def restore(self, state: dict | None) -> None:
        if state:
            self.initial, self.scale = state["initial"], state["scale"]
            self.growth = state["growth"]
            self.ledger.restore(state.get("ledger"))

    def sample(self, totals: np.ndarray) -> float | None:
        """Record (K, Ψ, W_g); return R/S when it exceeds the limit, else None."""
        k, psi, work = (float(v) for v in totals)
        self.last = (k, psi, work)
        if self.initial is None:
            self.initial = k + psi
        given = self.initial + work
        self.scale = max(self.scale, given, self.initial)
        if not self.scale > 0.0:
            return None
        growth = (k + psi - given) / self.scale
        if not np.isfinite(growth):
            growth = np.inf
        self.growth = max(self.growth, growth)
        if self.limit is not None and growth > self.limit:
            return growth
        return None

    def report(self) -> dict:
        """The watch's figures for ``summary.json``."""
        out = {"limit": self.limit, "max_growth": self.growth, "initial": self.initial}
        if self.last is not None:
            k, psi, work = self.last
            out.update(kinetic=k, elastic=psi, gravity_work=work,
                       residual=k + psi - ((self.initial or 0.0) + work))
        if self.balance is not None:
            out["balance"] = self.balance
        return out
