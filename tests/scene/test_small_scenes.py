"""Small scenes on several ranks (issue 16): ``grid.patch_size = "auto"`` (the default) gives a
scene smaller than one default patch enough patches for a handful of ranks, chosen from the
scene alone so results stay the same bit for bit on any rank count; a run with more ranks than
patches holding particles warns once, naming the idle ranks and a computed fix
(:mod:`parmpm.scene.patch_size`)."""
import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from decomposition import PatchLayout
from parmpm.cli.bench import build_bench_scene
from parmpm.transfer.discretisation import Discretisation, exterior_cells
from parmpm.core.errors import SceneError
from parmpm.particles.locate import locate_patches
from parmpm.scene.patch_size import (MAX_DENSE_PATCHES, _rank_list, auto_patch_size, covered_patches,
                               floor_size, idle_ranks_warning)
from parmpm.driver.set_up import _patch_size
from parmpm.scene.load import scene_from_toml
from parmpm.particles.seeding import seed_bodies
from parmpm.shapes import INTERPOLATORS

HERE = Path(__file__).parent
FIELDS = ("gid", "x", "v", "F", "stress", "damage")

#: the minimal scene of docs/reference/scenes.md: 20 x 32 cells, a 10 x 10-cell box (one patch of the old default)
SMALL = """\
dim = 2
[grid]
cell_size = 0.1
cells = [20, 32]
[materials.rubber]
model = "neo_hookean"
density = 1050.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
[[bodies]]
min = [0.5, 0.5]
max = [1.5, 1.5]
material = "rubber"
velocity = [0.5, -0.3]
[gravity]
g = [0.0, -100.0]
[time]
steps = 25
[output]
snapshots = false
figure = false
history = false
"""


def _scene(overrides=(), text=SMALL):
    return scene_from_toml(text, "small.toml", list(overrides), default_name="small")


def _ghost(scene) -> int:
    interp = INTERPOLATORS[scene.data["method"]["interpolator"]]
    return interp.ghost_width(scene.lcr if interp.name == "cpdi" else None, scene.min_dx)


def _choose(scene) -> list[int]:
    g = _ghost(scene)
    return auto_patch_size(scene.spec, g, exterior_cells(scene.spec.grid, scene.spec.bodies, g))


class _Comm:
    """Just enough of a communicator for the choice: its rank and size."""

    def __init__(self, size):
        self.size = size

    def Get_rank(self):
        return 0

    def Get_size(self):
        return self.size


# ---------------------------------------------------------------- the rule


def test_small_scene_gets_several_patches_and_the_default_stays_auto():
    scene = _scene()
    assert scene.data["grid"]["patch_size"] == "auto"
    assert _scene(["grid.patch_size=auto"]).data == scene.data
    assert _choose(scene) == [8, 8]  # 64 and 32 (clipped to 20 x 32) hold it in one patch
    assert covered_patches(scene.spec, 8) == 4
    assert covered_patches(scene.spec, 32) == 1
    assert _scene(["grid.patch_size=32"]).data["grid"]["patch_size"] == [20, 32]  # clipped
    with pytest.raises(SceneError, match='grid.patch_size: expected "auto" or 2 positive'):
        _scene(["grid.patch_size=big"])


def test_choice_depends_on_the_scene_not_the_rank_count():
    for over in ([], ["bodies.0.max=[1.9, 3.1]"], ["grid.cells=[400, 400]"]):
        spec = _scene(over).spec
        g = _ghost(_scene(over))
        ext = exterior_cells(spec.grid, spec.bodies, g)
        chosen = [_patch_size(_Comm(n), spec, g, ext).patch_size for n in (1, 2, 3, 4, 7, 64)]
        assert all(c == chosen[0] for c in chosen), over
        assert list(chosen[0]) == auto_patch_size(spec, g, ext)
    explicit = _scene(["grid.patch_size=4"]).spec
    assert _patch_size(_Comm(3), explicit, 2, None) is explicit.grid


def test_large_scenes_keep_the_default_and_halving_stops_at_the_target():
    assert _choose(build_bench_scene(2, "cpdi", 1_000_000)) == [64, 64]
    assert _choose(build_bench_scene(3, "cpdi", 1_000_000)) == [16, 16, 16]
    # 100 x 100 cells of body: 4 patches of 64, 16 of 32 -> 32
    wide = _scene(["grid.cells=[200, 200]", "bodies.0.max=[10.5, 10.5]"])
    assert covered_patches(wide.spec, 64) < 16 <= covered_patches(wide.spec, 32)
    assert _choose(wide) == [32, 32]


def test_floor_follows_dimension_and_ghost_width():
    assert floor_size(1, 2) == 16 and floor_size(2, 2) == 8 and floor_size(3, 1) == 8
    assert floor_size(2, 4) == 16 and floor_size(2, 5) == 20
    assert _choose(_scene(["method.lcr=4dx"])) == [16, 16]   # ghost 4: 8-cell patches cost 18 %
    assert _choose(_scene(["method.interpolator=mpm"])) == [8, 8]
    one_d = _scene(["dim=1", "grid.cell_size=0.1", "grid.cells=200", "bodies.0.min=0.5",
                    "bodies.0.max=1.5", "bodies.0.velocity=0.5", "gravity.g=-100.0"])
    assert _choose(one_d) == [16]
    cube = build_bench_scene(3, "cpdi", 20_000)
    assert _choose(cube) == [8, 8, 8]


def test_a_small_body_in_a_huge_grid_keeps_large_patches():
    """Every rank indexes every patch of the bounding grid: halving stops before too many."""
    huge = _scene(["grid.cells=[2000, 2000]"])
    assert _choose(huge) == [16, 16]  # 125 x 125 patches of 16; 250 x 250 of 8 is too many
    assert (2000 // 16) ** 2 <= MAX_DENSE_PATCHES < (2000 // 8) ** 2


@pytest.mark.parametrize("over", [[], ["bodies.0.ppc=3"], ["grid.origin=[-0.013, 0.021]"],
                                  ["bodies.0.min=[0.8, 0.75]", "bodies.0.max=[1.6, 3.1]"],
                                  ["grid.exterior=2"], ["bodies.0.min=[0.0, 0.0]"]])
def test_covered_patches_are_the_seeded_ones_for_boxes(over):
    """Unturned boxes: the count is exact (seeding's coordinates and patch formula)."""
    scene = _scene(over)
    g = _ghost(scene)
    spec = scene.spec
    ext = exterior_cells(spec.grid, spec.bodies, g)
    seeds = seed_bodies(spec.grid, spec.bodies, {"rubber": 0})
    for size in (64, 32, 16, 8, 4, 2):
        grid = replace(spec.grid, patch_size=tuple(min(size, n) for n in spec.grid.cells))
        D = Discretisation.from_grid(2, 0, None, grid, g, ext)
        assert covered_patches(spec, size, ext) == np.count_nonzero(seeds.patch_counts(D)), size


def test_disks_and_turned_boxes_count_at_most_their_bounding_boxes():
    disk = _scene(["bodies.0={shape='disk', center=[1.0, 1.6], radius=0.55, material='rubber'}"])
    turned = _scene(["bodies.0.angle=30.0"])
    for scene in (disk, turned):
        spec = scene.spec
        seeds = seed_bodies(spec.grid, spec.bodies, {"rubber": 0})
        ext = exterior_cells(spec.grid, spec.bodies, 2)
        for size in (16, 8, 4):
            D = Discretisation.from_grid(2, 0, None, replace(spec.grid, patch_size=(size,) * 2),
                                         2, ext)
            where = np.zeros(seeds.n, np.int64)
            lay = D.layout
            locate_patches(2, seeds.x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                           lay.patches_per_axis, where, where)
            assert covered_patches(spec, size, ext) >= \
                np.unique(where).size
    assert _choose(disk) == [8, 8]


# ---------------------------------------------------------------- the idle-rank warning


def _counts(scene, size):
    g = _ghost(scene)
    spec = scene.spec
    grid = replace(spec.grid, patch_size=tuple(min(size, n) for n in spec.grid.cells))
    D = Discretisation.from_grid(2, 0, None, grid, g, exterior_cells(spec.grid, spec.bodies, g))
    return D, seed_bodies(spec.grid, spec.bodies, {"rubber": 0}).patch_counts(D)


def _warning(scene, size, ranks):
    D, counts = _counts(scene, size)

    def count_at(s):
        other, there = _counts(scene, s)
        return other.layout, there
    return idle_ranks_warning(D.layout, counts, ranks, 2, count_at)


def test_idle_rank_warning_names_the_ranks_and_a_computed_patch_size():
    scene = _scene()
    assert _warning(scene, 32, 3) == ("3 ranks and 1 patch holding particles: ranks 0, 2 have "
                                      "no work; set grid.patch_size = 8 (gives 4 patches)")
    assert _warning(scene, 32, 2) == ("2 ranks and 1 patch holding particles: rank 0 has no "
                                      "work; set grid.patch_size = 8 (gives 4 patches)")
    assert _warning(scene, 8, 3) is None and _warning(scene, 32, 1) is None
    # four patches of 36, 84, 84 and 196 particles: the Morton cut leaves a rank without
    assert _warning(scene, 8, 4) == ("4 ranks and 4 patches holding particles: rank 3 has no "
                                     "work; run on at most 3 ranks")
    # four of the six ranks have work: the advice says so, not "at most 3" alone (issue 28)
    assert _warning(scene, 8, 6) == ("6 ranks and 4 patches holding particles: ranks 3, 5 have "
                                     "no work (4 of 6 do); every rank has work on 3 ranks")


def test_idle_rank_warning_without_a_size_that_helps():
    tiny = _scene(["bodies.0.min=[0.85, 0.85]", "bodies.0.max=[1.15, 1.15]"])  # 3 x 3 cells
    line = _warning(tiny, 32, 3)
    assert line == ("3 ranks and 1 patch holding particles: ranks 0, 2 have no work; run on at "
                    "most 1 rank")
    assert "\n" not in line


def test_rank_list():
    assert _rank_list([1, 2]) == "1-2" and _rank_list([3]) == "3"
    assert _rank_list([0, 2, 3, 4, 7]) == "0, 2-4, 7"


def test_patch_layout_of_another_size():
    D, _ = _counts(_scene(), 32)
    other = D.with_patch_size(8)
    assert other.layout.patch_size == (8, 8) and other.layout.ghost == D.layout.ghost
    assert D.with_patch_size(64).layout.patch_size == (20, 32)
    assert isinstance(other.layout, PatchLayout) and np.array_equal(other.origin, D.origin)


# ---------------------------------------------------------------- under mpirun


def _launch(mpirun, ranks, folder, cases):
    folder.mkdir(parents=True)
    spec = folder / "cases.json"
    spec.write_text(json.dumps(cases))
    proc = subprocess.run([mpirun, "-n", str(ranks), sys.executable, str(HERE.parents[1] / "run_scripts" / "tools" / "save_final_states.py"),
                           str(folder), str(spec)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, f"{ranks} ranks failed:\n{proc.stderr[-3000:]}"
    return proc


def _load(folder, case):
    data = np.load(folder / f"{case}.npz")
    return {k: data[k] for k in FIELDS}, json.loads(str(data["summary"]))


def test_small_scene_on_two_ranks_uses_both_and_matches_one_rank(mpirun, tmp_path):
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    cases = {"small": [str(path), []]}
    for n in (1, 2):
        _launch(mpirun, n, tmp_path / f"np{n}", cases)
    ref, one = _load(tmp_path / "np1", "small")
    got, two = _load(tmp_path / "np2", "small")
    for s in (one, two):
        assert s["grid"]["patch_size"] == [8, 8] and s["decomposition"]["patch_size"] == [8, 8]
    per_rank = two["decomposition"]["particles_per_rank"]
    assert len(per_rank) == 2 and min(per_rank) > 0 and sum(per_rank) == one["particles"] == 400
    assert two["steps"] == one["steps"] == 25
    for k in FIELDS:
        np.testing.assert_array_equal(got[k], ref[k], err_msg=f"{k} differs on 2 ranks")
    assert two["final"] == one["final"]


def test_more_ranks_than_patches_warns_once_with_the_fix(mpirun, tmp_path):
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    proc = _launch(mpirun, 3, tmp_path / "np3",
                   {"explicit": [str(path), ["grid.patch_size=32", "time.steps=3"]]})
    lines = [ln for ln in proc.stderr.splitlines() if "no work" in ln]
    assert len(lines) == 1 and lines[0].startswith("[0/3]") and "WARNING" in lines[0], proc.stderr
    assert lines[0].endswith("3 ranks and 1 patch holding particles: ranks 0, 2 have no work; "
                             "set grid.patch_size = 8 (gives 4 patches)")
    _, summary = _load(tmp_path / "np3", "explicit")
    assert sorted(summary["decomposition"]["particles_per_rank"]) == [0, 0, 400]
