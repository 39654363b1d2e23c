"""The contact benchmark (``run_scripts/benchmarks/contact_cost.py``) times the scene the contact
page's cost figures name: two disks touching head on, the same particles with and without
``[contact]``, each disk its own field with it; and it runs and refuses nonsense in one line."""
import math
import sys

import numpy as np
import pytest
from benchmarks import contact_cost as C

from decomposition import world
from parmpm.driver.set_up import set_up
from parmpm.scene.load import scene_from_toml


def test_the_scene_is_two_touching_disks_with_and_without_contact():
    cell = 0.02
    one, two = (set_up(scene_from_toml(C.scene(cell, contact), "<disks>"), world())
                for contact in (False, True))
    x1, x2 = one.particles.rows.x[:, :2], two.particles.rows.x[:, :2]
    assert x1.shape == x2.shape
    np.testing.assert_array_equal(np.sort(x1, axis=0), np.sort(x2, axis=0))
    # two lattice disks of radius 0.15 m, 4 particles a cell: about 2 π R² / (Δx / 2)² of them
    expected = 2 * math.pi * 0.15 ** 2 / (cell / 2) ** 2
    assert abs(x1.shape[0] / expected - 1.0) < 0.05
    left = x1[:, 0] < 0.0
    assert left.sum() == (~left).sum()
    assert x1[left, 0].max() > -0.5 * cell and x1[~left, 0].min() < 0.5 * cell  # they touch
    assert two.stepper.contact is not None and one.stepper.contact is None


def test_it_runs_and_prints_the_ratio(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["contact_cost", "--cell", "0.02", "--warm", "1",
                                      "--steps", "1", "--repeat", "1"])
    C.main()
    out = capsys.readouterr().out
    assert "one field" in out and "contact" in out and "x;" in out


@pytest.mark.parametrize("bad", [["--steps", "0"], ["--repeat", "-1"], ["--cell", "nan"],
                                 ["--cell", "0"], ["--cell", "inf"], ["--cell", "10"],
                                 ["--patch", "-2"]])
def test_nonsense_is_refused_in_one_line(monkeypatch, bad):
    monkeypatch.setattr(sys, "argv", ["contact_cost", *bad])
    with pytest.raises(SystemExit) as e:
        C.main()
    assert "contact_cost:" in str(e.value) and "\n" not in str(e.value)
