"""Faults around a run (issue: no input, fault or full disk hangs a run or loses a result):
schedules that cannot loop, stop signals honoured everywhere, output folders that are never taken
from another run, pruning that touches only the run's own checkpoints, a checkpoint at the end of
a run that stopped early, the blow-up watch, and the small CLI contracts."""
from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
from mpi_launch import mpirun, needs_mpi
from run_waits import signal_during_set_up
from test_cli import assert_one_line_error
from test_cli import parmpm as cli

import parmpm
from parmpm.cli.main import main
from parmpm.core.errors import ParmpmError, RunInterrupted
from parmpm.driver.schedule import Schedule
from parmpm.driver.simulation import Simulation

QUIET = ["--quiet"]
OFF = ["--set", "output.snapshots=false", "--set", "output.figure=false"]


# --- schedules -------------------------------------------------------------------------------------
def test_a_period_below_the_round_off_of_time_fires_once_per_step_and_never_loops():
    s = Schedule(every=1e-20)
    t = 0.0
    for step in range(1, 6):
        t += 1e-3
        assert s.due(t, step)
        s.advance(t)                # computed, not accumulated: returns at once
        assert s.next_time >= t
    assert Schedule(every=0.1).next_time == pytest.approx(0.1)


def test_a_schedule_fires_at_multiples_of_its_period_and_of_its_step_count():
    s = Schedule(every=0.25, every_steps=3)
    fired = []
    t = 0.0
    for step in range(1, 13):
        t = step * 0.1
        if s.due(t, step):
            fired.append(step)
            s.advance(t)
    # time: 0.3 (>= 0.25), 0.5, 0.8 (>= 0.75), 1.0; steps: 3, 6, 9, 12
    assert fired == [3, 5, 6, 8, 9, 10, 12]
    assert Schedule(every=0.25, next_time=0.75).next_time == 0.75  # a restored clock


def test_any_of_asks_every_part_and_at_end_follows_the_clock():
    """A collective part (wall time) must be asked at every step on every rank, even when an
    earlier part is already due; the end of the run has the schedules' tolerance."""
    from parmpm.driver.schedule import AnyOf, AtEnd, Clock

    asked = []

    class Counting:
        def due(self, t, step):
            asked.append(step)
            return False

        def advance(self, t):
            pass

    clock = Clock(SimpleNamespace(cfl=0.5, dt_max=None, dt=None, end=1.0, steps=None), 0.1, 1.0)
    both = AnyOf(Schedule(every_steps=1), Counting(), AtEnd(clock))
    assert both.due(0.5, 1) and asked == [1]
    clock.t = 1.0 - 1e-13  # within REL_TOL of the end
    assert clock.done() and AnyOf(AtEnd(clock)).due(clock.t, 2)
    assert clock.next_dt() == pytest.approx(1e-13) and clock.dt_limit == "time.cfl"


class _Ranks:
    """The answers of a few ranks' allgather/bcast, as seen from ``rank``."""

    def __init__(self, rank, values):
        self.rank, self.values = rank, values

    def Get_rank(self):
        return self.rank

    def allgather(self, obj):
        return [obj if r == self.rank else v for r, v in enumerate(self.values)]

    def bcast(self, obj, root=0):
        return self.values[root][1] if root != self.rank else obj


def test_agree_raises_the_same_message_on_every_rank():
    from parmpm.core.collective import agree
    from parmpm.core.errors import SimulationError

    agree(_Ranks(0, [(0, None), (1, None)]), None, root=None)  # no problem anywhere
    values = [(0, None), (1, "rank 1 failed"), (2, "rank 2 failed")]
    for rank in range(3):  # the lowest rank's problem, on every rank, as the error asked for
        with pytest.raises(SimulationError, match="^rank 1 failed$"):
            agree(_Ranks(rank, values), values[rank][1], root=None, error=SimulationError)
    keyed = [(0, None), (-1, "rank 1 failed"), (-2, "rank 2 failed")]
    with pytest.raises(ParmpmError, match="rank 2"):  # the smallest key's
        agree(_Ranks(0, keyed), None, root=None, key=0)
    with pytest.raises(ParmpmError, match="rank 1"):  # known on the root only: broadcast
        agree(_Ranks(0, values), None, root=1)


def test_a_new_output_is_one_callback_and_changes_no_result(tmp_path):
    """What a history writer needs: one Callback on a schedule, also on the initial state."""
    from parmpm.driver.callbacks import Callback

    rows = []
    with_history = _sim(tmp_path, "checkpoint.every_steps=3", name="h")
    with_history.callbacks.append(Callback(
        "history", lambda sim: rows.append((sim.nstep, sim.totals()["kinetic_energy"])),
        Schedule(every_steps=2), start=3))
    plain = _sim(tmp_path, "checkpoint.every_steps=3", name="p")
    a, b = with_history.run(), plain.run()
    assert [step for step, _ in rows] == [0, 2, 4, 6]
    assert rows[-1][1] == a["final"]["kinetic_energy"]
    assert (a["final"], a["metrics"], a["steps"]) == (b["final"], b["metrics"], b["steps"])
    assert sorted(p.name for p in (tmp_path / "h").glob("checkpoint_*.h5")) == \
        ["checkpoint_00000003.h5", "checkpoint_00000006.h5"]


@pytest.mark.parametrize("key", ["output.every=1e-20", "output.every=1e-17",
                                 "checkpoint.every=1e-20"])
def test_tiny_periods_end(tmp_path, key):
    """Before: 'the next output time' loop added a period below the time's ulp and never ended
    (SIGTERM could not stop it)."""
    proc = cli("run", "hanging_bar", "-o", str(tmp_path / "o"), *QUIET, "--set", key,
               "--set", "time.steps=3", "--set", "output.figure=false", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    if key.startswith("output"):
        xdmf = (tmp_path / "o" / "hanging_bar.xdmf").read_text()
        assert xdmf.count("<Time ") == 2 * 4  # the initial state and once per step (particles, domains)
    else:
        assert len(list((tmp_path / "o").glob("checkpoint_*.h5"))) == 3  # keep = 3, one per step


# --- stop signals ---------------------------------------------------------------------------------
def _sim(tmp_path, *over, name="o"):
    scene = parmpm.load_scene("hanging_bar_1d", ["time.steps=6", "output.snapshots=false", *over])
    return Simulation(scene, tmp_path / name, quiet=True)


def test_sigterm_while_the_final_figure_is_drawn_writes_a_checkpoint(tmp_path, monkeypatch):
    """Before: the signal handler was gone after the loop, so SIGTERM killed the process (rc 143)
    and no checkpoint was written."""
    import parmpm.io.figures as figures

    drawn = []

    def figure_then_signal(path, *args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)  # delivered at once, in this (main) thread
        drawn.append(path)

    monkeypatch.setattr(figures, "plot_particles", figure_then_signal)
    sim = _sim(tmp_path)
    with pytest.raises(RunInterrupted) as info:
        sim.run()
    path = tmp_path / "o" / "checkpoint_00000006.h5"
    assert drawn and path.is_file()
    assert f"continue with: parmpm restart {path}" in str(info.value)
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["steps"] == 6
    assert signal.getsignal(signal.SIGTERM) is not None  # handlers restored


def test_sigterm_during_set_up_is_one_line_and_exit_130(tmp_path):
    """Before the time loop there is nothing to save: SIGTERM ends the run like Ctrl-C (before:
    killed by the signal, rc -15, no message)."""
    returncode, err = signal_during_set_up(tmp_path / "o", signal.SIGTERM, 100, 120)
    assert returncode == 130, err
    assert err.strip() == "parmpm: interrupted"


# --- output folders -------------------------------------------------------------------------------
def _tree(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def test_a_failing_run_cannot_overwrite_another_runs_results(tmp_path):
    """The issue's case: a second (blowing-up) run into the same folder truncated the first run's
    snapshots. Now the folder is refused before anything is written, and --overwrite is needed."""
    same = tmp_path / "same"
    assert main(["run", "vibrating_bar", "-o", str(same), *QUIET]) == 0
    before = _tree(same)
    proc = cli("run", "vibrating_bar", "-o", str(same), *QUIET, "--set", "method.interpolator=mpm",
               "--set", "method.update=usl", "--set", "time.cfl=0.99", cwd=tmp_path)
    assert_one_line_error(proc, "holds the results of another run", "--overwrite")
    assert _tree(same) == before
    # --overwrite deletes that run's files (and keeps what parmpm did not write)
    (same / "notes.txt").write_text("mine")
    assert main(["run", "vibrating_bar", "-o", str(same), *QUIET, *OFF, "--overwrite",
                 "--set", "time.steps=3"]) == 0
    # snapshots off: the history table has no snapshot file to go into, so history.h5
    assert sorted(p.name for p in same.iterdir()) == ["history.csv", "history.h5", "notes.txt",
                                                      "parmpm-run.json", "parmpm-run.lock",
                                                      "scene.toml", "summary.json"]


def test_the_default_folder_is_never_taken_from_another_run(tmp_path):
    for _ in range(2):
        proc = cli("run", "hanging_bar_1d", *QUIET, "--set", "time.steps=2", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
    out = tmp_path / "parmpm-out"
    assert sorted(p.name for p in out.iterdir()) == ["hanging_bar_1d", "hanging_bar_1d_2"]
    ids = {json.loads((d / "parmpm-run.json").read_text())["run_id"] for d in out.iterdir()}
    assert len(ids) == 2
    summary = json.loads((out / "hanging_bar_1d_2" / "summary.json").read_text())
    assert summary["output_dir"].endswith("hanging_bar_1d_2")


def test_a_folder_of_an_older_parmpm_counts_as_a_run(tmp_path):
    (tmp_path / "summary.json").write_text("{}")
    proc = cli("run", "hanging_bar_1d", "-o", str(tmp_path), *QUIET, cwd=tmp_path)
    assert_one_line_error(proc, "holds another run's results")


def test_unwritable_folder_fails_before_the_run(tmp_path, monkeypatch):
    """A folder that cannot be written fails when the run claims it, before the first step (as
    root, permissions do not bind, so the failure is injected where the marker is created)."""
    import parmpm.io.run_folder as run_folder

    def refuse(path, flags, mode=0o777):
        raise OSError(30, "Read-only file system", str(path))

    monkeypatch.setattr(run_folder.os, "open", refuse)
    sim = _sim(tmp_path)
    with pytest.raises(ParmpmError, match="cannot write to output folder .*Read-only file system"):
        sim.run()
    assert sim.nstep == 0


def test_leftover_temporary_files_are_removed_when_a_run_claims_its_folder(tmp_path):
    """A killed run's temporary files leave a folder free; a file parmpm did not write makes it
    need --overwrite (issue 41), and stays."""
    for extra in ([], ["--overwrite"]):
        d = tmp_path / f"o{len(extra)}"
        d.mkdir()
        (d / "checkpoint_00000005.h5.tmp").write_bytes(b"half a checkpoint")
        if extra:
            (d / "keep.txt").write_text("not parmpm's")
        assert main(["run", "hanging_bar_1d", "-o", str(d), *QUIET, *OFF, "--set", "time.steps=1",
                     *extra]) == 0
        assert not (d / "checkpoint_00000005.h5.tmp").exists()
        assert (d / "keep.txt").exists() == bool(extra)


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores folder permissions")
def test_read_only_folder_fails_before_the_run(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        proc = cli("run", "hanging_bar_1d", "-o", str(ro), *QUIET, cwd=tmp_path)
    finally:
        ro.chmod(stat.S_IRWXU)
    assert_one_line_error(proc, "cannot write to output folder")


# --- pruning and at_end -----------------------------------------------------------------------------
def test_pruning_keeps_other_runs_checkpoints_and_the_restart_keeps_its_own(tmp_path):
    """Before: prune kept the newest files by name in the folder, so a run sharing a folder with
    a longer run deleted its own new checkpoints (and then pointed the user at a deleted file).
    Now a restart gets a folder of its own, the first run's folder is refused to it, and pruning
    deletes only checkpoints of the run that prunes."""
    from parmpm.io.checkpoint import prune

    d = tmp_path / "run"
    assert main(["run", "hanging_bar_1d", "-o", str(d), *QUIET, *OFF, "--set", "time.steps=40",
                 "--set", "checkpoint.every_steps=10", "--set", "checkpoint.keep=5"]) == 0
    first = sorted(p.name for p in d.glob("checkpoint_*.h5"))
    assert first == [f"checkpoint_{k:08d}.h5" for k in (10, 20, 30, 40)]
    before = _tree(d)
    proc = cli("restart", str(d / "checkpoint_00000010.h5"), "-o", str(d), *QUIET, cwd=tmp_path)
    assert_one_line_error(proc, "holds the results of another run")
    assert _tree(d) == before
    assert main(["restart", str(d / "checkpoint_00000010.h5"), *QUIET, "--set", "time.steps=25",
                 "--set", "checkpoint.every_steps=5", "--set", "checkpoint.keep=1"]) == 0
    assert [p.name for p in (tmp_path / "run" / "restart_00000010").glob("checkpoint_*.h5")] == \
        ["checkpoint_00000025.h5"]
    assert _tree(d) == before
    # the rule itself: files of another lineage are never deleted, whatever their step
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    for name in first:
        (mixed / name).write_bytes((d / name).read_bytes())
    restarted = tmp_path / "run" / "restart_00000010" / "checkpoint_00000025.h5"
    (mixed / "checkpoint_00000025.h5").write_bytes(restarted.read_bytes())
    import h5py
    with h5py.File(restarted) as f:
        lineage = str(f.attrs["lineage"])
    prune(mixed, 1, lineage=lineage)
    assert sorted(p.name for p in mixed.iterdir()) == sorted(first + ["checkpoint_00000025.h5"])


def test_at_end_checkpoint_also_when_the_run_stops_on_separation(tmp_path):
    """mpm separates the bar in its first upswing; stop_on_separation ended the loop without the
    checkpoint that checkpoint.at_end asks for."""
    d = tmp_path / "sep"
    assert main(["run", "hanging_bar", "-o", str(d), *QUIET, *OFF,
                 "--set", "method.interpolator=mpm", "--set", "checkpoint.at_end=true"]) == 0
    summary = json.loads((d / "summary.json").read_text())
    assert summary["stopped"] == "separated"
    assert (d / f"checkpoint_{summary['steps']:08d}.h5").is_file()


# --- blow-ups ------------------------------------------------------------------------------------
def test_an_unstable_run_stops_with_its_cause(tmp_path):
    """cpdi with USL at CFL 0.99 on the vibrating bar multiplied its energy by 15 and exited 0."""
    proc = cli("run", "vibrating_bar", "-o", str(tmp_path / "o"), *QUIET, "--set",
               "method.update=usl", "--set", "time.cfl=0.99", cwd=tmp_path)
    # the history's warning comes first (5 % gained), then the watch stops the run (one line)
    warning, error = proc.stderr.strip().splitlines()
    assert "WARNING" in warning and "more than it was given" in warning
    assert_one_line_error(subprocess.CompletedProcess(proc.args, proc.returncode, proc.stdout,
                                                      error), "unstable",
                          "try a smaller time.cfl (now 0.99)")


def test_the_watch_is_quiet_on_a_sound_run_and_reports(tmp_path):
    summary = main(["run", "vibrating_bar", "-o", str(tmp_path), *QUIET, *OFF])
    assert summary == 0
    energy = json.loads((tmp_path / "summary.json").read_text())["energy"]
    assert energy["limit"] == 1.0 and 0.0 <= energy["max_growth"] < 0.1
    # a sound run: what the body holds is what it was given, to within its numerical dissipation
    assert abs(energy["residual"]) < 0.05 * energy["initial"]


def test_a_blow_up_under_dt_max_names_dt_max(tmp_path):
    sim = _sim(tmp_path, "time.dt_max=1e-5")
    clock = sim.state.clock
    clock.next_dt()
    clock.last_dt = 1e-5
    assert clock.dt_limit == "time.dt_max"
    assert "time.dt_max" in clock.unstable_hint() and "time.cfl" not in clock.unstable_hint()


@needs_mpi
def test_huge_gravity_gives_the_same_message_on_one_and_two_ranks(tmp_path):
    """Before: 'non-finite velocity' on 1 rank, 'left the grid' on 2 (the 1-rank path skipped
    the grid check when no particle changed patch)."""
    lines = []
    for n in (1, 2):
        cmd = [sys.executable, "-m", "parmpm", "run", "hanging_bar", "-o", str(tmp_path / str(n)),
               *QUIET, *OFF, "--set", "gravity.g=[0,-1e100]"]
        if n > 1:
            cmd = [mpirun(), "-n", "2", *cmd]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 2, proc.stderr
        err = proc.stderr.strip().splitlines()
        assert len(err) == 1, proc.stderr
        lines.append(err[0])
    assert "left the grid" in lines[0] and lines[0] == lines[1]


# --- restart -----------------------------------------------------------------------------------------
def test_a_restart_cannot_change_the_dimension(tmp_path):
    d = tmp_path / "r"
    assert main(["run", "hanging_bar_1d", "-o", str(d), *QUIET, *OFF, "--set", "time.steps=2",
                 "--set", "checkpoint.at_end=true"]) == 0
    proc = cli("restart", str(d / "checkpoint_00000002.h5"), "--set", "dim=2", *QUIET, cwd=tmp_path)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr


# --- small CLI contracts ---------------------------------------------------------------------------
def test_summary_json_is_readable_by_the_group(tmp_path):
    old = os.umask(0o022)
    try:
        assert main(["run", "hanging_bar_1d", "-o", str(tmp_path), *QUIET, *OFF,
                     "--set", "time.steps=1"]) == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "summary.json").stat().st_mode) == 0o644


@pytest.mark.parametrize("option", ["--patch-size=0", "--steps=0", "--ppc=-1", "--speed=nan"])
def test_bench_refuses_non_positive_options(tmp_path, option):
    proc = cli("bench", option, cwd=tmp_path)
    assert proc.returncode == 2 and "expected a positive" in proc.stderr, proc.stderr


def test_run_is_the_default_command_also_with_options(tmp_path):
    proc = cli("--quiet", "--set", "time.steps=2", "--set", "output.figure=false", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "parmpm-out" / "hanging_bar" / "summary.json").is_file()


@needs_mpi
def test_argument_errors_print_once_under_mpirun(tmp_path):
    proc = subprocess.run([mpirun(), "-n", "2", sys.executable, "-m", "parmpm", "run", "--bogus"],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert proc.returncode != 0
    assert proc.stderr.count("unrecognized arguments: --bogus") == 1, proc.stderr


@needs_mpi
def test_new_run_errors_print_once_under_two_ranks(tmp_path):
    """The folder refusal (found on rank 0) and the blow-up (found together) end both ranks with
    one line, printed once."""
    taken = tmp_path / "taken"
    taken.mkdir()
    (taken / "summary.json").write_text("{}")
    for args, fragment in (
            (["-o", str(taken)], "holds another run's results"),
            (["-o", str(tmp_path / "b"), "--set", "method.update=usl", "--set", "time.cfl=0.99"],
             "unstable")):
        proc = subprocess.run([mpirun(), "-n", "2", sys.executable, "-m", "parmpm", "run",
                               "vibrating_bar", *QUIET, *args], capture_output=True, text=True,
                              timeout=300, cwd=tmp_path)
        assert proc.returncode == 2, proc.stderr
        # (the blow-up is announced first by the history's warning, once)
        lines = [ln for ln in proc.stderr.splitlines() if ln.strip() and "WARNING" not in ln]
        assert len(lines) == 1 and fragment in lines[0], proc.stderr
        assert sum("WARNING" in ln for ln in proc.stderr.splitlines()) <= 1, proc.stderr
