"""The separation-count benchmark (``run_scripts/benchmarks/separation_cost.py``) times the default
scene (or its 3D twin) at the cell asked for, counts one piece of an intact bar, and refuses
nonsense in one line."""
import sys

import numpy as np
import pytest
from benchmarks import separation_cost as C

from decomposition import world
from parmpm.driver.set_up import set_up
from parmpm.scene.load import load_scene


def test_the_scene_is_the_default_one_at_the_cell_asked_for():
    default = set_up(load_scene("hanging_bar"), world())
    fine = set_up(C.scene(0.05), world())
    assert default.particles.n == 900 and fine.particles.n == 4 * 900
    for s, cell in ((default, 0.1), (fine, 0.05)):
        lo = s.particles.x.min(axis=0)
        hi = s.particles.x.max(axis=0)
        # the bar is the unit square below y = 0, seeded 3 a cell across in either scene
        np.testing.assert_allclose(lo, [cell / 6, -1.0 + cell / 6], rtol=0, atol=1e-12)
        np.testing.assert_allclose(hi, [1.0 - cell / 6, -cell / 6], rtol=0, atol=1e-12)


def test_the_3d_scene_at_its_own_cell_is_the_builtin_one():
    builtin = load_scene("hanging_bar_3d")
    assert C.scene(0.2, "hanging_bar_3d").spec.grid.cells == builtin.spec.grid.cells
    fine = C.scene(0.0667, "hanging_bar_3d")
    assert list(fine.spec.grid.cells) == [27, 48, 27]


@pytest.mark.parametrize("name, cell, particles", [("hanging_bar", "0.1", "900"),
                                                   ("hanging_bar_3d", "0.2", "3375")])
def test_it_runs_and_counts_one_piece(monkeypatch, capsys, name, cell, particles):
    monkeypatch.setattr(sys, "argv", ["separation_cost", "--scene", name, "--cells", cell,
                                      "--warm", "1", "--steps", "2", "--repeat", "1"])
    C.main()
    row = capsys.readouterr().out.splitlines()[-1].split()
    assert row[0] == cell and row[1] == particles and row[-1] == "1"
    assert float(row[2]) > 0 and float(row[3]) > 0


def test_the_default_scene_is_the_2d_bar(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["separation_cost", "--cells", "0.1", "--warm", "1",
                                      "--steps", "2", "--repeat", "1"])
    C.main()
    row = capsys.readouterr().out.splitlines()[-1].split()
    assert row[0] == "0.1" and row[1] == "900" and row[-1] == "1"
    assert float(row[2]) > 0 and float(row[3]) > 0


@pytest.mark.parametrize("bad", [["--steps", "0"], ["--repeat", "-1"], ["--cells", "nan"],
                                 ["--cells", "0"], ["--cells", "inf"], ["--cells", "0.5"],
                                 ["--warm", "0"], ["--cells", "0.2"],
                                 ["--scene", "hanging_bar_3d", "--cells", "0.3"]])
def test_nonsense_is_refused_in_one_line(monkeypatch, bad):
    monkeypatch.setattr(sys, "argv", ["separation_cost", *bad])
    with pytest.raises(SystemExit) as e:
        C.main()
    assert "separation_cost:" in str(e.value) and "\n" not in str(e.value)
