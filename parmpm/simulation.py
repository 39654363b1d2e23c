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

from decomposition import PatchSet, SerialComm, allreduce_max
from parmpm.errors import ParmpmError, RunInterrupted, SimulationError
from parmpm.grid import BC_CODES
from parmpm.log import get_logger
from parmpm.measures import Measures
from parmpm.materials import material_table
from parmpm.particles import Particles, locate_patches
from parmpm.seeding import seed_bodies
from parmpm.progress import Progress
from parmpm.shapes import CPDI, INTERPOLATORS
from parmpm.stepper import PHASES, WORK_PHASES, Discretisation, Stepper, exterior_cells, fmt_vec
from parmpm.transfer import max_speed

log = get_logger(__name__)


class Simulation(Measures):
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
        # the patches cover the grid and its exterior layer (grid.exterior), the face conditions
        # stay on the user's faces (parmpm.stepper.exterior_cells)
        self.disc = Discretisation.from_grid(d, interp.code, self.lcr or 0.0, grid, int(ghost),
                                             exterior_cells(data, int(ghost)))
        layout = self.disc.layout
        self.params, names = material_table(data["materials"])
        self.restart = checkpoint
        P = seeds = counts = where = None
        D = self.disc
        dec = data["decomposition"]
        if checkpoint is None:
            # Every rank seeds the same particles (global ids = seeding order) and builds only
            # its own once the patches are dealt out (parmpm.seeding).
            seeds = seed_bodies(data, {n: i for i, n in enumerate(names)})
            if data.get("manufactured"):  # start on the exact field (before patches are chosen)
                from parmpm.manufactured import initialise
                P, seeds = seeds.particles(self.params), None
                initialise(P, data["manufactured"]["amplitude"], self.params)
            elif data["metrics"]["kind"] == "none":  # no metric needs every particle's x0
                counts = seeds.patch_counts(D)  # unturned boxes: counted axis by axis
        if counts is not None:
            self.n_total = seeds.n
            self.metrics = None
        else:
            if P is not None:
                x_all, x0_all, mass_all = P.x, P.x0, P.mass
            elif seeds is not None:
                x_all = x0_all = seeds.x
                mass_all = seeds.mass(self.params) if data["metrics"]["kind"] != "none" else None
            else:
                x_all, x0_all, mass_all = (checkpoint.read(k) for k in ("x", "x0", "mass"))
            self.n_total = x_all.shape[0]
            from parmpm.metrics import make_metrics
            self.metrics = make_metrics(data, x0_all, mass_all)
            where = np.zeros(self.n_total, np.int64)
            bad, _ = locate_patches(d, x_all, D.origin3, D.inv_h3, layout.cells3, layout.psize3,
                                    layout.patches_per_axis, where, where)
            if bad >= 0:
                raise SimulationError(f"particle {bad} at {fmt_vec(x_all[bad])} is outside the grid")
            counts = np.bincount(where, minlength=layout.n_patches)
            del x_all, x0_all, mass_all  # no second reference to the seeded arrays while they move
        self.patches = PatchSet(layout, comm, counts, threshold=dec["rebalance_threshold"],
                                cooldown=dec["rebalance_cooldown"])
        owned = self.patches.rank_of == self.rank
        mine = np.flatnonzero(owned[where]) if where is not None else seeds.members(D, owned)
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
        if where is not None:
            P.patch = where[mine]
        else:  # the lattice path: locate only this rank's particles
            locate_patches(d, P.x, D.origin3, D.inv_h3, layout.cells3, layout.psize3,
                           layout.patches_per_axis, P.patch, P.patch)
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
            "grid": {"cells": [int(c) for c in self.disc.cells],
                     "exterior": [[int(c) for c in self.disc.exterior_lo],
                                  [int(c) for c in self.disc.exterior_hi]],
                     "cell_size": list(map(float, self.disc.h)),
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
