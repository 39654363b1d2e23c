"""The grid's exterior layer (``grid.exterior``): cells kept outside the physical faces, so a
particle domain next to a wall has nodes to reach while the face conditions stay on the user's
faces (as Uintah's extra cells).

* GIMP boxes pressed against a fixed and a slip wall run (without the layer their domains cross
  the grid's edge and the run is refused), and the wall nodes hold their condition exactly, the
  exterior nodes beyond them too;
* a one-cell, one-particle CPDI body translates rigidly past the grid's edge;
* without a layer the refusal says which face, by how much, and the ``grid.exterior`` that fixes it;
* ``"auto"`` adds no layer to a built-in scene (their bodies start away from the faces), and an
  explicit layer changes a run that never reaches it by round-off only;
* 1 and 2 ranks give the same particles bit for bit (mpirun).
"""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mpi_launch import mpirun, needs_mpi

import parmpm
from parmpm.transfer.discretisation import Discretisation, exterior_cells
from parmpm.core.errors import SceneError, SimulationError
from parmpm.driver.simulation import Simulation
from parmpm.scene.records import Grid

HERE = Path(__file__).parent
QUIET = ["output.snapshots=false", "output.figure=false"]

#: a neo-Hookean box in the grid's lower-left corner moving into it: x_min fixed, y_min slip
WALL_SCENE = """
dim = 2
[grid]
cell_size = 0.1
cells = [10, 10]
patch_size = 3
[materials.m]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e5
poisson_ratio = 0.3
[[bodies]]
min = [0.0, 0.0]
max = [0.4, 0.4]
material = "m"
ppc = 2
velocity = [-1.0, -0.5]
[method]
interpolator = "ugimp"
[boundary]
x_min = "fixed"
y_min = "slip"
[time]
steps = 20
"""

#: one particle filling the only cell of the grid, translating
ONE_CELL_SCENE = """
dim = 2
[grid]
cell_size = 1.0
cells = [1, 1]
[materials.m]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e5
poisson_ratio = 0.3
[[bodies]]
min = [0.0, 0.0]
max = [1.0, 1.0]
material = "m"
ppc = 1
velocity = [0.3, -0.2]
[method]
interpolator = "cpdi"
[time]
steps = 10
"""


def _scene(tmp_path, text, name, overrides=()):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return parmpm.load_scene(path, QUIET + list(overrides))


def _nodes(sim):
    """(global node index (n, 3), mass (n,), velocity (n, d)) of every node the local patches own,
    as the last grid update left them."""
    D, st = sim.state.disc, sim.state.stepper
    idx, mass, vel = [], [], []
    L = D.nloc
    for s in range(D.base.shape[0]):
        loc = np.stack(np.meshgrid(*[np.arange(D.own_lo[s, k], D.own_hi[s, k]) for k in range(3)],
                                   indexing="ij"), axis=-1).reshape(-1, 3)
        flat = loc[:, 0] + L[0] * (loc[:, 1] + L[1] * loc[:, 2])
        idx.append(loc + D.base[s])
        mass.append(st.grid.gm[s, flat, 0])
        vel.append(st.grid.gvel[s, flat])
    return np.concatenate(idx), np.concatenate(mass), np.concatenate(vel)


@pytest.mark.parametrize("exterior", ["auto", 3])
@pytest.mark.parametrize("method", ["ugimp", "cpgimp"])
def test_gimp_box_against_fixed_and_slip_walls(tmp_path, method, exterior):
    """GIMP domains straddle both walls (today's refusal); after every step the physical face
    nodes and every exterior node beyond them hold the condition exactly: v = 0 at and beyond the
    fixed x_min, v_y = 0 at and beyond the slip y_min (v_x free there); the exterior nodes carry
    mass."""
    sc = _scene(tmp_path, WALL_SCENE, "wall", [f"method.interpolator={method}",
                                                f"grid.exterior={json.dumps(exterior)}",
                                                "output.every_steps=1"])
    sim = Simulation(sc, tmp_path / "out", quiet=True)
    seen = {"steps": 0, "straddle_x": False, "straddle_y": False, "layer_x": False,
            "layer_y": False, "slip_moves": False}

    def check(sim):
        D, P = sim.state.disc, sim.particles
        half = P.lh0 * (np.abs(np.einsum("nii->ni", P.F)) if method == "cpgimp" else 1.0)
        g, m, v = _nodes(sim)
        on_x, on_y = g[:, 0] <= D.face_lo3[0], g[:, 1] <= D.face_lo3[1]
        if sim.nstep == 0:
            return
        assert np.all(v[on_x] == 0.0), sim.nstep
        assert np.all(v[on_y, 1] == 0.0), sim.nstep
        seen["steps"] += 1
        seen["straddle_x"] |= bool(np.any(P.x[:, 0] - half[:, 0] < 0.0))
        seen["straddle_y"] |= bool(np.any(P.x[:, 1] - half[:, 1] < 0.0))
        seen["layer_x"] |= bool(np.any((m > 0) & (g[:, 0] < D.face_lo3[0])))
        seen["layer_y"] |= bool(np.any((m > 0) & (g[:, 1] < D.face_lo3[1])))
        seen["slip_moves"] |= bool(np.any((m > 0) & on_y & ~on_x & (v[:, 0] != 0.0)))

    sim.observers.append(check)
    summary = sim.run()
    assert summary["steps"] == 20 and summary["stopped"] == "end"
    ghost = summary["grid"]["ghost"]
    pad = ghost if exterior == "auto" else exterior
    # auto: a layer only on the two faces the body touches, as wide as the ghost layer
    want = [[pad, pad], [0, 0]] if exterior == "auto" else [[pad, pad], [pad, pad]]
    assert summary["grid"]["cells"] == [10, 10] and summary["grid"]["exterior"] == want
    assert list(sim.state.disc.face_lo3[:2]) == [pad, pad]
    assert seen["steps"] == 20 and all(seen.values()), seen


def test_one_cell_cpdi_particle_translates_past_the_grid_edge(tmp_path):
    """A particle whose CPDI domain is the grid's only cell moves rigidly: its domain leaves the
    physical grid at once, and the layer holds it (x = x0 + v·t, F = I, to round-off)."""
    sim = Simulation(_scene(tmp_path, ONE_CELL_SCENE, "one"), tmp_path / "out", quiet=True)
    summary = sim.run()
    assert summary["steps"] == 10 and summary["grid"]["exterior"] == [[2, 2], [2, 2]]
    P = sim.particles
    t = summary["time"]
    assert 0.3 * t > 0.1  # the domain crossed the x_max face by more than a tenth of a cell
    np.testing.assert_allclose(P.x[0], [0.5 + 0.3 * t, 0.5 - 0.2 * t], rtol=0, atol=1e-14)
    np.testing.assert_allclose(P.v[0], [0.3, -0.2], rtol=0, atol=1e-14)
    np.testing.assert_allclose(P.F[0], np.eye(2), rtol=0, atol=1e-14)


@pytest.mark.parametrize("scene, override, message", [
    (WALL_SCENE, [], "crosses the x_min face by 0.00786 cells: set grid.exterior = 1 (cells kept "
                     "outside every face; the boundary conditions stay on the faces)"),
    (ONE_CELL_SCENE, [], "crosses the x_max face by 0.01 cells: set grid.exterior = 2 (cells "
                         "kept outside every face; the boundary conditions stay on the faces) or "
                         "add 1 cell on the x_max side (grid.cells, grid.origin)"),
    (ONE_CELL_SCENE, ["method.lcr=none", "grid.ghost=1"],
     "crosses the x_max face by 0.01 cells: set grid.exterior = 1 (cells kept outside every face; "
     "the boundary conditions stay on the faces) or add 1 cell on the x_max side (grid.cells, "
     "grid.origin)"),
])
def test_without_a_layer_the_error_names_face_and_fix(tmp_path, scene, override, message):
    """grid.exterior = 0 keeps today's grid: the refusal names the face crossed, by how much, and
    the layer that holds it (at a fixed wall only the layer: adding cells would move the wall)."""
    sc = _scene(tmp_path, scene, "no_layer", ["grid.exterior=0"] + override)
    with pytest.raises(SimulationError) as err:
        Simulation(sc, tmp_path / "out", quiet=True).run()
    text = str(err.value)
    assert "\n" not in text and "reaches outside the grid" in text
    assert text.endswith(message), text


@pytest.mark.parametrize("value", [-1, 65, 1.5, "wide"])
def test_bad_exterior_is_a_one_line_error(value):
    with pytest.raises(SceneError, match=r"grid\.exterior.*\"auto\" or an integer from 0 to 64"):
        parmpm.load_scene("hanging_bar", [f"grid.exterior={json.dumps(value)}"])


@pytest.mark.parametrize("name", parmpm.builtin_scenes())
def test_auto_adds_no_layer_to_builtin_scenes(name):
    """Every built-in scene's bodies start a cell or more from every face: "auto" gives them no
    layer, so they run on exactly the grid (and give exactly the results) they did before —
    but the manufactured solution, whose body fills the grid up to its mirror faces, and the
    vibrating bar, clamped at its x_min face (the layer holds the mirror image, parmpm.grid.symmetry)."""
    sc = parmpm.load_scene(name)
    assert sc.data["grid"]["exterior"] == "auto"
    for ghost in (1, 2, 3):
        lo, hi = exterior_cells(sc.spec.grid, sc.spec.bodies, ghost)
        if name == "manufactured":
            assert list(lo) == list(hi) == [ghost, ghost]
        elif name == "vibrating_bar":
            assert list(lo) == [ghost] and list(hi) == [0]
        else:
            assert not lo.any() and not hi.any(), (name, lo, hi)


def test_auto_pads_only_the_faces_a_body_comes_near():
    sc = parmpm.load_scene("hanging_bar", ["bodies.0.min=[-0.45, -1.0]", "bodies.0.max=[1.0, 0.15]"])
    lo, hi = exterior_cells(sc.spec.grid, sc.spec.bodies, 2)
    assert list(lo) == [2, 0] and list(hi) == [0, 2]
    wide = parmpm.load_scene("hanging_bar", ["grid.exterior=4"]).spec
    lo, hi = exterior_cells(wide.grid, wide.bodies, 2)
    assert list(lo) == [4, 4] and list(hi) == [4, 4]


def test_discretisation_keeps_the_physical_grid():
    grid = Grid(origin=(-0.5, -3.0), cell_size=(0.1, 0.2), cells=(20, 32), patch_size=(8, 8),
                ghost="auto", exterior="auto")
    D = Discretisation.from_grid(2, 0, None, grid, 2, (np.array([2, 1]), np.array([3, 0])))
    assert D.layout.cells == (25, 33) and list(D.cells) == [20, 32]
    np.testing.assert_allclose(D.physical_origin, [-0.5, -3.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(D.origin, [-0.7, -3.2], rtol=0, atol=1e-15)
    assert list(D.face_lo3) == [2, 1, 0] and list(D.face_hi3) == [22, 33, 0]


def test_a_layer_nobody_reaches_changes_round_off_only(tmp_path):
    """The hanging bar (a fixed support region, gravity) on a grid with a 2-cell layer on every
    face: the same motion to round-off (the origin moves by 2Δx, so the node positions round
    differently); its summary speaks of the physical grid."""
    runs = {}
    for ext in (0, 2):
        sim = Simulation(parmpm.load_scene("hanging_bar", QUIET + [f"grid.exterior={ext}",
                                                                   "time.steps=40"]),
                         tmp_path / f"e{ext}", quiet=True)
        summary = sim.run()
        order = np.argsort(sim.particles.gid)
        runs[ext] = summary, sim.particles.x[order], sim.particles.v[order]
    (s0, x0, v0), (s2, x2, v2) = runs[0], runs[2]
    assert s2["grid"]["cells"] == s0["grid"]["cells"] == [20, 32]
    assert s2["grid"]["exterior"] == [[2, 2], [2, 2]] and s0["grid"]["exterior"] == [[0, 0], [0, 0]]
    np.testing.assert_allclose(x2, x0, rtol=0, atol=1e-12)  # measured 8e-16 m
    np.testing.assert_allclose(v2, v0, rtol=0, atol=1e-12)  # measured 8e-14 (|v| up to 28 m/s)


@needs_mpi
def test_rank_independent_with_a_layer(tmp_path):
    """The wall scene (GIMP domains in the layer, patches of 3 cells) and the one-cell CPDI
    particle give the same particles bit for bit on 1 and 2 ranks."""
    cases = {}
    for name, text, over in (("wall_ugimp", WALL_SCENE, []),
                             ("wall_cpgimp", WALL_SCENE, ["method.interpolator=cpgimp"]),
                             ("one_cell", ONE_CELL_SCENE, ["grid.patch_size=1"])):
        path = tmp_path / f"{name}.toml"
        path.write_text(text)
        cases[name] = [str(path), QUIET + over]
    spec = tmp_path / "cases.json"
    spec.write_text(json.dumps(cases))
    got = {}
    for n in (1, 2):
        folder = tmp_path / f"np{n}"
        folder.mkdir()
        proc = subprocess.run([mpirun(), "-n", str(n), sys.executable, str(HERE.parents[1] / "run_scripts" / "tools" / "save_final_states.py"),
                               str(folder), str(spec)], capture_output=True, text=True, timeout=400)
        assert proc.returncode == 0, f"{n} ranks failed:\n{proc.stderr[-3000:]}"
        got[n] = folder
    for name in cases:
        a, b = (np.load(got[n] / f"{name}.npz") for n in (1, 2))
        sa, sb = (json.loads(str(z["summary"])) for z in (a, b))
        assert sa["steps"] > 0 and sa["ranks"] == 1 and sb["ranks"] == 2
        assert sb["decomposition"]["patches_per_rank"][1] > 0  # both ranks hold patches
        for k in ("gid", "x", "v", "F", "stress"):
            np.testing.assert_array_equal(a[k], b[k], err_msg=f"{name}: {k}")
        assert sa["final"] == sb["final"]
