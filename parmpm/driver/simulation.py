"""The run loop: owns time (Δt from CFL, stop criteria), not physics.

``Simulation(scene, out_dir, comm=comm).run()`` sets up this rank's state (particles, patches,
stepper, clock: :mod:`parmpm.driver.set_up`), claims the output folder, steps until ``time.end`` or
``time.steps`` and after every step asks its callbacks (:mod:`parmpm.driver.callbacks`: the NaN check,
the energy watch, metrics, the separation stop, snapshots, stop signals, checkpoints) whether
they are due; then it writes ``summary.json`` and a figure and returns the summary. The folder
also gets the resolved scene (``scene.toml``, a scene file that runs the same again) before the
first step, and ``summary.json`` is written too when a signal stops the run (``"stopped":
"interrupted"``, with the checkpoint to continue from). Under MPI, rank 0 compiles the kernels
(two ranks at once) and the others load them when the caller passes ``warm_up=compile_first``
(:func:`parmpm.driver.warm_up.compile_first`: the run itself knows nothing of compiling). Every rank
runs the same loop with the same global Δt; every figure in the summary is reduced over all
ranks (:mod:`parmpm.driver.measures`) and only rank 0 writes files.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from decomposition import SerialComm, allreduce_max
from parmpm.driver import measures
from parmpm.driver.callbacks import Checkpoints, interrupted, standard_callbacks, stop_agreed, stop_signals
from parmpm.core.collective import agree
from parmpm.driver.compile_clock import CompileClock
from parmpm.core.errors import RunInterrupted
from parmpm.io.summary import run_info
from parmpm.core.log import get_logger
from parmpm.driver.progress import Progress
from parmpm.driver.restart import open_checkpoint
from parmpm.driver.set_up import RankState, set_up
from parmpm.driver.run_files import RunFiles, run_inputs

log = get_logger(__name__)


class Simulation:
    """One run of a resolved scene on this process's patches (``comm``: an mpi4py communicator;
    None runs every patch here). ``observers``: callables ``f(simulation)`` run (collectively)
    at every output time after the snapshot, how studies look at the state without files;
    ``callbacks``: more :class:`parmpm.driver.callbacks.Callback`, run after the scene's own."""

    def __init__(self, scene, out_dir=None, quiet: bool = False, comm=None, checkpoint=None,
                 overwrite: bool = False, warm_up=None):
        # an explicit folder is used or refused; the default one is never taken from another run
        # (parmpm.io.run_folder)
        self.out_explicit = out_dir is not None
        self.out_dir = Path(out_dir) if out_dir else Path("parmpm-out") / scene.name
        self.overwrite, self.quiet = overwrite, quiet
        if warm_up is not None and comm is not None:  # e.g. rank 0 compiles, the others load
            warm_up(scene, comm)
        self.state: RankState = set_up(scene, comm if comm is not None else SerialComm(),
                                       checkpoint)
        self.observers: list = []
        self.callbacks: list = []
        self.checkpoints = Checkpoints()
        self.out_schedule = None  # the output schedule, once the run has begun
        self.stopped = None       # why the run stopped before its end ("separated")
        self.pieces = 1           # pieces of material at the last metrics sample
        self.files = None
        self.summary = None       # the summary, once written

    @classmethod
    def from_checkpoint(cls, path, overrides=(), out_dir=None, quiet=False, comm=None,
                        overwrite=False, warm_up=None):
        """Continue the run saved in ``path`` (on any number of ranks); ``overrides`` apply to
        the stored scene (e.g. ``time.end=...``)."""
        scene, reader = open_checkpoint(path, overrides, comm)
        try:
            sim = cls(scene, out_dir, quiet=quiet, comm=comm, checkpoint=reader,
                      overwrite=overwrite, warm_up=warm_up)
        finally:
            reader.close()
        if out_dir is None:  # never over earlier output: a folder of its own beside the file
            sim.out_dir = Path(path).parent / f"restart_{sim.nstep:08d}"
        return sim

    # What observers and studies read most: the rest is ``sim.state`` (the rank's state:
    # particles, patches, stepper, energy, metrics...) and ``sim.state.clock`` (Δt, the CFL limit).
    particles = property(lambda self: self.state.particles, doc="this rank's particles")
    t = property(lambda self: self.state.clock.t, doc="the time reached (s)")
    nstep = property(lambda self: self.state.clock.nstep, doc="the steps taken")
    dim = property(lambda self: self.state.dim, doc="the scene's dimension")
    comm = property(lambda self: self.state.comm, doc="the communicator the run is on")
    spec = property(lambda self: self.state.spec, doc="the scene's records (scene.spec)")

    # --- the clock and the load ---------------------------------------------------------------
    def next_dt(self) -> float:
        """The CFL step, capped by ``time.dt_max`` and the end time (:class:`parmpm.driver.schedule.Clock`)."""
        return self.state.clock.next_dt()

    def done(self) -> bool:
        return self.state.clock.done()

    def gravity(self, t: float) -> np.ndarray:
        """Gravity at time ``t`` (ramped over ``gravity.ramp_time``), padded to 3 components."""
        g = self.spec.gravity
        ramp = g.ramp_time
        f = min(1.0, t / ramp) if ramp > 0 else 1.0
        return np.concatenate([np.asarray(g.g, float) * f, np.zeros(3 - self.dim)])

    # --- measurements (parmpm.driver.measures) -------------------------------------------------------
    def gather(self, fields: dict[str, np.ndarray]) -> dict[str, np.ndarray] | None:
        """All particles' ``fields`` in global-id order on rank 0 (None elsewhere). Output only."""
        return measures.gather(self.state, fields)

    def sample_metrics(self) -> int:
        return measures.sample_metrics(self.state)

    def totals(self) -> dict:
        return measures.totals(self.state)

    def axial_stretch(self) -> np.ndarray:
        return measures.axial_stretch(self.state)

    def domain_corners(self) -> np.ndarray | None:
        return measures.domain_corners(self.state)

    def write_checkpoint(self) -> Path:
        """Write ``checkpoint_<step>.h5`` now (collective, atomic)."""
        return self.checkpoints.write_for(self)

    # --- the loop -----------------------------------------------------------------------------
    def run(self) -> dict:
        """Step to the end (collective). Every rank returns the same summary; rank 0 writes the
        shared files (summary.json, snapshots, figure) into the folder the run claims first."""
        with stop_signals(self.state.stepper):
            s = self.state
            name = self.spec.name
            series = name if not s.restart else f"{name}_from_{self.nstep:08d}"
            # what the run reads (its scene file, its bodies' files, a restart's checkpoint):
            # claiming the folder never deletes or replaces it
            self.files = RunFiles(self.comm, self.out_dir, self.out_explicit, self.overwrite,
                                  inputs=run_inputs(s.scene, s.continues))
            try:  # the claim (rank 0's lock: the run is alive) is held until the run is over
                self.out_dir = self.files.claim({
                    "run_id": s.run_id, "continues": s.continues, "scene": name,
                    "ranks": self.state.size,
                    "files": ["scene.toml", "summary.json", f"{series}.xdmf", f"{series}.h5",
                              f"{name}.png", "history.csv", "history.h5", "history.png"]})
                self.files.write_scene(s.scene.to_toml())  # what ran, as a scene file
                if self.spec.output.snapshots:
                    # the snapshots' writer groups follow the checkpoints'
                    self.files.open_snapshots(series, self.dim,
                                              self.spec.checkpoint.ranks_per_file,
                                              plastic=s.stepper.plastic is not None)
                return self._run()
            finally:
                self.files.release()

    def _run(self) -> dict:
        # numba's compilations meanwhile (one rank compiles where a kernel is first called) are
        # left out of the wall time and the rate and reported apart (parmpm.driver.compile_clock)
        self._compiling, self._compile_warm, self._compile_loop = CompileClock(), 0.0, None
        with self._compiling.listen():
            return self._run_timed()

    def _run_timed(self) -> dict:
        callbacks = standard_callbacks(self) + self.callbacks
        self.checkpoints = Checkpoints()
        self.stopped, self.summary = None, None
        self._warm_wall, self._warm_steps, self._loop_wall = None, 0, None
        tm = self.spec.time
        progress = Progress(total_steps=tm.steps, end_time=tm.end,
                            enabled=not self.quiet and self.state.rank == 0)
        self._wall0 = time.perf_counter()
        try:
            try:
                if not self.state.restart:  # a restarted run has these from before
                    for cb in sorted((c for c in callbacks if c.start is not None),
                                     key=lambda c: c.start):
                        cb.action(self)
                self._loop(callbacks, progress)
                self._loop_wall = time.perf_counter()  # the rate leaves out the end's outputs
                self._compile_loop = self._compiling.seconds
                for cb in callbacks:
                    if cb.at_end is not None and cb.at_end(cb, self):
                        cb.action(self)
                if stop_agreed(self):
                    raise interrupted(self)
            finally:
                progress.close()
                closing = self.files.close_snapshots()  # never raises: a failing run's error wins
            agree(self.comm, closing)
            self.state.next_output = self.out_schedule.next_time
            return self._finish()
        except RunInterrupted:
            if self.summary is None:
                self._summary_of_interrupted_run()
            raise

    def _loop(self, callbacks: list, progress: Progress) -> None:
        """Step until the clock is done or a callback stops the run; keeps the wall clock after
        the first step (which includes JIT compilation) and the steps after it."""
        clock, stepper = self.state.clock, self.state.stepper
        while not clock.done():
            dt = clock.next_dt()
            vmax = stepper.step(dt, self.gravity(clock.t), clock.t)
            clock.tick(dt, vmax, stepper.speed_measured)
            if self._warm_wall is None:
                self._warm_wall = time.perf_counter()  # the first step includes JIT compilation
                self._compile_warm = self._compiling.seconds
                stepper.timers = dict.fromkeys(stepper.timers, 0.0)
            else:
                self._warm_steps += 1
            for cb in callbacks:
                if cb.schedule.due(clock.t, clock.nstep):
                    self.stopped = cb.action(self)
                    if self.stopped:
                        return
                    cb.schedule.advance(clock.t)
            warm_steps = self._warm_steps
            elapsed = time.perf_counter() - (self._warm_wall or self._wall0)
            elapsed -= self._compiling.seconds - self._compile_warm  # kernels met mid-run
            rate = self.state.n_total * warm_steps / elapsed if warm_steps and elapsed > 0 else 0.0
            progress.update(clock.nstep, clock.t, rate)

    def _write_summary(self) -> dict:
        """The summary of the run so far, written to summary.json (collective)."""
        now = time.perf_counter()
        wall = now - self._wall0
        loop = (self._loop_wall or now) - self._warm_wall if self._warm_wall else wall
        compiled = self._compiling.seconds  # left out of both, reported apart
        in_loop = ((self._compile_loop if self._compile_loop is not None else compiled)
                   - self._compile_warm) if self._warm_wall else compiled
        wall, loop, compiled, in_loop = (
            float(v) for v in allreduce_max(self.comm, np.array([wall, loop, compiled, in_loop])))
        summary = measures.summary(self.state, self.out_dir, self.stopped, wall - compiled,
                                   loop - in_loop, self._warm_steps)
        summary["compile_seconds"] = compiled
        summary.update(run_info(self.state.size))
        if self.stopped == "interrupted":
            summary["checkpoint"] = str(self.checkpoints.last_path)
        self.files.write_summary(summary)
        self.summary = summary
        return summary

    def _summary_of_interrupted_run(self) -> None:
        """summary.json of a run a signal stopped (its checkpoint is written; the ranks agreed,
        so this is collective). A failure here is a warning: the interrupt and its restart line
        must reach the user all the same."""
        self.stopped = "interrupted"
        try:
            self._write_summary()
        except Exception as exc:  # noqa: BLE001 (any failure: the interrupt wins)
            log.warning("summary.json of the interrupted run not written: %s",
                        " ".join(str(exc).split()) or type(exc).__name__)

    def _finish(self) -> dict:
        """The summary (written), then the figure; a stop signal meanwhile still checkpoints."""
        summary = self._write_summary()
        if stop_agreed(self):  # a signal while the summary was made: no figure
            raise interrupted(self)
        if self.spec.output.figure:
            P = self.particles
            corners = self.domain_corners()
            fields = {"x": P.x, "stretch": self.axial_stretch()}
            if corners is not None:
                fields["corners"] = corners
            name = self.spec.name
            self.files.write_figure(name, self.gather(fields), self.dim,
                                    f"{name} · {self.state.interp.name} · t = {self.t:.3g} s")
        if stop_agreed(self):  # a signal while the figure was drawn
            raise interrupted(self)
        return summary
