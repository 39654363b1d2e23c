"""``parmpm show``: a built-in or resolved scene as TOML, a scene file to start from.

The contract is the round trip: ``parmpm show SCENE [--set ...] > my.toml`` then ``parmpm run
my.toml`` runs the same resolved scene (every default, every override), for every built-in scene;
and the ``scene.toml`` a run leaves in its folder is the same scene again.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import parmpm.cli.main as cli
from parmpm.scene.load import builtin_scenes, load_scene

REPO = Path(__file__).resolve().parents[2]
TIMEOUT_S = 120


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-m", "parmpm", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=TIMEOUT_S)


def _shown(capsys, *args: str) -> str:
    assert cli.main(["show", *args]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    return out


@pytest.mark.parametrize("name", sorted(builtin_scenes()))
def test_show_round_trips_every_builtin_scene(tmp_path, capsys, name):
    path = tmp_path / "my.toml"
    path.write_text(_shown(capsys, name))
    assert load_scene(path).data == load_scene(name).data


def test_show_applies_overrides(tmp_path, capsys):
    over = ["method.interpolator=mpm", "time.end=0.05", "bodies.0.ppc=2",
            "boundary.fixed_regions=[{min=[-0.5, 0.0], max=[1.5, 0.2]}]"]
    args = [a for o in over for a in ("--set", o)]
    path = tmp_path / "my.toml"
    path.write_text(_shown(capsys, "hanging_bar", *args))
    shown = load_scene(path)
    assert shown.data == load_scene("hanging_bar", over).data
    assert shown.data["method"]["interpolator"] == "mpm" and shown.data["time"]["end"] == 0.05


def test_show_of_a_scene_file_is_that_file_resolved(tmp_path, capsys):
    src = tmp_path / "mine.toml"
    src.write_text('dim = 1\n[grid]\ncell_size = 0.1\ncells = 20\n[materials.m]\n'
                   'model = "linear_elastic"\ndensity = 1.0\nyoungs_modulus = 100.0\n'
                   'poisson_ratio = 0.0\n[[bodies]]\nmin = 0.5\nmax = 1.5\nmaterial = "m"\n'
                   '[time]\nend = 0.1\n')
    path = tmp_path / "resolved.toml"
    path.write_text(_shown(capsys, str(src)))
    assert load_scene(path).data == load_scene(src).data
    assert "patch_size" in path.read_text()  # the defaults are spelled out


def test_show_errors_are_one_line(tmp_path, capsys):
    assert cli.main(["show", "no_such_scene"]) == 2
    assert cli.main(["show", "hanging_bar", "--set", "time.cfl=7"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 2 and all(line.startswith("parmpm: error: ") for line in lines)
    assert "no_such_scene" in lines[0] and "cfl" in lines[1]


def test_show_then_run_runs_the_same_scene(tmp_path):
    """The getting-started page's ``parmpm show hanging_bar > my_scene.toml; parmpm run my_scene.toml``, as a user types
    it (shortened), and the run folder's scene.toml is the same scene once more."""
    proc = _cli("show", "hanging_bar_1d", "--set", "time.steps=3", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    (tmp_path / "my.toml").write_text(proc.stdout)
    run = _cli("run", "my.toml", "--quiet", "--set", "output.figure=false", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    folder = tmp_path / "parmpm-out" / "hanging_bar_1d"  # the scene keeps its name
    expected = load_scene("hanging_bar_1d", ["time.steps=3", "output.figure=false"]).data
    assert load_scene(folder / "scene.toml").data == expected


def test_show_into_a_closed_pipe_is_quiet(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.run(f"'{sys.executable}' -m parmpm show hanging_bar | head -1", shell=True,
                          cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=TIMEOUT_S)
    assert proc.stdout.startswith("# parmpm scene") and proc.stderr == ""
