"""What a run does between its steps: actions on a schedule, driven by one loop.

A :class:`Callback` is an action on the run (a :class:`parmpm.driver.simulation.Simulation`) and a
schedule (:mod:`parmpm.driver.schedule`) that says after which steps it runs. The loop asks every
callback, in order, at the end of every step; an action may return a reason to stop the run
(``"separated"``), or raise to end it. Every action is collective: every rank runs the same
callbacks at the same steps. :func:`standard_callbacks` gives the scene's set, in this order:

    finite       every step      a non-finite speed or stress ends the run (NaN check)
    energy       every 10 steps  the blow-up watch (parmpm.output.energy)
    history      output.history  a row of history.csv (parmpm.output.history); at the end its table
                                 in the run's HDF5 and history.png
    metrics      metrics.every_steps   a sample of the scene's metrics
    separation   metrics.every_steps   stop when the material has separated (if asked)
    output       output.every / every_steps, last step   snapshot, then the observers
    interrupt    every step      a stop signal (TERM, INT, HUP), agreed at the end of the step:
                                 checkpoint, stop
    checkpoint   checkpoint.every / every_steps / wall_minutes / at_end

A new output (a history writer, say) is one more callback: in this list for every run, or
appended to a run's own ``Simulation.callbacks`` (run after these), e.g.
``Callback("history", write_row, Schedule(every_steps=10), start=3)``.
"""
from __future__ import annotations

import json
import math
import signal
import threading
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from decomposition import allreduce_max
from parmpm.output.energy import ENERGY_EVERY, energy_totals
from parmpm.core.errors import RunInterrupted, SimulationError
from parmpm.output.history import HistoryOutput
from parmpm.io.checkpoint import checkpoint_name
from parmpm.driver.checkpoint_writer import write_checkpoint
from parmpm.core.log import get_logger
from parmpm.driver.measures import sample_metrics
from parmpm.driver.schedule import AnyOf, AtEnd, Schedule, WallTime
from parmpm.driver.signals import is_hangup, silence_hung_up_terminal, to_handle
from parmpm.driver.snapshot_fields import snapshot_fields

log = get_logger(__name__)


@dataclass
class Callback:
    """``action(sim)`` after every step ``schedule`` names (collective). ``start``: its place
    among the actions on a fresh run's initial state (None: not run there); ``at_end(callback,
    sim)``: whether it runs once more after the last step (None: never)."""

    name: str
    action: Callable
    schedule: object
    start: int | None = None
    at_end: Callable | None = None


class _Never:
    """A schedule that names no step (for actions that run only at the end)."""

    def due(self, t: float, nstep: int) -> bool:
        return False

    def advance(self, t: float) -> None:
        pass


NEVER = _Never()


def unless_due(callback: Callback, sim) -> bool:
    """At the end unless the schedule named the last step (the last state is always seen)."""
    return not callback.schedule.due(sim.t, sim.nstep)


def unless_written(callback: Callback, sim) -> bool:
    """At the end unless this step has a checkpoint already."""
    return sim.checkpoints.last_step != sim.nstep


def standard_callbacks(sim) -> list[Callback]:
    """The callbacks a scene asks for (see the module doc), with their schedules set from the
    run's clock (and, on restart, the checkpointed output schedule)."""
    spec, clock = sim.spec, sim.state.clock
    out, ck, me = spec.output, spec.checkpoint, spec.metrics
    every_step = Schedule(every_steps=1)
    sim.out_schedule = Schedule(out.every, out.every_steps, clock.t, sim.state.next_output)
    ck_schedule = [Schedule(ck.every, ck.every_steps, clock.t)]
    if ck.at_end:
        ck_schedule.append(AtEnd(clock))
    if ck.wall_minutes:
        ck_schedule.append(WallTime(ck.wall_minutes, sim.comm))
    # on a fresh run's initial state: metrics, output, then the energy watch's baseline (after
    # the observers, which may look at the state); after a step the watch comes first, so that
    # a blow-up stops the run before its state is sampled or written
    callbacks = [
        Callback("finite", check_finite, every_step),
        Callback("energy", check_energy, Schedule(every_steps=ENERGY_EVERY), start=2,
                 at_end=unless_due)]
    hist = out.history
    if hist.enabled:  # after the watch: a blown-up state is not sampled
        sim.history = HistoryOutput(sim)
        sim.state.stepper.ledger = sim.state.energy.ledger
        callbacks += [
            Callback("history", lambda sim: sim.history.sample(sim),
                     Schedule(hist.every, hist.every_steps, clock.t), start=3,
                     at_end=lambda cb, sim: True),
            Callback("history files", lambda sim: sim.history.finish(sim), NEVER,
                     at_end=lambda cb, sim: True)]
    callbacks += [
        Callback("metrics", sample_metrics_of, Schedule(every_steps=me.every_steps), start=0)]
    if me.stop_on_separation:
        callbacks.append(Callback("separation", stop_on_separation,
                                  Schedule(every_steps=me.every_steps)))
    return callbacks + [
        Callback("output", output, AnyOf(sim.out_schedule, AtEnd(clock)), start=1),
        Callback("interrupt", check_interrupt, every_step),
        # at the end also when the run stopped early (separation), unless this step has one
        Callback("checkpoint", checkpoint, AnyOf(*ck_schedule),
                 at_end=unless_written if ck.at_end else None)]


# --- the actions --------------------------------------------------------------------------------
def check_finite(sim) -> None:
    if not math.isfinite(sim.state.clock.vmax):
        raise SimulationError(f"non-finite velocity or stress at step {sim.nstep} "
                              f"(t = {sim.t:.6g} s); {sim.state.clock.unstable_hint()}")


def check_energy(sim) -> None:
    """The blow-up watch (:mod:`parmpm.output.energy`): stop when the energy balance has grown past
    ``time.max_energy_growth``."""
    s = sim.state
    totals = energy_totals(s.comm, s.patches.local_ids, s.particles, s.params, sim.gravity(sim.t),
                           s.stepper.plastic)
    growth = s.energy.sample(totals)
    if growth is not None:
        k, psi, work = s.energy.last
        raise SimulationError(
            f"the run is unstable: at step {sim.nstep} (t = {sim.t:.6g} s) the body holds "
            f"{k + psi:.4g} J (kinetic {k:.3g} J, elastic {psi:.3g} J) but was given "
            f"{s.energy.initial + work:.4g} J (a growth of {growth:.3g} times that; "
            f"time.max_energy_growth = {s.energy.limit:g}); {sim.state.clock.unstable_hint()}")


def sample_metrics_of(sim) -> None:
    """A sample of the scene's metrics; the pieces of material counted are kept for the
    separation stop."""
    sim.pieces = sample_metrics(sim.state)


def stop_on_separation(sim) -> str | None:
    """The material separated (``metrics.stop_on_separation``): a last output, then stop."""
    if sim.pieces > 1:
        log.info("material separated at t = %.6g s: stopping (metrics.stop_on_separation)", sim.t)
        output(sim)
        return "separated"
    return None


def output(sim) -> None:
    """An output time: the snapshot (if enabled), then every observer."""
    if sim.spec.output.snapshots:
        sim.files.write_snapshot(sim.t, snapshot_fields(sim))
    for observe in sim.observers:
        observe(sim)


def checkpoint(sim) -> None:
    sim.checkpoints.write_for(sim)


def check_interrupt(sim) -> None:
    """Some rank got a stop signal (agreed at the end of the step): checkpoint, stop."""
    if sim.state.stepper.stop_requested:
        raise interrupted(sim)


# --- checkpoints and stop signals ---------------------------------------------------------------
class Checkpoints:
    """The run's checkpoints: what goes into one (the particles, the scene, the clock and the
    state a restart needs to continue bit for bit), and the last one written."""

    def __init__(self):
        self.last_step, self.last_path = -1, None

    def write_for(self, sim) -> Path:
        """Write ``checkpoint_<step>.h5`` (collective, atomic; :mod:`parmpm.driver.checkpoint_writer`)."""
        s, clock = sim.state, sim.state.clock
        state = {"metrics": s.metrics.state() if s.metrics is not None else None,
                 "next_output": sim.out_schedule.next_time if sim.out_schedule else None,
                 "energy": s.energy.state(),
                 "run": {"id": s.run_id},
                 "bodies": s.body_records}
        attrs = {"scene": s.scene.to_toml(), "step": clock.nstep, "time": clock.t,
                 "dt": clock.last_dt, "vmax": clock.vmax, "method": s.interp.name,
                 "lcr": s.lcr if s.lcr is not None else float("nan"), "ranks": s.size,
                 "particles": s.n_total, "dim": s.dim, "state": json.dumps(state),
                 "lineage": s.run_id}
        ck = sim.spec.checkpoint
        path = write_checkpoint(s.comm, s.particles, sim.out_dir / checkpoint_name(clock.nstep),
                                s.n_total, attrs, ck.keep, s.run_id, s.disc, ck.ranks_per_file)
        self.last_step, self.last_path = clock.nstep, path
        log.info("wrote %s (step %d, t = %.6g s)", path, clock.nstep, clock.t)
        return path


def stop_agreed(sim) -> bool:
    """Whether any rank got a stop signal (collective; outside the step loop)."""
    flag = np.array([1.0 if sim.state.stepper.stop_flag else 0.0])
    return bool(allreduce_max(sim.comm, flag)[0] > 0)


def interrupted(sim) -> RunInterrupted:
    """A stop signal was agreed: the final checkpoint (unless this step has one), then the
    exception that ends the run with exit code 130."""
    ck = sim.checkpoints
    path = ck.last_path if ck.last_step == sim.nstep else ck.write_for(sim)
    return RunInterrupted(f"interrupted at step {sim.nstep} (t = {sim.t:.6g} s); "
                          f"continue with: parmpm restart {path}")


@contextmanager
def stop_signals(stepper):
    """SIGTERM/SIGINT/SIGHUP (a batch system's time limit, Ctrl-C, a closed terminal or dropped
    ssh session: :mod:`parmpm.driver.signals`) only raise the stepper's flag while the run is inside;
    the ranks agree on it at the end of a step (or at the next collective check after the
    loop), write a checkpoint and stop together. A hang-up also points the streams that were
    the dead terminal at /dev/null, so that no later write fails. Outside, the CLI's own handler
    applies (:mod:`parmpm.__main__`)."""
    old = None
    if threading.current_thread() is threading.main_thread():
        def flag(signum, frame):
            if is_hangup(signum):
                silence_hung_up_terminal()
            stepper.stop_flag = True

        old = {sig: signal.signal(sig, flag) for sig in to_handle()}
    try:
        yield
    finally:
        for sig, handler in (old or {}).items():
            signal.signal(sig, handler)
