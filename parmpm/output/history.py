"""A run's history: one row of global figures per sample, the same on any number of ranks.

Columns (SI units; ``docs/energy.md`` derives the energy balance):

    time, step, dt                    s, -, s (dt: the last step's)
    kinetic, elastic                  K = Σ ½m|v|², Ψ = Σ V₀(1 − D)ψ(F)                   J
    gravity_potential                 U_g = −Σ m g(t)·(x − X) (X: the initial position)   J
    work_gravity                      work of gravity on the grid since the start          J
    work_forces                       work of the internal (and any body) forces           J
    work_boundary                     work of the boundary constraints (≤ 0)               J
    damping_dissipation               energy taken by mass-proportional damping (≥ 0)      J
    transfer_dissipation              kinetic energy lost between particles and grid       J
    energy_residual                   Ψ − Ψ₀ + work_forces: the time integrator's error    J
    residual_estimate                 its leading term ½ Σ Δt_k (P_k − P_{k−1}), P the power
                                      of the internal forces (docs/energy.md)               J
    increment_work                    X = ½ Σ Δt f·(v_new − v): the forces' work over the
                                      second half of each velocity increment; R + X is the
                                      deformation update's own error (docs/energy.md)      J
    momentum_x.., angular_momentum..  Σ m v, Σ m x × v (about the origin; z only in 2D)
    mass, damaged, frozen             Σ m, particles with D > 0, frozen CPDI domains
    support.force_x.., .impulse_x..   with held faces or regions: their force on the bodies
                                      over the last step, their impulse since the start   N, N s
    mirror.force_x.., .impulse_x..    with symmetry or clamped faces (no damping, no loads):
                                      their mean force since the last row, their impulse
                                      since the start, by momentum balance                N, N s
    plastic_dissipation               with a plastic material: the plastic work so far    J
    work_walls, <wall>.force_x.., <wall>.impulse_x..   with [[walls]] (parmpm.grid.walls)
    work_loads                        with [[loads]]: their work, estimated at the particles J
    work_contact, <name>.force_x.., <name>.impulse_x..   with [contact]: per field, named by
                                      contact.names (default contact<k>); with cracks each
                                      one's far side too, <name>_far                 J, N, N s

and the scene's probes (``[[output.history.probes]]``): ``<name>.<field>`` for the particle
nearest a point in the initial configuration (followed through the run), ``<name>.<field>.<stat>`` for the
mass-weighted mean, the min or the max of a field over the particles that started in a region,
belong to a body or are of a material.

Every sum is a per-patch partial sum added in patch order (:func:`decomposition.ordered_sum`),
every min/max an exact reduction, a point probe's values are the one particle's own: each column
is identical, bit for bit, on any number of ranks. The energy ledger (work of gravity, forces,
constraints, damping) is summed on the grid every step (:class:`parmpm.output.energy.EnergyLedger`).
"""
from __future__ import annotations

import numpy as np

from decomposition import allreduce_max, ordered_sum
from parmpm.core.collective import agree
from parmpm.core.errors import ParmpmError
from parmpm.core.jit import kernel
from parmpm.core.log import get_logger
from parmpm.materials.plasticity.state import STATE_EPSP, plastic_volume
from parmpm.materials.plasticity.update import plastic_energy_sums
from parmpm.output.energy import particle_energy
from parmpm.output.metrics.sums import patch_sums
from parmpm.io.history_columns import (contact_columns, mirror_columns, probe_columns,
                                       support_columns,
                                       wall_columns)
from parmpm.output.reactions import (contact_row, held, mirror_row, mirrors, support_row,
                                    wall_row)

log = get_logger(__name__)

#: component letters of vector and tensor columns (the probe names :mod:`parmpm.scene.history` checks)
AXES = "xyz"


def field_values(P, name: str) -> np.ndarray:
    """Per particle of this rank: the probe field ``name`` (a :func:`field_names` entry)."""
    base, _, comp = name.partition(".")
    if base == "J":
        return np.linalg.det(P.F) if P.n else np.zeros(0)
    if base == "stretch":
        if not P.n:
            return np.zeros(0)
        b = np.einsum("nij,nkj->nik", P.F, P.F)
        return np.sqrt(np.linalg.eigvalsh(b)[:, -1])
    if base == "damage":
        return P.damage
    if base in ("plastic_strain", "plastic_volume"):
        if "plastic" not in P.optional:
            return np.zeros(P.n)
        if base == "plastic_strain":
            return P.plastic[:, STATE_EPSP]
        return plastic_volume(P.plastic)
    vec = {"x": P.x, "u": P.x - P.x0, "v": P.v}
    if base in vec:
        return vec[base][:, AXES.index(comp)]
    tensor = P.stress if base == "stress" else P.F
    return tensor[:, AXES.index(comp[0]), AXES.index(comp[1])]


class Probe:
    """One ``[[output.history.probes]]`` entry (its record, ``scene.spec.output.history.probes``):
    its columns and how to evaluate them."""

    def __init__(self, record, body_ranges: list[tuple[int, int]], material_rows: dict):
        self.name = record.name
        self.fields = list(record.fields)
        self.stats = list(record.stats)
        self.point = record.point
        self.region = record.region
        self.body = record.body
        self.material = record.material
        self.gid = None  # the point probe's particle, chosen at the first sample
        self.ids = body_ranges[self.body] if self.body is not None else None
        self.mat = material_rows[self.material] if self.material is not None else None

    def columns(self) -> list[str]:
        return probe_columns(self.name, self.fields, self.stats)

    def _selected(self, P) -> np.ndarray:
        if self.region is not None:
            lo, hi = np.asarray(self.region.min), np.asarray(self.region.max)
            return np.all((P.x0 >= lo) & (P.x0 <= hi), axis=1)
        if self.ids is not None:
            return (P.gid >= self.ids[0]) & (P.gid < self.ids[1])
        return P.mat == self.mat

    def _choose(self, s) -> None:
        """The particle that started nearest the point (ties: the smaller global id), so a
        restart follows the same one; on every rank."""
        P = s.particles
        best = (np.inf, np.iinfo(np.int64).max)
        if P.n:
            dist = np.sum((P.x0 - np.asarray(self.point)) ** 2, axis=1)
            i = int(np.lexsort((P.gid, dist))[0])
            best = (float(dist[i]), int(P.gid[i]))
        self.gid = min(s.comm.allgather(best))[1]

    def sample(self, s) -> list[float]:
        P = s.particles
        if self.point is not None:
            if self.gid is None:
                self._choose(s)
            here = np.flatnonzero(P.gid == self.gid)
            mine = [float(field_values(P, f)[here[0]]) for f in self.fields] if here.size else None
            return next(v for v in s.comm.allgather(mine) if v is not None)
        sel = self._selected(P)
        vals = np.stack([field_values(P, f) for f in self.fields], axis=1) if P.n else \
            np.zeros((0, len(self.fields)))
        m = np.where(sel, P.mass, 0.0)
        terms = np.concatenate([m[:, None], m[:, None] * np.where(sel[:, None], vals, 0.0)], 1)
        total = ordered_sum(s.comm, s.patches.local_ids, patch_sums(P.start, terms))
        big = np.where(sel[:, None], vals, -np.inf)
        small = np.where(sel[:, None], -vals, -np.inf)
        extreme = allreduce_max(s.comm, np.concatenate([big.max(axis=0, initial=-np.inf),
                                                        small.max(axis=0, initial=-np.inf)]))
        k = len(self.fields)
        out = []
        for j in range(k):
            stat = {"mean": total[1 + j] / total[0] if total[0] > 0 else np.nan,
                    "max": extreme[j] if np.isfinite(extreme[j]) else np.nan,
                    "min": -extreme[k + j] if np.isfinite(extreme[k + j]) else np.nan}
            out += [float(stat[name]) for name in self.stats]
        return out


#: the energy gained beyond what the body was given, as a fraction of that, that gets a warning
GROWTH_WARNING = 0.05
#: the residual's distance from its smooth-loading estimate, as a fraction of the largest energy
#: given, past which the run says that R is not the small first-order error it estimates
RESIDUAL_WARNING = 0.02

ENERGY_COLUMNS = ("kinetic", "elastic", "gravity_potential", "work_gravity", "work_forces",
                  "work_boundary", "damping_dissipation", "transfer_dissipation",
                  "energy_residual", "residual_estimate", "increment_work")


def _vector_columns(dim: int) -> list[str]:
    spin = ["angular_momentum_z"] if dim == 2 else (
        [f"angular_momentum_{a}" for a in AXES] if dim == 3 else [])
    return [f"momentum_{AXES[a]}" for a in range(dim)] + spin


@kernel
def history_sums(d, start, order, mass, vol0, v, x, x0, F, mat, damage, rf, params, g, freezing,
                 affine, inertia):
    """Per patch, in one pass over its particles (in storage order): K, Ψ, Σ m g·(x − X)
    (:func:`parmpm.output.energy.particle_energy`),
    momentum (d), angular momentum (1 in 2D, 3 in 3D; with APIC's affine part
    ``m ε : (C D)ᵀ``, ``inertia = diag D``, zeros under FLIP: :mod:`parmpm.transfer.affine`), mass,
    damaged and frozen particles. Rows ``order[start[p]:start[p + 1]]`` make patch ``p``."""
    spin = 1 if d == 2 else (3 if d == 3 else 0)
    k = 3 + d + spin + 3
    apic = affine.shape[0] > 0  # FLIP runs carry no affine rows
    out = np.zeros((start.size - 1, k))
    for p in range(start.size - 1):
        o = out[p]
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):
            i = order[kk]
            m = mass[i]
            kinetic, stored, work = particle_energy(d, i, mass, vol0, v, x, x0, F, mat, damage,
                                                    params, g)
            o[0] += kinetic
            o[1] += stored
            o[2] += work
            for a in range(d):
                o[3 + a] += m * v[i, a]
            if d == 2:
                o[3 + d] += m * (x[i, 0] * v[i, 1] - x[i, 1] * v[i, 0])
            elif d == 3:
                o[6] += m * (x[i, 1] * v[i, 2] - x[i, 2] * v[i, 1])
                o[7] += m * (x[i, 2] * v[i, 0] - x[i, 0] * v[i, 2])
                o[8] += m * (x[i, 0] * v[i, 1] - x[i, 1] * v[i, 0])
            if apic:  # the particle's own spin m ε:(C D)ᵀ
                C, D = affine[i], inertia
                if d == 2:
                    o[3 + d] += m * (C[1, 0] * D[0] - C[0, 1] * D[1])
                elif d == 3:
                    o[6] += m * (C[2, 1] * D[1] - C[1, 2] * D[2])
                    o[7] += m * (C[0, 2] * D[2] - C[2, 0] * D[0])
                    o[8] += m * (C[1, 0] * D[0] - C[0, 1] * D[1])
            o[k - 3] += m
            if damage[i] > 0.0:
                o[k - 2] += 1.0
            if freezing:  # rf = 0 marks a domain that is not frozen (parmpm.shapes.freeze)
                frozen = False
                for a in range(d):
                    for b in range(d):
                        frozen = frozen or rf[i, a, b] != 0.0
                if frozen:
                    o[k - 1] += 1.0
    return out


class History:
    """The history's columns and rows; :meth:`sample` is collective and returns the new row."""

    def __init__(self, dim: int, probes: list[Probe], walls: tuple[str, ...] = (),
                 loads: bool = False, supports: bool = False, contact: tuple[str, ...] = (),
                 plastic: bool = False, mirrors: bool = False):
        self.dim = dim
        self.mirrors = mirrors  # symmetry or clamped faces: their reaction by momentum balance
        self.plastic = plastic  # a plastic material: its dissipation, in a column of its own
        self.probes = probes
        self.walls = walls
        self.loads = loads
        self.supports = supports
        self.contact = contact  # the contact fields' names (none: no contact)
        self.columns = (["time", "step", "dt", *ENERGY_COLUMNS, *_vector_columns(dim), "mass",
                         "damaged", "frozen"] + [c for p in probes for c in p.columns()]
                        + wall_columns(dim, walls) + (["work_loads"] if loads else [])
                        + (support_columns(dim) if supports else [])
                        + contact_columns(dim, contact)
                        + (mirror_columns(dim) if mirrors else [])
                        + (["plastic_dissipation"] if plastic else []))

    def sample(self, s, gravity: np.ndarray) -> list[float]:
        """One row of the run's state ``s`` (a :class:`parmpm.driver.set_up.RankState`)."""
        P, d = s.particles, self.dim
        R = P.rows  # as they lie (no copy into canonical order): summed in P.order()
        per_patch = history_sums(d, P.start, P.order(), R.mass, R.vol0, R.v, R.x, R.x0, R.F,
                                 R.mat, R.damage, R.rf, s.params,
                                 np.ascontiguousarray(gravity[:d], dtype=np.float64),
                                 s.stepper.freezing, R.affine, s.stepper.inertia)
        if self.plastic:  # Ψ of b_e and the plastic work so far, as two more columns
            per_patch = np.concatenate([per_patch, plastic_energy_sums(
                d, P.start, P.order(), R.vol0, R.F, R.mat, s.stepper.plastic, R.plastic)], axis=1)
        total = ordered_sum(s.comm, s.patches.local_ids, per_patch)
        k, psi, minus_ug = total[0], total[1], total[2]
        dissipated = 0.0
        if self.plastic:
            psi, dissipated = psi + total[-2], total[-1]
            total = total[:-2]
        ledger = s.energy.ledger
        if ledger.baseline is None:
            ledger.baseline = [float(k), float(psi), int(s.clock.nstep)]
        k0, psi0 = ledger.baseline[0], ledger.baseline[1]
        w = ledger.work()
        # the loads' work is not stored; the internal forces' work is stored or dissipated
        residual = psi - psi0 + dissipated + w["forces"] - w["loads"]
        transfer = (k0 - k + w["forces"] + w["gravity"] + w["boundary"] + w["walls"]
                    - w["damping"])
        if self.contact:
            transfer += w["contact"]
        row = [s.clock.t, s.clock.nstep, s.clock.last_dt, k, psi, -minus_ug, w["gravity"],
               w["forces"], w["boundary"], w["damping"], transfer, residual, ledger.estimate,
               w["increment"]]
        row += [float(v) for v in total[3:]]
        for probe in self.probes:
            row += probe.sample(s)
        if self.walls:
            row += wall_row(ledger, self.dim, len(self.walls))
        if self.loads:
            row.append(w["loads"])
        if self.supports:
            row += support_row(ledger, self.dim)
        if self.contact:
            row += contact_row(ledger, self.dim, len(self.contact))
        if self.mirrors:
            spin = 1 if self.dim == 2 else (3 if self.dim == 3 else 0)
            row += mirror_row(ledger, self.dim, s.clock.t, total[3:3 + self.dim],
                              float(total[3 + self.dim + spin]))
        if self.plastic:
            row.append(dissipated)
        return [float(v) for v in row]


def body_ranges(grid, bodies, material_rows: dict) -> list[tuple[int, int]]:
    """Global-id range ``[first, last)`` of every body (``grid``, ``bodies``: the scene's
    records): particles are numbered body by body, in the order of ``[[bodies]]``
    (:func:`parmpm.particles.seeding.seed_bodies`, one chunk per body). Seeds the scene again:
    only for a checkpoint written before checkpoints recorded the ranges
    (:mod:`parmpm.scene.recorded_files`)."""
    from parmpm.particles.seeding import seed_bodies

    ends = np.cumsum([len(chunk[0]) for chunk in seed_bodies(grid, bodies, material_rows).chunks])
    return [(int(e - len_), int(e)) for e, len_ in
            zip(ends, np.diff(np.concatenate([[0], ends])))]


class HistoryOutput:
    """The run's history: the rows (:class:`History`), ``history.csv`` on rank 0, and at the end
    the same table in the run's HDF5 and ``history.png``."""

    def __init__(self, sim):
        spec, rows = sim.state.spec, sim.state.material_rows
        probes = spec.output.history.probes
        bodies = sim.state.body_ranges  # seeded, or as the checkpoint records them
        self.history = History(sim.dim, [Probe(p, bodies, rows) for p in probes],
                               tuple(w.name for w in spec.walls), bool(spec.loads),
                               held(spec.boundary),
                               spec.contact.column_names() if spec.contact else (),
                               sim.state.stepper.plastic is not None, mirrors(spec))
        self.file = None
        self.last_step = -1
        self.last = None
        self.scale, self.warned, self.warned_residual = 0.0, False, False
        problem = None
        if sim.state.rank == 0:
            try:
                from parmpm.io.history_file import HistoryFile
                self.file = HistoryFile(sim.out_dir, self.history.columns)
            except OSError as exc:
                problem = f"cannot write '{sim.out_dir / 'history.csv'}': {exc.strerror or exc}"
        agree(sim.comm, problem)

    def sample(self, sim) -> None:
        """A row (collective); rank 0 appends it to ``history.csv``."""
        if self.last_step == sim.nstep:
            return
        row = self.history.sample(sim.state, sim.gravity(sim.t))
        self.last_step, self.last = sim.nstep, dict(zip(self.history.columns, row))
        self._check_growth(sim)
        problem = None
        if self.file is not None:
            try:
                self.file.append(row)
            except OSError as exc:
                problem = f"cannot write '{self.file.path}': {exc.strerror or exc}"
        agree(sim.comm, problem)

    def _check_growth(self, sim) -> None:
        """Keep the balance for the summary; warn once when the body holds more energy than it
        was given by over ``GROWTH_WARNING`` of the largest energy given (the blow-up watch,
        :mod:`parmpm.output.energy`, stops the run at ``time.max_energy_growth``)."""
        r = self.last
        k0, psi0 = sim.state.energy.ledger.baseline[:2]
        # moving walls and loads give energy
        pushed = max(r.get("work_walls", 0.0), 0.0) + r.get("work_loads", 0.0)
        self.scale = max(self.scale, k0 + psi0 + r["work_gravity"] + pushed, k0 + psi0)
        # rigid walls and supports do no work (their nodes do not move): W_bc is not energy
        # given to the body (with FLIP the particles keep much of what it removes from the grid)
        gained = (r["kinetic"] + r["elastic"] - k0 - psi0 - r["work_gravity"] - pushed
                  + r["damping_dissipation"])
        sim.state.energy.balance = {
            "gained": gained, "scale": self.scale,
            **{c: r[c] for c in ENERGY_COLUMNS[3:] + ("residual_estimate",)}}
        if not self.warned and self.scale > 0 and gained > GROWTH_WARNING * self.scale:
            self.warned = True
            if sim.state.rank == 0:  # every rank knows it: one line
                log.warning("at t = %.6g s the body holds %.4g J more than it was given (%.1f %% of "
                            "%.4g J): a sign of instability (see history.csv; lower time.cfl, or "
                            "method.update = \"musl\")", sim.t, gained,
                            100 * gained / self.scale, self.scale)
        if gained < RESIDUAL_WARNING * self.scale:  # a gain is the warning above's business
            self._check_residual(sim, r)

    def _check_residual(self, sim, r: dict) -> None:
        """Warn once when the residual ``R`` is further from its estimate than
        ``RESIDUAL_WARNING`` of the largest energy given while the body has not gained energy (an
        unstable run gets the growth warning alone): the step's error is then not the smooth
        ``½Δt dP/dt`` it estimates but an impact's, or that of grid velocity increments the
        particles do not receive, whose energy ``R`` and ``transfer_dissipation`` share
        (docs/energy.md: only their difference is then the net loss)."""
        off = r["energy_residual"] - r["residual_estimate"]
        if self.warned_residual or not abs(off) > RESIDUAL_WARNING * self.scale:
            return
        self.warned_residual = True
        if sim.state.rank == 0:
            log.warning("at t = %.6g s the energy residual R = %.4g J is %.1f %% of the %.4g J given "
                        "but its smooth-loading estimate is %.4g J: an impact, or grid velocity "
                        "increments the particles do not receive, whose energy R shares with "
                        "transfer_dissipation (%.4g J; the net gain R - D_t = %.4g J); R converges "
                        "as time.cfl is lowered (docs/energy.md)", sim.t, r["energy_residual"],
                        100 * abs(r["energy_residual"]) / self.scale, self.scale,
                        r["residual_estimate"], r["transfer_dissipation"],
                        r["energy_residual"] - r["transfer_dissipation"])

    def finish(self, sim) -> None:
        """The table into the run's HDF5 (or ``history.h5``) and ``history.png`` (rank 0)."""
        problem = None
        if self.file is not None:
            from parmpm.io.history_file import plot_history, write_table_h5
            try:
                self.file.close()
                columns, attrs = self.file.table()
                snapshots = sim.files.snapshots if sim.files is not None else None
                if snapshots is not None:  # the run's snapshot file: its /history group
                    snapshots.write_table("history", columns, attrs)
                else:
                    write_table_h5(sim.out_dir / "history.h5", "history", columns, attrs)
                if sim.spec.output.figure and self.file.count > 1:
                    plot_history(columns, sim.out_dir / "history.png",
                                 f"{sim.spec.name} · {sim.state.interp.name} · energy history")
            except ParmpmError as exc:  # the snapshot writer's one line (a full disk)
                problem = str(exc)
            except OSError as exc:
                problem = f"cannot write the history to '{sim.out_dir}': {exc.strerror or exc}"
        agree(sim.comm, problem)
