"""A fixed time step (``time.dt``, :class:`parmpm.driver.schedule.Clock`): every step that long,
the last one shortened to end on ``time.end``; one warning when it is longer than the CFL step;
its keys checked to one line."""
from __future__ import annotations

import logging
import math
from types import SimpleNamespace

import numpy as np
import pytest

import parmpm
from parmpm.core.errors import SceneError
from parmpm.driver.schedule import Clock
from parmpm.driver.simulation import Simulation


def _time(**kw):
    base = dict(cfl=0.5, dt_max=None, dt=None, end=None, steps=None)
    base.update(kw)
    return SimpleNamespace(**base)


def _steps(clock: Clock, vmax: float) -> list[float]:
    taken = []
    while not clock.done():
        dt = clock.next_dt()
        taken.append(dt)
        clock.tick(dt, vmax)
    return taken


def test_every_step_is_time_dt_and_the_last_ends_on_time_end():
    clock = Clock(_time(dt=0.4, end=1.0), h_min=1.0, vmax=0.01)  # CFL step 50: far longer
    taken = _steps(clock, 0.01)
    assert taken[:2] == [0.4, 0.4] and math.isclose(taken[2], 0.2, rel_tol=1e-12)
    assert clock.t == 1.0 and clock.nstep == 3 and clock.dt_limit == "time.dt"
    assert "time.dt" in clock.unstable_hint()


def test_without_time_dt_the_cfl_step_is_unchanged():
    clock = Clock(_time(end=1.0), h_min=1.0, vmax=10.0)
    assert clock.next_dt() == 0.5 * 1.0 / 10.0 and clock.dt_limit == "time.cfl"


def test_a_step_longer_than_the_cfl_step_is_one_warning(caplog):
    clock = Clock(_time(dt=0.1, steps=5), h_min=1.0, vmax=1.0)  # CFL step 0.5: fine at first
    with caplog.at_level(logging.WARNING, logger="parmpm"):
        clock.next_dt()
        assert not caplog.records
        clock.tick(0.1, 100.0)  # now the CFL step is 0.005
        for _ in range(3):
            assert clock.next_dt() == 0.1
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1 and "time.dt = 0.1 s is longer than the CFL step" in lines[0]
    assert "0.005 s) at step 1" in lines[0]
    quiet = Clock(_time(dt=0.1, steps=5), h_min=1.0, vmax=100.0, speaks=False)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="parmpm"):
        quiet.next_dt()
    assert not caplog.records  # another rank: rank 0 says it


@pytest.mark.parametrize("value, message", [
    ("0", "time.dt: expected a number > 0 (s)"),
    ("-1e-5", "time.dt: expected a number > 0 (s)"),
    ("nan", "time.dt: expected a number > 0 (s)"),
    ("inf", "time.dt: expected a number > 0 (s)"),
    ('"1e-5"', "time.dt: expected a number > 0 (s)"),
    ("true", "time.dt: expected a number > 0 (s)"),
    ("1e-30", "would take 3e+29 steps to reach time.end = 0.3 s (more than 1e+09)"),
])
def test_a_bad_time_dt_is_one_line(value, message):
    with pytest.raises(SceneError) as info:
        parmpm.load_scene("hanging_bar", [f"time.dt={value}"])
    text = str(info.value)
    assert message in text and "\n" not in text, text


def test_time_dt_and_dt_max_together_are_one_line():
    with pytest.raises(SceneError, match="time.dt: expected time.dt .* or time.dt_max .*not both"):
        parmpm.load_scene("hanging_bar", ["time.dt=1e-4", "time.dt_max=1e-4"])


def test_a_tiny_time_dt_is_fine_when_time_steps_stops_the_run():
    scene = parmpm.load_scene("hanging_bar", ["time.dt=1e-30", "time.steps=10"])
    assert scene.spec.time.dt == 1e-30


def _final(tmp_path, name, *over, scene="hanging_bar_1d"):
    scene = parmpm.load_scene(scene, ["time.end=2e-3", "output.snapshots=false",
                                      "output.figure=false", *over])
    sim = Simulation(scene, tmp_path / name, quiet=True)
    sim.run()
    P = sim.particles
    order = np.argsort(P.gid)
    return sim.state.clock, P.x[order].copy(), P.v[order].copy(), P.stress[order].copy()


def test_a_fixed_step_runs_as_a_cfl_run_capped_at_the_same_step(tmp_path):
    """An independent route to the same steps: ``time.dt_max`` below the CFL step makes the
    CFL run take that step every time; ``time.dt`` must give the same trajectory bit for bit,
    and the step count the end time asks for."""
    dt = 1.6e-4  # the bar's CFL step is about 4e-4 s
    fixed = _final(tmp_path, "fixed", f"time.dt={dt}")
    capped = _final(tmp_path, "capped", f"time.dt_max={dt}")
    assert fixed[0].nstep == capped[0].nstep == math.ceil(2e-3 / dt)
    assert fixed[0].t == capped[0].t == pytest.approx(2e-3, rel=1e-12)
    assert fixed[0].dt_limit == "time.dt" and capped[0].dt_limit == "time.dt_max"
    for a, b in zip(fixed[1:], capped[1:]):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("method", ["cpdi", "mpm"])
def test_a_fixed_step_on_the_specialised_kernels_runs_as_the_capped_cfl_run(tmp_path, method):
    """The same in 2D, where G2P's kernels are compiled without the wave speed for the fixed
    step (:mod:`parmpm.transfer.running_speed`): every particle bit for bit as the CFL run's,
    whose kernels compute it; the speed the fixed run measures every few steps is the CFL
    run's at a step both measured."""
    dt = 2e-4  # the 2D bar's CFL step is about 1e-3 s
    over = (f'method.interpolator="{method}"', "time.end=4.2e-3")
    fixed = _final(tmp_path, "fixed", f"time.dt={dt}", *over, scene="hanging_bar")
    capped = _final(tmp_path, "capped", f"time.dt_max={dt}", *over, scene="hanging_bar")
    assert fixed[0].nstep == capped[0].nstep == 21  # measured at steps 1 and 21
    for a, b in zip(fixed[1:], capped[1:]):
        assert np.array_equal(a, b)
    assert fixed[0].vmax == pytest.approx(capped[0].vmax, rel=1e-12)
