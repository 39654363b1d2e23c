"""The mirror faces' reaction (``mirror.force_*``, ``mirror.impulse_*``: symmetry and clamped
faces, :func:`parmpm.output.reactions.mirror_row`), which the momentum balance gives: a body
resting on a mirror floor is held up by its weight, a body falling free of every face gets no
mirror impulse, and the columns are written only where the balance holds them alone."""
import numpy as np
import pytest

from parmpm.core.errors import SceneError
from parmpm.driver.simulation import Simulation
from parmpm.io.history_file import read_history
from parmpm.scene.load import scene_from_toml

BLOCK = '''
name = "rest"
dim = 2
[grid]
cell_size = 0.05
cells = [8, 8]
[materials.rubber]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e5
poisson_ratio = 0.3
[[bodies]]
min = [0.1, {y0}]
max = [0.3, {y1}]
material = "rubber"
[gravity]
g = [0.0, -10.0]
ramp_time = {ramp}
[boundary]
y_min = "{floor}"
[time]
end = {end}
[output]
snapshots = false
figure = false
[output.history]
every_steps = 1
'''


def _run(tmp_path, name, **kw):
    args = dict(y0=0.0, y1=0.2, ramp=0.2, floor="symmetry", end=1.0) | kw
    out = tmp_path / name
    Simulation(scene_from_toml(BLOCK.format(**args)), out, quiet=True).run()
    return read_history(out / "history.csv")


def test_a_body_resting_on_a_mirror_floor_is_held_by_its_weight(tmp_path):
    """After the ramp the floor's mean force over the rest of the run is the weight (the body
    oscillates about its static state; measured 0.9998 of it)."""
    h = _run(tmp_path, "rest")
    weight = 10.0 * h["mass"][0]
    t, impulse = h["time"], h["mirror.impulse_y"]
    i = int(np.searchsorted(t, 0.4))
    assert (impulse[-1] - impulse[i]) / (t[-1] - t[i]) == pytest.approx(weight, rel=0.01)
    assert np.all(h["mirror.impulse_x"] == pytest.approx(0.0, abs=1e-9 * weight))


def test_a_falling_body_gets_no_mirror_impulse(tmp_path):
    """Free fall well above the mirror: the balance closes without it (to round-off)."""
    h = _run(tmp_path, "fall", y0=0.2, y1=0.35, ramp=0.0, end=0.05)
    scale = 10.0 * h["mass"][0] * h["time"][-1]
    assert np.abs(h["mirror.impulse_y"]).max() < 1e-12 * scale
    assert h["momentum_y"][-1] == pytest.approx(-scale, rel=1e-12)


def test_mirror_columns_only_where_the_balance_holds(tmp_path):
    """Held faces have their own columns; damping would be in the balance: no mirror column."""
    assert "mirror.impulse_y" not in _run(tmp_path, "held", floor="slip", end=0.01)
    text = BLOCK.format(y0=0.0, y1=0.2, ramp=0.2, floor="symmetry", end=0.01)
    damped = scene_from_toml(text + "[damping]\ncoefficient = 1.0\n")
    Simulation(damped, tmp_path / "damped", quiet=True).run()
    assert "mirror.impulse_y" not in read_history(tmp_path / "damped" / "history.csv")


def test_a_wall_named_mirror_is_refused():
    text = BLOCK.format(y0=0.0, y1=0.2, ramp=0.2, floor="symmetry", end=0.01)
    wall = '[[walls]]\nname = "mirror"\npoint = [0.0, 0.38]\nnormal = [0.0, -1.0]\n'
    with pytest.raises(SceneError, match='"mirror" gives the column "mirror.force_x"'):
        scene_from_toml(text + wall)
