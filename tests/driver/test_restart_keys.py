"""What ``parmpm restart --set`` may change (issue 28 item 6; :mod:`parmpm.driver.restart_keys`).

Before, a restart's ``--set`` changed the stored scene wholesale: ``materials.bar.density=5000``
kept the checkpoint's masses but set Δt from the new density and scene.toml said 5000; a changed
body size was recorded though the full body ran; a ``time.end`` before the checkpoint's time ran
0 steps without a word. Now the keys the continued run cannot apply in full are refused in one
line naming the key, a restart with nothing left to run is refused, and what ran is recorded."""
from __future__ import annotations

import json
import os

import pytest

from parmpm.cli.main import main
from parmpm.io import load_snapshots
from parmpm.driver.restart_keys import RESTART_KEYS, allowed, changes
from parmpm.scene.load import load_scene, scene_from_toml

QUIET = ["--quiet", "--set", "output.figure=false"]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A 1D bar run to step 40 (t ≈ 0.034 s) with checkpoints at steps 20 and 40."""
    d = tmp_path_factory.mktemp("restart_keys") / "run"
    assert main(["run", "hanging_bar_1d", "-o", str(d), *QUIET, "--set", "time.steps=40",
                 "--set", "checkpoint.every_steps=20"]) == 0
    return d


def _restart(capsys, ck, out, *sets):
    args = ["restart", str(ck), "-o", str(out), *QUIET]
    for s in sets:
        args += ["--set", s]
    code = main(args)
    return code, capsys.readouterr().err.strip()


@pytest.mark.parametrize("override,key", [
    ("materials.bar.density=5000", "materials.bar.density"),      # HEAD: ran, recorded 5000
    ("bodies.0.max=-0.5", "bodies.0.max"),                        # HEAD: recorded, full body ran
    ("bodies.0.ppc=5", "bodies.0.ppc"),
    ("gravity.g=0", "gravity.g"),
    ("grid.cells=40", "grid.cells"),
    ("grid.cell_size=0.2", "grid.cell_size"),
    ("boundary.x_min=fixed", "boundary.x_min"),
    ("damping.coefficient=5", "damping.coefficient"),
    ("metrics.kind=none", "metrics.kind"),
    ("materials={bar={model='neo_hookean', density=9, youngs_modulus=1e6, poisson_ratio=0}}",
     "materials.bar.density"),                                    # through its table
])
def test_a_key_the_checkpoint_embodies_is_refused_in_one_line(run, tmp_path, capsys, override,
                                                              key):
    code, err = _restart(capsys, run / "checkpoint_00000020.h5", tmp_path / "o", override,
                         "time.steps=60")
    assert code == 2, err
    assert err.startswith("parmpm: error: checkpoint '") and "\n" not in err, err
    assert f"a restart cannot change {key}" in err and f"--set {override[:40]}" in err, err
    assert "time.*" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()  # refused before the folder was claimed


@pytest.mark.parametrize("override,fragment", [
    ("time.end=0.001", "time.end = 0.001 s leaves nothing to run"),   # HEAD: 0 steps, exit 0
    ("time.steps=20", "time.steps = 20 (counted from the run's start) leaves nothing to run"),
    ("time.steps=5", "--set time.steps to more than 20"),
])
def test_a_restart_with_nothing_to_run_is_refused(run, tmp_path, capsys, override, fragment):
    code, err = _restart(capsys, run / "checkpoint_00000020.h5", tmp_path / "o", override)
    assert code == 2 and "\n" not in err and fragment in err, err
    assert "the checkpoint is at" in err and f"--set {override}" in err, err


def test_the_last_checkpoint_without_a_later_end_is_refused(run, tmp_path, capsys):
    """The run's own end (time.steps = 40) is reached at the checkpoint of step 40."""
    code, err = _restart(capsys, run / "checkpoint_00000040.h5", tmp_path / "o")
    assert code == 2 and "the checkpoint is at step 40" in err and "--set" in err, err
    code, err = _restart(capsys, run / "checkpoint_00000040.h5", tmp_path / "o", "time.steps=42")
    assert code == 0, err


def test_allowed_changes_are_applied_and_recorded(run, tmp_path, capsys):
    out = tmp_path / "o"
    code, err = _restart(capsys, run / "checkpoint_00000020.h5", out, "time.steps=60",
                         "output.every=0.01", "method.lcr=1dx", "materials.bar.density=1050.0")
    assert code == 0, err
    text = (out / "scene.toml").read_text()
    assert "# a restart: continues from step 20" in text
    assert "# changed on restart: time.steps = 60 (was 40)" in text
    assert "# changed on restart: output.every = 0.01 (was 0.05)" in text
    assert '# changed on restart: method.lcr = "1dx" (was "2dx")' in text
    assert "density" not in text.split("\nname")[0]  # the same value: no change
    again = load_scene(out / "scene.toml")  # the header is comments: the file still runs
    assert again.data["time"]["steps"] == 60 and again.data["method"]["lcr"] == "1dx"
    marker = json.loads((out / "parmpm-run.json").read_text())
    assert marker["continues"]["changed"]["output.every"] == [0.05, 0.01]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 60
    # the new output schedule from the checkpoint's time on, not the stored one's next time
    # (t ≈ 0.0199 at step 20: next 0.02, 0.03, ...; HEAD: the stored 0.05 first)
    times = load_snapshots(out / "hanging_bar_1d_from_00000020.xdmf").times
    assert 0.02 <= times[0] < 0.022 and 0.03 <= times[1] < 0.032, times


def test_allowed_and_changes():
    for key in ("time.end", "output.history.every", "checkpoint.keep", "method.interpolator",
                "grid.patch_size", "decomposition.rebalance_threshold", "name",
                "metrics.stop_on_separation"):
        assert allowed(key), key
    for key in ("dim", "grid.cells", "grid.ghost", "grid.exterior", "materials.bar.density",
                "bodies.0.min.1", "gravity.g.0", "boundary.x_min", "metrics.kind", "timeline",
                "methods"):
        assert not allowed(key), key
    assert "time" in RESTART_KEYS
    stored = load_scene("hanging_bar").to_toml()  # as a checkpoint holds it: every value set
    a = scene_from_toml(stored).data
    b = scene_from_toml(stored, overrides=["time.end=0.5", "bodies.0.max=[1.0, -0.5]"]).data
    assert changes(a, b) == {"bodies.0.max.1": [0.0, -0.5], "time.end": [0.3, 0.5]}
    assert changes(a, a) == {}
    assert changes({"x": [1]}, {"x": [1, 2]}) == {"x": [[1], [1, 2]]}


def test_restart_keys_are_documented():
    """The list is in the manual (docs/checkpoints.md), key by key."""
    doc = open(os.path.join(os.path.dirname(__file__), "..", "..", "docs", "checkpoints.md")).read()
    section = doc.split("## What a restart may change")[1]
    for key in RESTART_KEYS:
        assert f"`{key}" in section, key
