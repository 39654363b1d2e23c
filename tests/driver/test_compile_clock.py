"""A one-rank run reports its compiling apart (issue 28 item 11): a first run's summary read
"wall time 59.2 s, 68,468 particle-steps/s" for 7 s of steps and 52 s of numba compiling
kernels met inside the timed loop. The run now leaves numba's compilations out of its wall time
and rate and reports them as ``compile_seconds`` (:mod:`parmpm.driver.compile_clock`)."""
from __future__ import annotations

import time

from parmpm.driver.callbacks import Callback
from parmpm.driver.compile_clock import CompileClock
from parmpm.io.summary import format_summary
from parmpm.scene.load import load_scene
from parmpm.driver.schedule import Schedule
from parmpm.driver.simulation import Simulation

PAUSE_S = 1.0


def _fake_compile(seconds: float) -> None:
    """What numba signals around a compilation, around a pause of ``seconds``."""
    from numba.core import event

    event.start_event("numba:compile", data={"dispatcher": None})
    event.start_event("numba:compile", data={"dispatcher": None})  # a nested one: counted once
    time.sleep(seconds)
    event.end_event("numba:compile", data={"dispatcher": None})
    event.end_event("numba:compile", data={"dispatcher": None})


def test_the_clock_counts_top_level_compilations():
    clock = CompileClock()
    with clock.listen():
        _fake_compile(0.2)
    _fake_compile(0.2)  # not listening
    assert 0.2 <= clock.seconds < 0.35


def test_compiling_mid_run_is_left_out_of_wall_time_and_rate(tmp_path):
    """A kernel compiled at step 5 (a pause inside numba's compile events): the summary's
    ``compile_seconds`` holds it, ``wall_seconds`` and the rate do not."""
    scene = load_scene("hanging_bar_1d", ["time.steps=12", "output.figure=false",
                                          "output.snapshots=false"])
    sim = Simulation(scene, tmp_path / "o", quiet=True)
    sim.callbacks.append(Callback("compiles", lambda s: _fake_compile(PAUSE_S),
                                  Schedule(every_steps=5)))  # steps 5 and 10
    t0 = time.perf_counter()
    summary = sim.run()
    elapsed = time.perf_counter() - t0
    assert summary["compile_seconds"] >= 2 * PAUSE_S
    assert summary["wall_seconds"] <= elapsed - 2 * PAUSE_S + 0.05
    loop = summary["particles"] * (summary["steps"] - 1) / summary["particle_steps_per_second"]
    assert loop < PAUSE_S  # 11 steps of a 1D bar, without the 2 s of "compiling"
    line = format_summary(summary).splitlines()[3]
    assert line.startswith("wall time") and " s compiling kernels" in line, line


def test_summary_line_says_the_compile_apart():
    base = {"scene": "x", "particles": 1000, "steps": 11, "wall_seconds": 7.0,
            "particle_steps_per_second": 1.5e3}
    assert format_summary({**base, "compile_seconds": 52.0}).splitlines()[3] == \
        "wall time   7 s + 52 s compiling kernels    1,500 particle-steps/s"
    assert format_summary({**base, "compile_seconds": 0.0}).splitlines()[3] == \
        "wall time   7 s    1,500 particle-steps/s"
