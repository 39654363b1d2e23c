"""Symmetry faces (``boundary.x_min = "symmetry"``, :mod:`parmpm.grid.symmetry`): a half body on a
mirror face moves exactly as the x > 0 half of the whole body; the energy ledger sees the half;
B-splines converge at second order on the manufactured solution with mirror faces (first order
with slip planes); a patch size that cuts a mirror pair is refused in one line."""
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from decomposition import world
from parmpm.output.energy import EnergyLedger
from parmpm.core.errors import SceneError
from parmpm.driver.set_up import set_up
from parmpm.scene.load import scene_from_toml

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "run_scripts"))

#: a neo-Hookean block squeezed along x (v_x = a·x, odd in x) and stretched along y under
#: gravity; ``{...}`` filled per case
BLOCK = """
name = "block"
dim = 2
[grid]
origin = [{x0}, 0.0]
cell_size = 0.1
cells = [{nx}, 14]
patch_size = {ps}
[materials.m]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e5
poisson_ratio = 0.3
[[bodies]]
min = [{bx}, 0.2]
max = [0.8, 1.0]
material = "m"
ppc = {ppc}
velocity = [{vx}, 0.0]
velocity_gradient = [[-2.0, 0.0], [0.0, 1.0]]
[method]
interpolator = "{method}"
{extra}
[gravity]
g = [0.0, -9.81]
[boundary]
x_min = "{x_min}"
[time]
steps = 10
[output]
snapshots = false
figure = false
"""


def _state(method, half, ppc=2, extra="", ps=8):
    text = BLOCK.format(x0=0.0 if half else -1.2, nx=12 if half else 24, bx=0.0 if half else -0.8,
                        vx=-0.8 if half else 0.0, x_min="symmetry" if half else "free",
                        method=method, ppc=ppc, extra=extra, ps=ps)
    return set_up(scene_from_toml(text, "<block>"), world())


def _advance(state, steps=12, dt=2e-4):
    ledger = EnergyLedger()
    state.stepper.ledger = ledger
    g = np.array([0.0, -9.81, 0.0])
    for n in range(steps):
        state.stepper.step(dt, g, n * dt)
    return ledger


def _by_x0(P):
    order = np.lexsort(P.x0.T[::-1])
    return {k: getattr(P, k)[order] for k in ("x0", "x", "v", "F", "stress")}


@pytest.mark.parametrize("method,extra", [("bspline", ""), ("bspline", 'transfer = "apic"'),
                                          ("cpdi", ""), ("ugimp", ""), ("mpm", "")])
def test_a_half_body_on_a_mirror_face_moves_as_the_whole(method, extra):
    """The whole block [-0.8, 0.8] (free faces, a node on x = 0) and its right half on a
    symmetry face at x = 0: after 12 steps every particle of the half has the position, velocity,
    F and stress of its twin in the whole to round-off (the sums are added in another order), and
    the ledger's grid work is half the whole's. A ``"slip"`` face, which holds the node beyond the
    face at v_x = 0, is visibly off for the B-spline (whose particles weight that node)."""
    whole, half = _state(method, False, extra=extra), _state(method, True, extra=extra)
    lw, lh = _advance(whole), _advance(half)
    W, H = _by_x0(whole.particles), _by_x0(half.particles)
    right = W["x0"][:, 0] > 0
    np.testing.assert_allclose(W["x0"][right], H["x0"], rtol=0, atol=1e-14)
    scale = {"x": 1.0, "v": 1.0, "F": 1.0, "stress": 1e5}
    for k in ("x", "v", "F", "stress"):
        np.testing.assert_allclose(H[k], W[k][right], rtol=0, atol=1e-12 * scale[k], err_msg=k)
    # the grid work of the forces, of gravity and of the boundary: the half's is half the whole's
    np.testing.assert_allclose(lh.totals[:2], 0.5 * lw.totals[:2], rtol=1e-9)
    assert abs(lh.totals[3] - 0.5 * lw.totals[3]) <= 1e-9 * abs(lw.totals[0])
    if method == "bspline" and not extra:
        slip = set_up(scene_from_toml(BLOCK.format(
            x0=0.0, nx=12, bx=0.0, vx=-0.8, x_min="slip", method=method, ppc=2, extra=extra,
            ps=8), "<block>"), world())
        _advance(slip)
        S = _by_x0(slip.particles)
        # measured 9.3e-4 m/s after 12 steps (the mirror: below 1e-12)
        assert np.max(np.abs(S["v"] - W["v"][right])) > 1e-4


def test_an_exterior_layer_wider_than_a_patch_can_mirror_is_refused():
    """Each patch folds its own partial sums, so its block (owned nodes and ghosts) must hold
    the mirror of every exterior node it holds: always true for the automatic layer (as wide as
    the ghost layer), not for a user's wide ``grid.exterior`` on small patches."""
    def scene(exterior, ps):
        text = BLOCK.format(x0=0.0, nx=12, bx=0.0, vx=0.0, x_min="symmetry", method="bspline",
                            ppc=2, extra="", ps=ps)
        return scene_from_toml(text.replace("cell_size = 0.1", f"cell_size = 0.1\nexterior = {exterior!r}".replace("'", '"')),
                               "<block>")
    with pytest.raises(SceneError, match=r"^scene '<block>': boundary\.x_min = \"symmetry\" reflects the "
                                         r'exterior layer into the patches that hold it, but a patch'
                                         r' of 3 cells with 1 ghost cells cannot hold the mirror of '
                                         r'an exterior layer of 4 cells; use a larger '
                                         r'grid\.patch_size or a narrower grid\.exterior$'):
        set_up(scene(4, 3), world())
    set_up(scene(4, 8), world())
    for ps in (1, 2, 3):
        set_up(scene("auto", ps), world())


def test_symmetry_and_clamped_are_boundary_kinds():
    with pytest.raises(SceneError, match=r'boundary\.x_min: expected one of "fixed", "slip", '
                                         r'"symmetry", "clamped", "free", got "mirror"'):
        scene_from_toml(BLOCK.format(x0=0.0, nx=12, bx=0.0, vx=0.0, x_min="mirror",
                                     method="mpm", ppc=2, extra="", ps=8), "<block>")


def _orders(dim, cells, method, faces, **kw):
    from study import manufactured_scene, run_case

    errs = [run_case(manufactured_scene(dim, c, method, faces=faces, **kw))[0]["metrics"]
            ["rms_error_max"] for c in cells]
    return errs, [math.log2(a / b) for a, b in zip(errs, errs[1:])]


def test_bspline_is_second_order_with_mirror_faces_and_first_with_slip_planes():
    """The manufactured solution in 2D at 8 → 16 → 32 cells (measured: symmetry faces 9.0e-3,
    2.2e-3, 5.6e-4, orders 2.04, 1.97; slip planes 2.9e-2 → 6.0e-3, orders 1.14, 1.13)."""
    errs, orders = _orders(2, (8, 16, 32), "bspline", "symmetry")
    assert min(orders) > 1.85, (errs, orders)
    slip, slip_orders = _orders(2, (8, 16, 32), "bspline", "slip_regions")
    assert max(slip_orders) < 1.3 and slip[-1] > 5 * errs[-1], (slip, slip_orders)


def test_bspline_in_1d_is_second_order_while_the_particles_cross_few_cells():
    """1D, amplitude 0.01 (a particle travels 0.64 cells at 64 cells): orders 2.04, 2.01
    measured. With the standard 0.05 the error stalls beyond 32 cells (README)."""
    errs, orders = _orders(1, (16, 32, 64), "bspline", "symmetry", amplitude=0.01)
    assert min(orders) > 1.9, (errs, orders)


#: a 1D bar squeezed and stretched by an odd velocity field v = a·x about x = 0
BAR_1D = """
name = "bar"
dim = 1
[grid]
origin = {x0}
cell_size = 0.1
cells = {nx}
patch_size = 6
[materials.m]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e5
poisson_ratio = 0.0
[[bodies]]
min = {bx}
max = 1.0
material = "m"
ppc = 3
velocity = {vx}
velocity_gradient = [[-3.0]]
[method]
interpolator = "{method}"
{extra}
[boundary]
x_min = "{x_min}"
[time]
steps = 10
[output]
snapshots = false
figure = false
"""


@pytest.mark.parametrize("method,extra", [("bspline", ""), ("bspline", 'transfer = "apic"'),
                                          ("cpdi", ""), ("ugimp", ""), ("mpm", "")])
def test_a_half_bar_on_a_clamped_face_moves_as_the_whole_odd_bar(method, extra):
    """In 1D the odd mirror is a body: the bar [-1, 1] with the odd velocity v = −3x (free ends,
    no gravity) keeps x = 0 at rest, and its right half on a ``"clamped"`` face at x = 0 moves as
    that half, to round-off, for every interpolator. (In 2D and 3D the odd extension of the grid
    fields is not the image of a body: it is a boundary condition exact to second order for a
    field that vanishes on the face, docs/symmetry.md.)"""
    def bar(half):
        text = BAR_1D.format(x0=0.0 if half else -1.5, nx=15 if half else 30,
                             bx=0.0 if half else -1.0, vx=-1.5 if half else 0.0,
                             x_min="clamped" if half else "free", method=method, extra=extra)
        return set_up(scene_from_toml(text, "<bar>"), world())
    whole, half = bar(False), bar(True)
    for s in (whole, half):
        for n in range(12):
            s.stepper.step(2e-4, np.zeros(3), n * 2e-4)
    W, H = _by_x0(whole.particles), _by_x0(half.particles)
    right = W["x0"][:, 0] > 0
    np.testing.assert_allclose(W["x0"][right], H["x0"], rtol=0, atol=1e-14)
    scale = {"x": 1.0, "v": 1.0, "F": 1.0, "stress": 1e5}
    for k in ("x", "v", "F", "stress"):
        np.testing.assert_allclose(H[k], W[k][right], rtol=0, atol=1e-12 * scale[k], err_msg=k)
    assert np.max(np.abs(H["v"])) > 1.0  # it moved
