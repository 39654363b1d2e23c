"""The run loop: owns time (Δt from CFL, stop criteria), not physics.

``Simulation(scene, out_dir, comm=comm).run()`` builds particles and patches from the resolved
scene, spreads the patches over the ranks of ``comm`` (none: one rank), steps until ``time.end``
or ``time.steps``, samples the scene's metrics, writes snapshots (XDMF), ``summary.json`` and a
figure, and returns the summary. Output and metrics are callbacks on the clock; a non-finite
velocity stops the run with a clear error (NaN check on by default). Every rank runs the same
loop with the same global Δt; every figure in the summary is reduced over all ranks and only
rank 0 writes files.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from decomposition import PatchLayout, PatchSet, SerialComm, allreduce_max, ordered_sum
from parmpm.errors import ParmpmError, RunInterrupted, SimulationError
from parmpm.grid import BC_CODES
from parmpm.log import get_logger
from parmpm.materials import material_table
from parmpm.particles import Particles, locate_patches, seed_bodies
from parmpm.progress import Progress
from parmpm.shapes import CPDI, INTERPOLATORS
from parmpm.stepper import (PHASES, WORK_PHASES, Discretisation, Stepper, fmt_vec, reach_message,
                            support_reach)
from parmpm.transfer import max_speed, support_nodes

log = get_logger(__name__)


class Simulation:
    """One run of a resolved scene on this process's patches (``comm``: an mpi4py communicator;
    None runs every patch here)."""

    def __init__(self, scene, out_dir=None, quiet: bool = False, comm=None, checkpoint=None):
        self.scene = scene
        self.data = data = scene.data
        self.out_dir = Path(out_dir) if out_dir else Path("parmpm-out") / scene.name
        self.quiet = quiet
        self.comm = comm = comm if comm is not None else SerialComm()
        self.rank, self.size = comm.Get_rank(), comm.Get_size()
        d = self.dim = data["dim"]
        grid = data["grid"]
        interp = INTERPOLATORS[data["method"]["interpolator"]]
        self.interp = interp
        self.lcr = scene.lcr if interp.code == CPDI else None
        ghost = grid["ghost"]
        if ghost == "auto":
            ghost = interp.ghost_width(self.lcr, scene.min_dx)
        layout = PatchLayout(tuple(grid["cells"]), tuple(grid["patch_size"]), int(ghost))
        self.disc = Discretisation(d, interp.code, self.lcr or 0.0,
                                   np.asarray(grid["origin"], float),
                                   np.asarray(grid["cell_size"], float), layout)
        self.params, names = material_table(data["materials"])
        self.restart = checkpoint
        P = seeds = None
        if checkpoint is None:
            # Every rank seeds the same positions (global ids = seeding order) and builds only
            # its own particles once the patches are dealt out.
            seeds = seed_bodies(data, {n: i for i, n in enumerate(names)})
            if data.get("manufactured"):  # start on the exact field (before patches are chosen)
                from parmpm.manufactured import initialise
                P, seeds = seeds.particles(self.params), None
                initialise(P, data["manufactured"]["amplitude"], self.params)
                x_all, x0_all, mass_all = P.x, P.x0, P.mass
            else:
                x_all = x0_all = seeds.x
                mass_all = seeds.mass(self.params) if data["metrics"]["kind"] != "none" else None
        else:
            x_all, x0_all, mass_all = (checkpoint.read(k) for k in ("x", "x0", "mass"))
        self.n_total = x_all.shape[0]
        from parmpm.metrics import make_metrics
        self.metrics = make_metrics(data, x0_all, mass_all)
        D = self.disc
        where = np.zeros(self.n_total, np.int64)
        bad, _ = locate_patches(d, x_all, D.origin3, D.inv_h3, layout.cells3, layout.psize3,
                                layout.patches_per_axis, where, where)
        if bad >= 0:
            raise SimulationError(f"particle {bad} at {fmt_vec(x_all[bad])} is outside the grid")
        dec = data["decomposition"]
        self.patches = PatchSet(layout, comm, np.bincount(where, minlength=layout.n_patches),
                                threshold=dec["rebalance_threshold"],
                                cooldown=dec["rebalance_cooldown"])
        mine = np.flatnonzero(self.patches.rank_of[where] == self.rank)
        del x_all, x0_all, mass_all  # no second reference to the seeded arrays while they move
        if checkpoint is None:
            if seeds is not None:
                P = seeds.particles(self.params, mine)
                del seeds
            elif mine.size != P.n:
                P.permute(mine)
        else:  # collective: a damaged block found by one rank stops every rank
            problem = None
            try:
                P = self._load_particles(checkpoint, mine)
            except ParmpmError as exc:
                problem = str(exc)
            problems = [p for p in comm.allgather(problem) if p]
            if problems:
                raise ParmpmError(problems[0])
        P.patch = where[mine]
        self.particles = P
        bc = np.zeros((3, 2), np.int64)
        for k, axis in enumerate("xyz"[:d]):
            bc[k] = [BC_CODES[data["boundary"][f"{axis}_min"]], BC_CODES[data["boundary"][f"{axis}_max"]]]
        regions = data["boundary"]["fixed_regions"] + data["boundary"]["slip_regions"]
        region_box = np.zeros((len(regions), 2, 3))
        region_normal = np.full(len(regions), -1, np.int64)  # -1: fixed, k: slip with normal k
        for r, reg in enumerate(regions):
            region_box[r, 0, :d], region_box[r, 1, :d] = reg["min"], reg["max"]
            if "normal" in reg:
                region_normal[r] = "xyz".index(reg["normal"])
        m = data["method"]
        self.update = m["update"] if m["update"] != "auto" else ("usl" if interp.code == CPDI else "musl")
        self.stepper = Stepper(self.disc, P, self.patches, self.params, bc, region_box, self.update,
                               m["flip"], data["damping"]["coefficient"], self.n_total, region_normal)
        if data.get("manufactured"):
            self._manufactured(data["manufactured"]["amplitude"])
        self.t, self.nstep, self.last_dt = 0.0, 0, 0.0
        self.next_out = None
        # callables f(simulation), run (collectively) at every output time after the snapshot:
        # how studies look at the state without files
        self.observers: list = []
        if checkpoint is None:
            vmax = max_speed(d, P.v, P.F, P.mat, self.params)
            self.vmax = float(allreduce_max(comm, np.array([vmax]))[0])
        else:
            a = checkpoint.attrs
            self.t, self.nstep = float(a["time"]), int(a["step"])
            self.last_dt, self.vmax = float(a["dt"]), float(a["vmax"])
            state = checkpoint.state
            self.next_out = state.get("next_output")
            if self.metrics is not None and state.get("metrics"):
                self.metrics.restore(state["metrics"])

    def _manufactured(self, A: float) -> None:
        """Drive the run with the manufactured solution's body force (:mod:`parmpm.manufactured`)."""
        from parmpm.manufactured import body_force, frequency
        from parmpm.materials import PARAM

        c, row = frequency(self.params), self.params[0]
        lam, mu, rho = row[PARAM["lam"]], row[PARAM["mu"]], row[PARAM["density"]]
        d = self.dim
        self.stepper.forcing = lambda t, P, out: body_force(d, P.x0, t, A, c, lam, mu, rho, out)

    @classmethod
    def from_checkpoint(cls, path, overrides=(), out_dir=None, quiet=False, comm=None):
        """Continue the run saved in ``path`` (on any number of ranks); ``overrides`` apply to
        the stored scene (e.g. ``time.end=...``)."""
        from parmpm.io.checkpoint import CheckpointReader
        from parmpm.scene import scene_from_toml

        reader = CheckpointReader(path)
        if out_dir is None:  # never over earlier output: a folder of its own beside the file
            out_dir = Path(path).parent / f"restart_{int(reader.attrs['step']):08d}"
        try:
            scene = scene_from_toml(str(reader.attrs["scene"]), f"{path}", overrides)
            return cls(scene, out_dir, quiet=quiet, comm=comm, checkpoint=reader)
        finally:
            reader.close()

    def _load_particles(self, reader, mine: np.ndarray) -> Particles:
        """This rank's rows of the checkpoint, read block by block (``mine`` ascending)."""
        from parmpm.io.checkpoint import FIELDS

        P = Particles(self.dim, mine.size)
        block = 1 << 18
        for name in FIELDS:
            if not reader.has(name):  # an older format: the field keeps its initial value
                continue
            dst = getattr(P, name)
            for lo in range(0, self.n_total, block):
                hi = min(lo + block, self.n_total)
                a, b = np.searchsorted(mine, [lo, hi])
                if b > a:
                    dst[a:b] = reader.read(name, lo, hi)[mine[a:b] - lo]
        if not np.array_equal(P.gid, mine):
            raise ParmpmError(f"checkpoint '{reader.path}': damaged: particle ids out of order")
        return P

    # --- clock --------------------------------------------------------------------------------
    def next_dt(self) -> float:
        tm = self.data["time"]
        dt = tm["cfl"] * float(self.disc.h.min()) / self.vmax
        if tm["dt_max"]:
            dt = min(dt, tm["dt_max"])
        if tm["end"] is not None:
            dt = min(dt, tm["end"] - self.t)
        return dt

    def done(self) -> bool:
        tm = self.data["time"]
        if tm["steps"] is not None and self.nstep >= tm["steps"]:
            return True
        return tm["end"] is not None and self.t >= tm["end"] * (1 - 1e-12)

    def gravity(self, t: float) -> np.ndarray:
        g = self.data["gravity"]
        ramp = g["ramp_time"]
        f = min(1.0, t / ramp) if ramp > 0 else 1.0
        return np.concatenate([np.asarray(g["g"], float) * f, np.zeros(3 - self.dim)])

    # --- callbacks (collective: every rank calls them) ---------------------------------------
    def components(self) -> int:
        """Connected pieces of material over all ranks (particles linked through grid nodes)."""
        from parmpm.connectivity import compact_nodes, global_components, local_components, shared_pairs

        P, D, ps = self.particles, self.disc, self.patches
        # entries per particle: a tensor-product support reaches at most `ghost` cells past the
        # particle's cell on each side (farther is the reach error below), a CPDI one 2^d nodes
        # for each of 2^d corners
        g = int(D.layout.ghost)
        K = min(int(np.prod(D.nloc[:self.dim])), max(4 ** self.dim, (2 * g + 2) ** self.dim))
        nodes = np.zeros((P.n, K), np.int64)
        count = np.zeros(P.n, np.int64)
        err = np.full(1, -1, np.int64)
        support_nodes(D.method, D.dim, D.lcr, P.start, D.base, D.nloc, D.nglob, D.origin3,
                      D.inv_h3, P.x, P.F, P.r0, P.lh0, nodes, count, err)
        # A support past the ghost layer (inside the grid) would leave that particle without
        # nodes and fake a separation: stop with the reach error (the next p2g would raise it).
        # A support leaving the grid belongs to material on its way out: it counts as a piece of
        # its own, and the next step stops the run unless the separation stops it first.
        bad = int(err[0]) >= 0 and support_reach(self.stepper, int(err[0]))[1]
        if bad and self.stepper.error is None:
            self.stepper.error = reach_message(self.stepper, int(err[0]), "the separation check")
        failed = allreduce_max(self.comm, np.array([self.rank + 1.0 if bad else 0.0]))[0]
        if failed > 0:
            raise SimulationError(self.comm.bcast(self.stepper.error, root=int(failed) - 1))
        compact, n_nodes = compact_nodes(nodes, count)
        k, label = local_components(compact, count, n_nodes)
        if self.size == 1:
            return int(k)
        lay = D.layout
        pairs = shared_pairs(nodes, count, label, lay.global_nodes3, lay.psize3, lay.ghost3,
                             lay.patches_per_axis, ps.rank_of, self.rank)
        return global_components(self.comm, int(k), pairs)

    def sample_metrics(self) -> int:
        """Sample the scene's metrics; returns the number of connected pieces of material (1 when
        the metric does not look at separation: counting them costs about a time step)."""
        if self.metrics is None:
            return 1
        from parmpm.metrics import patch_sums

        P = self.particles
        pieces = self.components() if self.metrics.needs_components else 1
        sums, maxes = self.metrics.terms(P.gid, P.x, P.v, P.F, t=self.t, particles=P,
                                         method=self.disc.method, lcr=self.disc.lcr)
        per_patch = patch_sums(P.start, np.ascontiguousarray(sums))
        total = ordered_sum(self.comm, self.patches.local_ids, per_patch)
        maxes = allreduce_max(self.comm, maxes) if maxes.size else maxes
        self.metrics.record(self.t, total, maxes, pieces, v_time=self.t - 0.5 * self.last_dt)
        return pieces

    def totals(self) -> dict:
        """Mass, momentum and kinetic energy over all ranks (per-patch sums in patch order)."""
        from parmpm.metrics import patch_sums

        P = self.particles
        terms = np.concatenate([P.mass[:, None], P.mass[:, None] * P.v,
                                0.5 * P.mass[:, None] * np.sum(P.v * P.v, axis=1, keepdims=True)], axis=1)
        total = ordered_sum(self.comm, self.patches.local_ids, patch_sums(P.start, terms))
        return {"mass": float(total[0]), "momentum": [float(c) for c in total[1:1 + self.dim]],
                "kinetic_energy": float(total[-1])}

    def gather(self, fields: dict[str, np.ndarray]) -> dict[str, np.ndarray] | None:
        """All particles' ``fields`` in global-id order on rank 0 (None elsewhere). Output only."""
        fields = dict(fields, _gid=self.particles.gid)
        parts = self.comm.gather(fields, root=0)
        if self.rank != 0:
            return None
        out = {k: np.concatenate([p[k] for p in parts]) for k in fields}
        order = np.argsort(out.pop("_gid"), kind="stable")
        return {k: v[order] for k, v in out.items()}

    def axial_stretch(self) -> np.ndarray:
        axis = self.data["metrics"]["axis"]
        return np.linalg.norm(self.particles.F[:, :, axis], axis=1)

    def domain_corners(self) -> np.ndarray | None:
        """(N, 4, 2) domain corners of this rank's particles as the interpolation sees them
        (scaled CPDI domains, cpGIMP boxes, ...; :mod:`parmpm.domains`); 2D only."""
        if self.dim != 2:
            return None
        from parmpm.domains import domain_corners

        P = self.particles
        return domain_corners(2, self.disc.method, self.disc.lcr, P.x, P.F, P.r0, P.lh0)

    def output(self, writer) -> None:
        """An output time: the snapshot (if enabled), then every observer (collective)."""
        self.snapshot(writer)
        for observe in self.observers:
            observe(self)

    def snapshot(self, writer) -> None:
        if not self.data["output"]["snapshots"]:
            return
        P = self.particles
        g = self.gather({"x": P.x, "velocity": P.v, "stress": P.stress.reshape(P.n, self.dim * self.dim),
                         "stretch": self.axial_stretch(), "damage": P.damage,
                         "rank": np.full(P.n, float(self.rank)), "gid": P.gid.astype(float)})
        if writer is None or g is None:
            return
        x = g.pop("x")
        writer.write(self.t, x, g)

    def write_checkpoint(self) -> Path:
        """Write ``checkpoint_<step>.h5`` (collective): blocks of global ids gathered to rank 0,
        which writes them; atomic; the oldest beyond ``checkpoint.keep`` are deleted."""
        import json

        from parmpm.io.checkpoint import FIELDS, CheckpointWriter, checkpoint_name, prune

        P, root = self.particles, self.rank == 0
        order = np.argsort(P.gid, kind="stable")
        gids = P.gid[order]
        path = self.out_dir / checkpoint_name(self.nstep)
        state = {"metrics": self.metrics.state() if self.metrics is not None else None,
                 "next_output": self.next_out}
        attrs = {"scene": self.scene.to_toml(), "step": self.nstep, "time": self.t,
                 "dt": self.last_dt, "vmax": self.vmax, "method": self.interp.name,
                 "lcr": self.lcr if self.lcr is not None else float("nan"), "ranks": self.size,
                 "particles": self.n_total, "dim": self.dim, "state": json.dumps(state)}
        writer, problem = None, None
        if root:
            try:
                writer = CheckpointWriter(path, self.n_total,
                                          {k: getattr(P, k)[:0] for k in FIELDS}, attrs)
            except ParmpmError as exc:
                problem = str(exc)
        problem = self.comm.bcast(problem, root=0)
        if problem:
            raise ParmpmError(problem)
        block = 1 << 18  # ids per gather: bounds rank 0's extra memory
        for lo in range(0, self.n_total, block):
            hi = min(lo + block, self.n_total)
            a, b = np.searchsorted(gids, [lo, hi])
            part = {k: getattr(P, k)[order[a:b]] for k in FIELDS}
            parts = self.comm.gather(part, root=0)
            if root and problem is None:
                try:
                    merged = {k: np.concatenate([q[k] for q in parts]) for k in FIELDS}
                    o = np.argsort(merged["gid"], kind="stable")
                    merged = {k: v[o] for k, v in merged.items()}
                    if not np.array_equal(merged["gid"], np.arange(lo, hi)):
                        raise ParmpmError(f"checkpoint: particle ids {lo}..{hi - 1} incomplete")
                    writer.write(lo, merged)
                except (OSError, ParmpmError) as exc:
                    problem = f"cannot write checkpoint '{path}': {exc}"
        if root:
            try:
                if problem is None:
                    writer.commit()
                    prune(self.out_dir, self.data["checkpoint"]["keep"])
                else:
                    writer.abort()
            except OSError as exc:
                problem = f"cannot write checkpoint '{path}': {exc}"
        problem = self.comm.bcast(problem, root=0)
        if problem:
            raise ParmpmError(problem)
        log.info("wrote %s (step %d, t = %.6g s)", path, self.nstep, self.t)
        return path

    def decomposition_report(self) -> dict:
        """Patches, particles per rank, imbalance, ghost width and halo traffic (collective)."""
        ps, lay = self.patches, self.disc.layout
        plan = ps.plan
        d = self.dim
        comps = 1 + 2 * d if self.update == "usl" else 1 + 3 * d  # components accumulated
        comps_fill = 2 * d if self.update == "usl" else 3 * d     # components filled
        # bytes this rank sends per step: ghost boxes in accumulate, owned boxes in fill
        sent = 8 * (int(plan.ghost_seg_nodes.sum()) * comps + int(plan.own_seg_nodes.sum()) * comps_fill)
        local = {"patches": ps.n_local, "particles": int(self.particles.n), "sent": sent}
        rows = self.comm.allgather(local)
        loads = np.array([r["particles"] for r in rows], float)
        halo_bytes = sum(r["sent"] for r in rows)
        return {
            "ranks": self.size, "patches": int(ps.ids.size), "patches_dense": lay.n_patches,
            "patch_size": list(lay.patch_size), "ghost": lay.ghost,
            "patches_per_rank": [r["patches"] for r in rows],
            "particles_per_rank": [r["particles"] for r in rows],
            "imbalance": float(loads.max() / loads.mean() - 1.0) if loads.mean() > 0 else 0.0,
            "halo_bytes_per_step": int(halo_bytes),
            "rebalances": ps.rebalances, "patch_set_changes": ps.rebuilds,
        }

    # --- signals ------------------------------------------------------------------------------
    def _trap_signals(self):
        """SIGTERM/SIGINT (a batch system's time limit, Ctrl-C) only raise a flag; the ranks agree
        on it at the end of the step, write a checkpoint and stop together."""
        import signal
        import threading

        if threading.current_thread() is not threading.main_thread():
            return None

        def flag(signum, frame):
            self.stepper.stop_flag = True

        return {sig: signal.signal(sig, flag) for sig in (signal.SIGTERM, signal.SIGINT)}

    @staticmethod
    def _restore_signals(old) -> None:
        import signal

        for sig, handler in (old or {}).items():
            signal.signal(sig, handler)

    # --- the loop -----------------------------------------------------------------------------
    def run(self) -> dict:
        """Step to the end (collective). Every rank returns the same summary; rank 0 writes the
        shared files (summary.json, snapshots, figure)."""
        from parmpm.io.summary import write_summary
        from parmpm.io.xdmf import SnapshotWriter

        data = self.data
        out = data["output"]
        root = self.rank == 0
        problem = None
        if root:
            try:
                self.out_dir.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                problem = f"cannot create output folder '{self.out_dir}': {exc.strerror}"
        problem = self.comm.bcast(problem, root=0)
        if problem:
            raise ParmpmError(problem)
        series = data["name"] if self.restart is None else f"{data['name']}_from_{self.nstep:08d}"
        writer = SnapshotWriter(self.out_dir, series, self.dim) if out["snapshots"] and root else None
        every_t, every_n = out["every"], out["every_steps"]
        if self.next_out is None:
            self.next_out = every_t if every_t else math.inf
        ck = data["checkpoint"]
        next_ck = ck["every"] * (math.floor(self.t / ck["every"] + 1e-9) + 1) if ck["every"] else math.inf
        ck_wall = time.monotonic()
        me = data["metrics"]["every_steps"]
        stop_on_sep = data["metrics"]["stop_on_separation"]
        self.stopped = None
        progress = Progress(total_steps=data["time"]["steps"], end_time=data["time"]["end"],
                            enabled=not self.quiet and root)
        wall0 = time.perf_counter()
        warm_wall, warm_steps = None, 0
        old_handlers = self._trap_signals()
        try:
            if self.restart is None:  # a restarted run has these from before
                self.sample_metrics()
                self.output(writer)
            while not self.done():
                dt = self.next_dt()
                self.vmax = self.stepper.step(dt, self.gravity(self.t), self.t)
                self.t += dt
                self.nstep += 1
                self.last_dt = dt
                if not math.isfinite(self.vmax):
                    raise SimulationError(f"non-finite velocity or stress at step {self.nstep} "
                                          f"(t = {self.t:.6g} s); try a smaller time.cfl")
                if warm_wall is None:
                    warm_wall = time.perf_counter()  # the first step includes JIT compilation
                    self.stepper.timers = dict.fromkeys(self.stepper.timers, 0.0)
                else:
                    warm_steps += 1
                if self.nstep % me == 0 and self.sample_metrics() > 1 and stop_on_sep:
                    self.stopped = "separated"
                    log.info("material separated at t = %.6g s: stopping (metrics.stop_on_separation)", self.t)
                    self.output(writer)
                    break
                due = (every_n and self.nstep % every_n == 0) or self.t >= self.next_out * (1 - 1e-12)
                if due or self.done():
                    self.output(writer)
                    while self.next_out <= self.t * (1 + 1e-12):
                        self.next_out += every_t
                if self.stepper.stop_requested:
                    path = self.write_checkpoint()
                    raise RunInterrupted(f"interrupted at step {self.nstep} (t = {self.t:.6g} s); "
                                         f"continue with: parmpm restart {path}")
                ck_due = (ck["every_steps"] and self.nstep % ck["every_steps"] == 0) or \
                    self.t >= next_ck * (1 - 1e-12) or (ck["at_end"] and self.done())
                if ck["wall_minutes"]:
                    waited = allreduce_max(self.comm, np.array([time.monotonic() - ck_wall]))[0]
                    ck_due = ck_due or waited >= 60.0 * ck["wall_minutes"]
                if ck_due:
                    self.write_checkpoint()
                    ck_wall = time.monotonic()
                    while next_ck <= self.t * (1 + 1e-12):
                        next_ck += ck["every"]
                elapsed = time.perf_counter() - (warm_wall or wall0)
                rate = self.n_total * warm_steps / elapsed if warm_steps and elapsed > 0 else 0.0
                progress.update(self.nstep, self.t, rate)
        finally:
            self._restore_signals(old_handlers)
            progress.close()
            if writer is not None:
                writer.close()
        wall = time.perf_counter() - wall0
        loop = time.perf_counter() - warm_wall if warm_wall else wall
        wall, loop = (float(v) for v in allreduce_max(self.comm, np.array([wall, loop])))
        timers = self.stepper.timers
        per_rank = np.array(self.comm.allgather([timers[k] for k in PHASES]))  # (ranks, phases)
        phase = per_rank.max(axis=0)
        # each rank's own work (the phases that wait for no one): how unevenly it is spread
        work = per_rank[:, [PHASES.index(k) for k in WORK_PHASES]].sum(axis=1)
        lay = self.disc.layout
        summary = {
            "scene": data["name"], "dim": self.dim, "method": self.interp.name,
            "lcr": self.lcr, "update": self.update, "flip": data["method"]["flip"],
            "ranks": self.size, "particles": self.n_total, "steps": self.nstep, "time": self.t,
            "stopped": self.stopped or "end",
            "wall_seconds": wall,
            "particle_steps_per_second": (self.n_total * warm_steps / loop
                                          if warm_steps and loop > 0 else None),
            "grid": {"cells": list(lay.cells), "cell_size": list(map(float, self.disc.h)),
                     "patch_size": list(lay.patch_size), "patches": int(self.patches.ids.size),
                     "ghost": lay.ghost},
            "decomposition": self.decomposition_report(),
            "final": self.totals(),
            "phase_seconds_per_step": ({k: float(v) / warm_steps for k, v in zip(PHASES, phase)}
                                       if warm_steps else None),
            "rank_work_seconds_per_step": ({"min": float(work.min()) / warm_steps,
                                            "mean": float(work.mean()) / warm_steps,
                                            "max": float(work.max()) / warm_steps}
                                           if warm_steps else None),
            "metrics": self.metrics.result() if self.metrics is not None else {},
        }
        if root:
            write_summary(self.out_dir, summary)
        if out["figure"]:
            P = self.particles
            corners = self.domain_corners()
            fields = {"x": P.x, "stretch": self.axial_stretch()}
            if corners is not None:
                fields["corners"] = corners
            g = self.gather(fields)
            if root:
                from parmpm.io.figures import plot_particles
                plot_particles(self.out_dir / f"{data['name']}.png", g["x"], g["stretch"],
                               self.dim, corners=g.get("corners"),
                               title=f"{data['name']} · {self.interp.name} · t = {self.t:.3g} s")
        return summary
