"""The 3D yardstick (``run_scripts/benchmarks/yardstick3d.py``) takes a true step: a linear
velocity field (a stretch and a shear) gives every interior particle ``F = I + Δt L`` with the
field's own gradient, and a translating block stays at ``F = I``, for CPDI1 and the linear hat,
so the throughput it is held against is that of the right algorithm."""
import numpy as np
import pytest
from benchmarks import yardstick3d as Y


@pytest.mark.parametrize("method", ["cpdi", "hat"])
def test_a_linear_velocity_field_gives_its_gradient(method):
    s = Y.setup(3e3)
    x = s["x"]
    centre = x.mean(axis=1)
    s["v"][:] = 0.0
    s["v"][0] = 0.1 * (x[0] - centre[0])     # ∂v_x/∂x = 0.1
    s["v"][1] = -0.05 * (x[2] - centre[2])   # ∂v_y/∂z = -0.05
    dt = 1e-4
    Y.step(s, method, dt, 1.0)
    lo, hi = x.min(axis=1), x.max(axis=1)
    inner = np.all((x > lo[:, None] + 2.1 * Y.CELL) & (x < hi[:, None] - 2.1 * Y.CELL), axis=0)
    assert inner.sum() >= 27
    F = s["F"][:, inner]
    np.testing.assert_allclose(F[0], 1.0 + 0.1 * dt, rtol=0, atol=1e-15)
    np.testing.assert_allclose(F[5], -0.05 * dt, rtol=0, atol=1e-15)
    assert np.abs(F[[1, 2, 3, 6, 7]]).max() < 1e-15 and np.abs(F[[4, 8]] - 1.0).max() < 1e-15


@pytest.mark.parametrize("method", ["cpdi", "hat"])
def test_a_translating_block_stays_unstrained(method):
    s = Y.setup(3e3)
    x0 = s["x"].copy()
    for _ in range(3):
        Y.step(s, method, 1e-4, 0.95)
    assert np.abs(s["F"][[0, 4, 8]] - 1.0).max() < 1e-14 and np.abs(s["stress"]).max() < 1e-6
    moved = s["x"] - x0 - 3e-4 * np.array(Y.VELOCITY)[:, None]
    assert np.abs(moved).max() < 1e-15
