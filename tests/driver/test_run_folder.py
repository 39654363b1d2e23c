"""A run folder that explains itself: the resolved scene, the version and command in the summary,
and a summary also when a signal stops the run.

* ``scene.toml``: the scene as it ran (defaults and overrides resolved), claimed in
  ``parmpm-run.json`` like every other file of the run, so ``--overwrite`` removes it too;
* ``summary.json``: ``parmpm_version`` and ``command`` (``argv``, ``ranks``, ``python``);
* SIGTERM/SIGINT inside the loop: the checkpoint, then ``summary.json`` with ``"stopped":
  "interrupted"`` and the checkpoint's path, on every rank count; a summary that cannot be
  written is a warning and the interrupt still ends the run with its restart line.
"""
from __future__ import annotations

import json
import logging
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from run_waits import wait_for_steps

import parmpm
from parmpm.driver.callbacks import Callback, Schedule
from parmpm.core.errors import ParmpmError, RunInterrupted
from parmpm.io.run_folder import claim
from parmpm.driver.run_files import RunFiles
from parmpm.driver.simulation import Simulation

REPO = Path(__file__).resolve().parents[2]
QUIET_SCENE = ["output.snapshots=false", "output.figure=false", "output.history=false"]
#: a run that a test signals: history rows every step, the proof that it is stepping
SIGNALLED_SCENE = ["output.snapshots=false", "output.figure=false", "output.history.every_steps=1"]


def _sim(folder: Path, *over: str) -> Simulation:
    scene = parmpm.load_scene("hanging_bar_1d", ["time.steps=6", *QUIET_SCENE, *over])
    return Simulation(scene, folder, quiet=True)


def test_the_folder_holds_the_resolved_scene_and_claims_it(tmp_path):
    sim = _sim(tmp_path / "o", "method.interpolator=ugimp")
    sim.run()
    folder = tmp_path / "o"
    assert parmpm.load_scene(folder / "scene.toml").data == sim.state.scene.data
    marker = json.loads((folder / "parmpm-run.json").read_text())
    assert "scene.toml" in marker["files"]
    claim(folder, {"files": []}, explicit=True, overwrite=True)  # --overwrite
    assert not (folder / "scene.toml").exists()  # removed with the run's other files


def test_the_summary_names_version_and_command(tmp_path, monkeypatch):
    monkeypatch.setattr(sys, "argv", ["parmpm", "run", "hanging_bar_1d", "--set", "x=1"])
    summary = _sim(tmp_path / "o").run()
    written = json.loads((tmp_path / "o" / "summary.json").read_text())
    for record in (summary, written):
        assert record["parmpm_version"].startswith(parmpm.__version__)
        assert record["command"]["argv"] == ["parmpm", "run", "hanging_bar_1d", "--set", "x=1"]
        assert record["command"]["ranks"] == 1 and record["command"]["python"]
        assert record["stopped"] == "end"


def _signal_at_step(step: int, sig=signal.SIGTERM) -> Callback:
    def send(sim):
        os.kill(os.getpid(), sig)  # delivered at once, in this (main) thread
    return Callback("signal", send, Schedule(every_steps=step))


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_an_interrupted_run_writes_its_summary(tmp_path, sig):
    sim = _sim(tmp_path / "o", "time.steps=100")
    sim.callbacks.append(_signal_at_step(3, sig))
    with pytest.raises(RunInterrupted) as info:
        sim.run()
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    # the signal came after step 3's interrupt check: the ranks agree on it after step 4
    assert summary["stopped"] == "interrupted" and summary["steps"] == 4
    checkpoint = tmp_path / "o" / "checkpoint_00000004.h5"
    assert checkpoint.is_file() and f"parmpm restart {checkpoint}" in str(info.value)
    assert summary["checkpoint"] == str(checkpoint)
    assert summary["time"] == pytest.approx(sim.t) and summary["command"]["ranks"] == 1


def test_a_summary_that_cannot_be_written_does_not_hide_the_interrupt(tmp_path, monkeypatch,
                                                                      caplog):
    def full_disk(self, summary):
        raise ParmpmError(f"cannot write '{self.folder / 'summary.json'}': No space left")

    monkeypatch.setattr(RunFiles, "write_summary", full_disk)
    sim = _sim(tmp_path / "o", "time.steps=100")
    sim.callbacks.append(_signal_at_step(2))
    logger = logging.getLogger("parmpm")
    monkeypatch.setattr(logger, "propagate", True)  # let caplog see parmpm's records
    with caplog.at_level(logging.WARNING, logger="parmpm"), pytest.raises(RunInterrupted) as info:
        sim.run()
    assert "continue with: parmpm restart" in str(info.value)
    assert not (tmp_path / "o" / "summary.json").exists()
    assert any("summary.json of the interrupted run not written" in r.getMessage()
               and "No space left" in r.getMessage() for r in caplog.records)


def test_a_signal_after_the_summary_keeps_it(tmp_path, monkeypatch):
    """A signal while the figure is drawn: the summary written before it stays (the run reached
    its end: ``"stopped": "end"``), the checkpoint is written, the interrupt raised."""
    import parmpm.io.figures as figures

    monkeypatch.setattr(figures, "plot_particles",
                        lambda *a, **k: os.kill(os.getpid(), signal.SIGTERM))
    sim = _sim(tmp_path / "o", "output.figure=true")
    with pytest.raises(RunInterrupted):
        sim.run()
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["stopped"] == "end" and summary["steps"] == 6


def test_sigterm_under_mpirun_writes_the_summary_on_every_rank_count(tmp_path, mpirun):
    """Two ranks, SIGTERM to the launcher: both ranks agree, checkpoint, write the summary
    (collectively) and stop with exit 130 — nothing hangs."""
    out = tmp_path / "o"
    cmd = [mpirun, "-n", "2", sys.executable, "-m", "parmpm", "run", "vibrating_bar", "-o",
           str(out), "--quiet", "--set", "time.end=1e6", *(a for o in SIGNALLED_SCENE
                                                            for a in ("--set", o))]
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env)
    wait_for_steps(proc, out / "history.csv")
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stopped"] == "interrupted" and summary["ranks"] == 2
    assert Path(summary["checkpoint"]).is_file() and "continue with: parmpm restart" in err
