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
import uuid
from pathlib import Path

import numpy as np

from decomposition import PatchSet, SerialComm, allreduce_max, ranks_on_this_node
from parmpm.errors import ParmpmError, RunInterrupted, SimulationError
from parmpm.footprint import check_memory
from parmpm.grid import BC_CODES
from parmpm.log import get_logger
from parmpm.measures import Measures
from parmpm.materials import material_table
from parmpm.checkpointing import load_particles, write_checkpoint
from parmpm.energy import ENERGY_EVERY, EnergyWatch, energy_totals
from parmpm.particles import locate_patches
from parmpm.seeding import seed_bodies
from parmpm.progress import Progress
from parmpm.run_files import RunFiles, agree
from parmpm.schedule import Schedule
from parmpm.shapes import CPDI, INTERPOLATORS
from parmpm.reach import fmt_vec
from parmpm.discretisation import Discretisation, exterior_cells
from parmpm.stepper import Stepper
from parmpm.transfer import max_speed

log = get_logger(__name__)


class Simulation(Measures):
    """One run of a resolved scene on this process's patches (``comm``: an mpi4py communicator;
    None runs every patch here)."""

    def __init__(self, scene, out_dir=None, quiet: bool = False, comm=None, checkpoint=None,
                 overwrite: bool = False):
        self.scene = scene
        self.data = data = scene.data
        # an explicit folder is used or refused; the default one is never taken from another run
        # (parmpm.io.run_folder)
        self.out_explicit = out_dir is not None
        self.out_dir = Path(out_dir) if out_dir else Path("parmpm-out") / scene.name
        self.overwrite = overwrite
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
        self._check_memory(int(ghost))  # before anything of the scene's size is allocated
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
        else:
            P = load_particles(comm, checkpoint, d, self.n_total, self.params.shape[0], mine)
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
        self.out_schedule: Schedule | None = None
        self.last_checkpoint: tuple[int, Path | None] = (-1, None)
        # callables f(simulation), run (collectively) at every output time after the snapshot:
        # how studies look at the state without files
        self.observers: list = []
        limit = data["time"]["max_energy_growth"]
        limit = None if limit == "off" else limit
        self.energy = EnergyWatch(None if self.stepper.forcing is not None else limit)
        # the run's identity: its folder's marker and its checkpoints carry it, so that pruning
        # touches only its own checkpoints (parmpm.io.run_folder); a restart is a run of its own
        self.run_id = comm.bcast(uuid.uuid4().hex if self.rank == 0 else None, root=0)
        self.continues = None  # the run a restart continues: (its run id, the checkpoint)
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
            self.energy.restore(state.get("energy"))
            self.continues = {"run_id": (state.get("run") or {}).get("id"),
                              "checkpoint": str(checkpoint.path)}

    def _check_memory(self, ghost: int) -> None:
        """Refuse, on every rank, a scene this node's ranks cannot hold (:mod:`parmpm.footprint`)."""
        problem = None
        try:
            check_memory(self.data, ghost, self.size, ranks_on_this_node(self.comm))
        except ParmpmError as exc:
            problem = str(exc)
        problems = [p for p in self.comm.allgather(problem) if p]
        if problems:
            raise ParmpmError(problems[0])

    def _manufactured(self, A: float) -> None:
        """Drive the run with the manufactured solution's body force (:mod:`parmpm.manufactured`)."""
        from parmpm.manufactured import body_force, frequency
        from parmpm.materials import PARAM

        c, row = frequency(self.params), self.params[0]
        lam, mu, rho = row[PARAM["lam"]], row[PARAM["mu"]], row[PARAM["density"]]
        d = self.dim
        self.stepper.forcing = lambda t, P, out: body_force(d, P.x0, t, A, c, lam, mu, rho, out)

    @classmethod
    def from_checkpoint(cls, path, overrides=(), out_dir=None, quiet=False, comm=None,
                        overwrite=False):
        """Continue the run saved in ``path`` (on any number of ranks); ``overrides`` apply to
        the stored scene (e.g. ``time.end=...``)."""
        from parmpm.io.checkpoint import CheckpointReader
        from parmpm.scene import scene_from_toml

        reader = CheckpointReader(path, warn=comm is None or comm.Get_rank() == 0)
        try:
            scene = scene_from_toml(str(reader.attrs["scene"]), f"{path}", overrides)
            if scene.data["dim"] != int(reader.attrs["dim"]):
                raise ParmpmError(f"checkpoint '{path}' holds a {int(reader.attrs['dim'])}D run; "
                                  f"dim cannot change on restart (got dim = {scene.data['dim']})")
            sim = cls(scene, out_dir, quiet=quiet, comm=comm, checkpoint=reader,
                      overwrite=overwrite)
        finally:
            reader.close()
        if out_dir is None:  # never over earlier output: a folder of its own beside the file
            sim.out_dir = Path(path).parent / f"restart_{sim.nstep:08d}"
        return sim

    # --- clock --------------------------------------------------------------------------------
    def next_dt(self) -> float:
        """The CFL step, capped by ``time.dt_max`` and the end time; ``dt_limit`` names the key
        that set it, so that a blow-up can say which one to lower."""
        tm = self.data["time"]
        dt = tm["cfl"] * float(self.disc.h.min()) / self.vmax
        self.dt_limit = "time.cfl"
        if tm["dt_max"] and tm["dt_max"] < dt:
            dt, self.dt_limit = tm["dt_max"], "time.dt_max"
        if tm["end"] is not None:
            dt = min(dt, tm["end"] - self.t)
        return dt

    def _unstable_hint(self) -> str:
        tm = self.data["time"]
        if getattr(self, "dt_limit", "time.cfl") == "time.dt_max":
            return (f"Δt = {self.last_dt:.3g} s was set by time.dt_max, below the CFL step: try a "
                    f"smaller time.dt_max (now {tm['dt_max']:.3g} s)")
        return f"try a smaller time.cfl (now {tm['cfl']:g})"

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

    def output(self) -> None:
        """An output time: the snapshot (if enabled), then every observer (collective)."""
        self.snapshot()
        for observe in self.observers:
            observe(self)

    def snapshot(self) -> None:
        if not self.data["output"]["snapshots"]:
            return
        P = self.particles
        g = self.gather({"x": P.x, "velocity": P.v, "stress": P.stress.reshape(P.n, self.dim * self.dim),
                         "stretch": self.axial_stretch(), "damage": P.damage,
                         "rank": np.full(P.n, float(self.rank)), "gid": P.gid.astype(float)})
        self.files.write_snapshot(self.t, g)

    def write_checkpoint(self) -> Path:
        """Write ``checkpoint_<step>.h5`` (collective, atomic; :mod:`parmpm.checkpointing`)."""
        import json

        from parmpm.io.checkpoint import checkpoint_name

        state = {"metrics": self.metrics.state() if self.metrics is not None else None,
                 "next_output": self.out_schedule.next_time if self.out_schedule else None,
                 "energy": self.energy.state(),
                 "run": {"id": self.run_id}}
        attrs = {"scene": self.scene.to_toml(), "step": self.nstep, "time": self.t,
                 "dt": self.last_dt, "vmax": self.vmax, "method": self.interp.name,
                 "lcr": self.lcr if self.lcr is not None else float("nan"), "ranks": self.size,
                 "particles": self.n_total, "dim": self.dim, "state": json.dumps(state),
                 "lineage": self.run_id}
        path = write_checkpoint(self.comm, self.particles, self.out_dir / checkpoint_name(self.nstep),
                                self.n_total, attrs, self.data["checkpoint"]["keep"], self.run_id)
        self.last_checkpoint = (self.nstep, path)
        log.info("wrote %s (step %d, t = %.6g s)", path, self.nstep, self.t)
        return path

    # --- checks ------------------------------------------------------------------------------
    def check_energy(self) -> None:
        """The blow-up watch (collective, :mod:`parmpm.energy`): stop when the energy balance
        has grown past ``time.max_energy_growth``."""
        totals = energy_totals(self.comm, self.patches.local_ids, self.particles, self.params,
                               self.gravity(self.t))
        growth = self.energy.sample(totals)
        if growth is not None:
            k, psi, work = self.energy.last
            raise SimulationError(
                f"the run is unstable: at step {self.nstep} (t = {self.t:.6g} s) the body holds "
                f"{k + psi:.4g} J (kinetic {k:.3g} J, elastic {psi:.3g} J) but was given "
                f"{self.energy.initial + work:.4g} J (a growth of {growth:.3g} times that; "
                f"time.max_energy_growth = {self.energy.limit:g}); {self._unstable_hint()}")

    def _stop_agreed(self) -> bool:
        """Whether any rank got SIGTERM/SIGINT (collective; outside the step loop)."""
        flag = np.array([1.0 if self.stepper.stop_flag else 0.0])
        return bool(allreduce_max(self.comm, flag)[0] > 0)

    def _interrupted(self) -> RunInterrupted:
        """A stop signal was agreed: the final checkpoint (unless this step has one), then the
        exception that ends the run with exit code 130."""
        path = self.last_checkpoint[1] if self.last_checkpoint[0] == self.nstep else self.write_checkpoint()
        return RunInterrupted(f"interrupted at step {self.nstep} (t = {self.t:.6g} s); "
                              f"continue with: parmpm restart {path}")

    # --- signals ------------------------------------------------------------------------------
    def _trap_signals(self):
        """SIGTERM/SIGINT (a batch system's time limit, Ctrl-C) only raise a flag from here to the
        end of :meth:`run`; the ranks agree on it at the end of a step (or at the next collective
        check after the loop), write a checkpoint and stop together."""
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
        shared files (summary.json, snapshots, figure) into the folder the run claims first."""
        old_handlers = self._trap_signals()
        try:
            name = self.data["name"]
            series = name if self.restart is None else f"{name}_from_{self.nstep:08d}"
            self.files = RunFiles(self.comm, self.out_dir, self.out_explicit, self.overwrite)
            self.out_dir = self.files.claim({
                "run_id": self.run_id, "continues": self.continues, "scene": name,
                "ranks": self.size,
                "files": ["summary.json", f"{series}.xdmf", f"{series}.h5", f"{name}.png"]})
            if self.data["output"]["snapshots"]:
                self.files.open_snapshots(series, self.dim)
            return self._run()
        finally:
            self._restore_signals(old_handlers)

    def _run(self) -> dict:
        data = self.data
        out = data["output"]
        self.out_schedule = Schedule(out["every"], out["every_steps"], self.t, self.next_out)
        ck = data["checkpoint"]
        ck_schedule = Schedule(ck["every"], ck["every_steps"], self.t)
        self.last_checkpoint = (-1, None)
        ck_wall = time.monotonic()
        me = data["metrics"]["every_steps"]
        stop_on_sep = data["metrics"]["stop_on_separation"]
        self.stopped = None
        progress = Progress(total_steps=data["time"]["steps"], end_time=data["time"]["end"],
                            enabled=not self.quiet and self.rank == 0)
        wall0 = time.perf_counter()
        warm_wall, warm_steps = None, 0
        try:
            if self.restart is None:  # a restarted run has these from before
                self.sample_metrics()
                self.output()
                self.check_energy()
            while not self.done():
                dt = self.next_dt()
                self.vmax = self.stepper.step(dt, self.gravity(self.t), self.t)
                self.t += dt
                self.nstep += 1
                self.last_dt = dt
                if not math.isfinite(self.vmax):
                    raise SimulationError(f"non-finite velocity or stress at step {self.nstep} "
                                          f"(t = {self.t:.6g} s); {self._unstable_hint()}")
                if warm_wall is None:
                    warm_wall = time.perf_counter()  # the first step includes JIT compilation
                    self.stepper.timers = dict.fromkeys(self.stepper.timers, 0.0)
                else:
                    warm_steps += 1
                if self.nstep % ENERGY_EVERY == 0:
                    self.check_energy()
                if self.nstep % me == 0 and self.sample_metrics() > 1 and stop_on_sep:
                    self.stopped = "separated"
                    log.info("material separated at t = %.6g s: stopping (metrics.stop_on_separation)", self.t)
                    self.output()
                    break
                if self.out_schedule.due(self.t, self.nstep) or self.done():
                    self.output()
                    self.out_schedule.advance(self.t)
                if self.stepper.stop_requested:
                    raise self._interrupted()
                ck_due = ck_schedule.due(self.t, self.nstep) or (ck["at_end"] and self.done())
                if ck["wall_minutes"]:
                    waited = allreduce_max(self.comm, np.array([time.monotonic() - ck_wall]))[0]
                    ck_due = ck_due or waited >= 60.0 * ck["wall_minutes"]
                if ck_due:
                    self.write_checkpoint()
                    ck_wall = time.monotonic()
                    ck_schedule.advance(self.t)
                elapsed = time.perf_counter() - (warm_wall or wall0)
                rate = self.n_total * warm_steps / elapsed if warm_steps and elapsed > 0 else 0.0
                progress.update(self.nstep, self.t, rate)
            if self.nstep % ENERGY_EVERY:
                self.check_energy()
            if ck["at_end"] and self.last_checkpoint[0] != self.nstep:
                self.write_checkpoint()  # also when the run stopped early (separation)
            if self._stop_agreed():
                raise self._interrupted()
        finally:
            progress.close()
            closing = self.files.close_snapshots()  # never raises: a failing run's error wins
        agree(self.comm, closing)
        self.next_out = self.out_schedule.next_time
        wall = time.perf_counter() - wall0
        loop = time.perf_counter() - warm_wall if warm_wall else wall
        wall, loop = (float(v) for v in allreduce_max(self.comm, np.array([wall, loop])))
        summary = self.summary(wall, loop, warm_steps)
        self.files.write_summary(summary)
        if self._stop_agreed():  # a signal while the summary was made: no figure
            raise self._interrupted()
        if out["figure"]:
            P = self.particles
            corners = self.domain_corners()
            fields = {"x": P.x, "stretch": self.axial_stretch()}
            if corners is not None:
                fields["corners"] = corners
            self.files.write_figure(data["name"], self.gather(fields), self.dim,
                                    f"{data['name']} · {self.interp.name} · t = {self.t:.3g} s")
        if self._stop_agreed():  # a signal while the figure was drawn
            raise self._interrupted()
        return summary
