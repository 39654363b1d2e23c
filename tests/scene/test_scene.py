"""Scene loading, defaults, --set overrides, l_cr parsing, TOML round trip and error messages."""

import math

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from parmpm.core.errors import SceneError
from parmpm.scene.load import Scene, builtin_scenes, load_scene, parse_lcr, scene_from_toml

BUILTINS = ("hanging_bar", "hanging_bar_1d", "hanging_bar_3d", "vibrating_bar")

BASE = """\
dim = 2

[grid]
cell_size = 0.5
cells = [8, 8]

[materials.rubber]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e5
poisson_ratio = 0.3

[[bodies]]
min = [1.0, 1.0]
max = [2.0, 3.0]
material = "rubber"

[time]
end = 1.0
"""


def _write(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _round_trip(scene, tmp_path):
    return load_scene(_write(tmp_path, scene.to_toml(), "round_trip.toml"))


# ---------------------------------------------------------------- built-ins


def test_builtin_list():
    scenes = builtin_scenes()
    assert tuple(scenes) == tuple(sorted(scenes))
    assert set(BUILTINS) <= set(scenes)
    for description in scenes.values():
        assert description and "\n" not in description


@pytest.mark.parametrize("name", sorted(builtin_scenes()))
def test_builtin_loads_and_round_trips(name, tmp_path):
    scene = load_scene(name)
    assert isinstance(scene, Scene)
    assert scene.name == name
    assert scene.source == f"builtin:{name}"
    assert scene.data["description"]
    again = _round_trip(scene, tmp_path)
    assert again.data == scene.data
    assert again.lcr == scene.lcr
    assert scene_from_toml(scene.to_toml()).data == scene.data


def test_hanging_bar_resolved():
    scene = load_scene("hanging_bar")
    d = scene.data
    assert scene.dim == 2
    assert d["grid"] == {"origin": [-0.5, -3.0], "cell_size": [0.1, 0.1], "cells": [20, 32],
                         "patch_size": [8, 8], "ghost": "auto", "exterior": "auto"}
    assert d["boundary"] == {"x_min": "free", "x_max": "free", "y_min": "free", "y_max": "free",
                             "fixed_regions": [],  # the published roller: y held only
                             "slip_regions": [{"min": [-0.5, 0.0], "max": [1.5, 0.2], "normal": "y"}]}
    assert d["materials"]["bar"]["model"] == "neo_hookean"
    assert d["bodies"][0]["ppc"] == [3, 3]
    assert d["bodies"][0]["vibration"] is None
    assert d["method"] == {"interpolator": "cpdi", "lcr": "2dx", "update": "auto", "transfer": "flip",
                           "flip": 1.0}
    assert d["gravity"] == {"g": [0.0, -1000.0], "ramp_time": 0.0}
    assert d["time"] == {"end": 0.3, "steps": None, "cfl": 0.4, "dt_max": None, "dt": None,
                         "max_energy_growth": 1.0}
    assert d["output"]["every"] == 0.05
    assert d["metrics"] == {"kind": "hanging_bar", "every_steps": 1, "axis": 1,
                            "stop_on_separation": True, "grip": None}
    assert scene.min_dx == 0.1
    assert scene.lcr == pytest.approx(0.2)


def test_other_builtins_resolved():
    bar1 = load_scene("hanging_bar_1d").data
    assert bar1["bodies"][0]["min"] == [-1.0] and bar1["bodies"][0]["max"] == [0.0]
    assert bar1["boundary"] == {"x_min": "free", "x_max": "free",
                                "fixed_regions": [{"min": [0.0], "max": [0.2]}], "slip_regions": []}
    assert bar1["metrics"]["axis"] == 0
    bar3 = load_scene("hanging_bar_3d").data
    assert bar3["grid"]["cells"] == [9, 16, 9] and bar3["metrics"]["axis"] == 1
    assert bar3["boundary"]["slip_regions"][0]["min"][1] == 0.0 and len(bar3["boundary"]) == 8
    assert bar3["boundary"]["slip_regions"][0]["normal"] == "y"
    vib = load_scene("vibrating_bar").data
    assert vib["materials"]["bar"]["poisson_ratio"] == 0.0
    assert vib["bodies"][0]["vibration"] == {"amplitude": 0.1, "mode": 1, "axis": 0}
    assert vib["grid"]["cell_size"] == [25 / 16]
    assert vib["gravity"]["g"] == [0.0]
    assert vib["metrics"]["kind"] == "vibrating_bar"


# ---------------------------------------------------------------- defaults and overrides


def test_defaults(tmp_path):
    scene = load_scene(_write(tmp_path, BASE, "my_scene.toml"))
    d = scene.data
    assert scene.name == "my_scene" and d["description"] == ""
    assert scene.source.endswith("my_scene.toml")
    assert d["grid"]["origin"] == [0.0, 0.0]
    assert d["grid"]["cell_size"] == [0.5, 0.5]
    assert d["grid"]["patch_size"] == "auto"  # chosen at set-up (parmpm.scene.patch_size)
    assert d["bodies"][0]["shape"] == "box" and d["bodies"][0]["velocity"] == [0.0, 0.0]
    assert d["method"]["lcr"] == "2dx" and scene.lcr == pytest.approx(1.0)
    assert d["damping"] == {"coefficient": 0.0}
    assert d["output"] == {"every": 0.05, "every_steps": None, "snapshots": True, "figure": True,
                           "domains": True,
                           "history": {"enabled": True, "every": 0.005, "every_steps": None,
                                       "probes": []}}
    assert d["metrics"] == {"kind": "none", "every_steps": 1, "axis": 1, "stop_on_separation": False,
                            "grip": None}
    assert d["boundary"]["fixed_regions"] == []
    assert _round_trip(scene, tmp_path).data == d


def test_output_default_from_steps(tmp_path):
    scene = load_scene(_write(tmp_path, BASE), ["time.steps=100"])
    assert scene.data["time"]["steps"] == 100 and scene.data["time"]["end"] == 1.0
    assert scene.data["output"]["every_steps"] == 5  # steps given: max(1, steps // 20)
    assert scene.data["output"]["every"] is None
    scene = load_scene(_write(tmp_path, BASE.replace("end = 1.0", "steps = 30")))
    assert scene.data["time"]["end"] is None
    assert scene.data["output"] == {"every": None, "every_steps": 1, "snapshots": True,
                                    "figure": True, "domains": True,
                                    "history": {"enabled": True, "every": None, "every_steps": 1,
                                                "probes": []}}  # max(1, 30 // 200)
    assert _round_trip(scene, tmp_path).data == scene.data


def test_overrides():
    scene = load_scene("hanging_bar",
                       overrides=["method.interpolator=mpm", "bodies.0.ppc=3", "time.end=0.1"])
    d = scene.data
    assert d["method"]["interpolator"] == "mpm"
    assert d["method"]["lcr"] == "none" and scene.lcr is None
    assert d["bodies"][0]["ppc"] == [3, 3]
    assert d["time"]["end"] == 0.1
    # values parse as TOML; lists, new tables and element indices work
    scene = load_scene("hanging_bar", ["gravity.g=[0, -9.81]", "grid.cells.1=40",
                                       "damping.coefficient=2", "method.lcr=1.5dx/2",
                                       "output.snapshots=false", "name=bar run"])
    d = scene.data
    assert d["gravity"]["g"] == [0.0, -9.81]
    assert d["grid"]["cells"] == [20, 40]
    assert d["damping"]["coefficient"] == 2.0
    assert scene.lcr == pytest.approx(0.075)
    assert d["output"]["snapshots"] is False
    assert scene.name == "bar run"


def test_disk_and_sphere(tmp_path):
    text = BASE.replace("min = [1.0, 1.0]\nmax = [2.0, 3.0]",
                        'shape = "disk"\ncenter = [2.0, 2.0]\nradius = 0.5')
    scene = load_scene(_write(tmp_path, text))
    assert scene.data["bodies"][0] == {
        "shape": "disk", "center": [2.0, 2.0], "radius": 0.5, "material": "rubber",
        "ppc": [2, 2], "velocity": [0.0, 0.0], "vibration": None,
        "angular_velocity": None, "angle": None, "velocity_gradient": None,
        "seeding": "conforming"}
    assert _round_trip(scene, tmp_path).data == scene.data
    scene = load_scene("hanging_bar_3d", ['bodies.0={shape = "sphere", center = [0.5, -0.5, 0.5], '
                                          'radius = 0.5, material = "bar"}'])
    assert scene.data["bodies"][0]["shape"] == "sphere"
    assert scene.data["bodies"][0]["seeding"] == "conforming"  # shells, as the disk's rings


@pytest.mark.parametrize("body, seeding", [
    ('{shape = "cylinder", axis = "z", center = [0.5, -0.5, 0.5], radius = 0.3, length = 0.6, '
     'material = "bar"}', "conforming"),
    ('{shape = "difference", material = "bar", parts = [{shape = "cylinder", axis = "x", '
     'center = [0.5, -0.5, 0.5], radius = 0.3, length = 0.6}, {shape = "cylinder", axis = "x", '
     'center = [0.5, -0.5, 0.5], radius = 0.2, length = 0.6}]}', "conforming"),   # a tube
    ('{shape = "difference", material = "bar", parts = [{shape = "cylinder", axis = "x", '
     'center = [0.5, -0.5, 0.5], radius = 0.3, length = 0.6}, {shape = "cylinder", axis = "x", '
     'center = [0.5, -0.4, 0.5], radius = 0.1, length = 0.6}]}', "lattice"),  # off the axis
    ('{shape = "union", material = "bar", parts = [{shape = "sphere", center = [0.5, -0.5, 0.5], '
     'radius = 0.3}]}', "conforming"),
])
def test_round_bodies_default_to_conforming_and_read_back(body, seeding, tmp_path):
    """A cylinder, and a CSG body that is a tube or sphere, seed conforming by default; another
    CSG body the lattice (tests/particles/test_conforming_csg.py: which are round)."""
    scene = load_scene("hanging_bar_3d", [f"bodies.0={body}"])
    assert scene.data["bodies"][0]["seeding"] == seeding
    again = _round_trip(scene, tmp_path)
    assert again.data == scene.data and again.spec == scene.spec


# ---------------------------------------------------------------- l_cr


@pytest.mark.parametrize("spec, expected", [
    ("2dx", 0.2), ("1.8dx/3", 0.06), ("dx", 0.1), (" 2 dx ", 0.2), ("0.5dx", 0.05),
    (0.25, 0.25), (1, 1.0), ("none", None), ("None", None),
])
def test_parse_lcr(spec, expected):
    value = parse_lcr(spec, 0.1)
    if expected is None:
        assert value is None
    else:
        assert value == pytest.approx(expected)


@pytest.mark.parametrize("spec", ["", "2", "dx/", "-2dx", "0dx", "2dx/0", "2dy", "abc", 0.0,
                                  -1.0, True, math.inf, [2], "2dx/3/4"])
def test_parse_lcr_rejects(spec):
    with pytest.raises(SceneError, match="lcr"):
        parse_lcr(spec, 0.1)


@settings(max_examples=50, deadline=None)
@given(k=st.floats(1e-3, 1e3), n=st.floats(1e-3, 1e3), dx=st.floats(1e-3, 10.0))
def test_parse_lcr_property(k, n, dx):
    assert parse_lcr(f"{k!r}dx/{n!r}", dx) == pytest.approx(k * dx / n)


@settings(max_examples=50, deadline=None)
@given(text=st.text(max_size=40), material=st.text(min_size=1, max_size=10))
@example(text="", material="0\n")  # found by CI: a key with a trailing newline was left bare
def test_round_trip_any_strings(text, material, tmp_path_factory):
    """The emitter escapes every string (quotes, backslashes, control characters, unicode)."""
    scene = load_scene("hanging_bar")
    scene.data["description"] = text
    scene.data["materials"] = {material: scene.data["materials"]["bar"]}
    scene.data["bodies"][0]["material"] = material
    path = tmp_path_factory.mktemp("rt") / "s.toml"
    path.write_text(scene.to_toml(), encoding="utf-8")
    assert load_scene(path).data == scene.data


# ---------------------------------------------------------------- errors

# (description, TOML text or None for BASE, overrides, fragment the message must contain)
BAD = [
    ("unknown top-level key", "colour = 1\n" + BASE, (), "unknown key 'colour'"),
    ("unknown nested key", None, ["grid.cell=3"], "unknown key 'grid.cell'"),
    ("string for cells", None, ['grid.cells="10"'], "grid.cells"),
    ("float for an int key", None, ["grid.cells=[8, 2.5]"], "grid.cells"),
    ("bool for an int key", None, ["bodies.0.ppc=true"], "bodies.0.ppc"),
    ("negative density", None, ["materials.rubber.density=-1"], "materials.rubber.density"),
    ("zero youngs modulus", None, ["materials.rubber.youngs_modulus=0"],
     "materials.rubber.youngs_modulus"),
    ("poisson ratio 0.5", None, ["materials.rubber.poisson_ratio=0.5"],
     "materials.rubber.poisson_ratio"),
    ("cfl 1.0", None, ["time.cfl=1.0"], "time.cfl"),
    ("body outside grid", None, ["bodies.0.max=[2.0, 4.5]"], "bodies.0.max"),
    ("body min >= max", None, ["bodies.0.max=[0.5, 3.0]"], "bodies.0.max"),
    ("disk in 1D", 'dim = 1\n[grid]\ncell_size = 1.0\ncells = 4\n[materials.m]\n'
     'model = "linear_elastic"\ndensity = 1.0\nyoungs_modulus = 1.0\npoisson_ratio = 0.0\n'
     '[[bodies]]\nshape = "disk"\ncenter = 2.0\nradius = 1.0\nmaterial = "m"\n[time]\nsteps = 1\n',
     (), "bodies.0.shape"),
    ("unknown material", None, ["bodies.0.material=steel"], "bodies.0.material"),
    ("bad interpolator", None, ["method.interpolator=flip"], "method.interpolator"),
    ("bad lcr string", None, ["method.lcr=twodx"], "method.lcr"),
    ("lcr with mpm", None, ["method.interpolator=mpm", "method.lcr=2dx"], "method.lcr"),
    ("boundary for a missing axis", None, ["boundary.z_min=fixed"], "boundary.z_min"),
    ("bad boundary kind", None, ["boundary.x_min=glued"], "boundary.x_min"),
    ("missing dim", BASE.replace("dim = 2\n", ""), (), "dim"),
    ("bad dim", None, ["dim=4"], "dim"),
    ("missing time end/steps", BASE.replace("end = 1.0\n", ""), (), "time"),
    ("missing cell_size", BASE.replace("cell_size = 0.5\n", ""), (), "grid.cell_size"),
    ("missing material model", BASE.replace('model = "neo_hookean"\n', ""), (),
     "materials.rubber.model"),
    ("TOML syntax error", BASE + "oops = = 1\n", (), "TOML syntax error"),
    ("malformed --set", None, ["time.end"], "time.end"),
    ("--set past the array", None, ["bodies.4.ppc=2"], "bodies"),
    ("vector scalar in 2D", None, ["gravity.g=-9.81"], "gravity.g"),
    ("negative flip", None, ["method.flip=-0.5"], "method.flip"),
    ("ghost zero", None, ["grid.ghost=0"], "grid.ghost"),
    ("bodies as a table", BASE.replace("[[bodies]]", "[bodies]"), (), "bodies"),
    ("vibration on a disk", None, ['bodies.0={shape = "disk", center = [2.0, 2.0], radius = 0.5,'
                                   ' material = "rubber", vibration = {amplitude = 1.0}}'],
     "bodies.0.vibration"),
    ("infinite value", None, ["time.end=inf"], "time.end"),
]


@pytest.mark.parametrize("text, overrides, fragment", [b[1:] for b in BAD],
                         ids=[b[0] for b in BAD])
def test_bad_input(tmp_path, text, overrides, fragment):
    path = _write(tmp_path, BASE if text is None else text, "bad_scene.toml")
    with pytest.raises(SceneError) as info:
        load_scene(path, overrides)
    message = str(info.value)
    assert "\n" not in message
    assert "bad_scene.toml" in message
    assert fragment in message


def test_bad_input_messages_name_value_and_expectation(tmp_path):
    path = _write(tmp_path, BASE, "foo.toml")
    with pytest.raises(SceneError) as info:
        load_scene(path, ["grid.cells=[10, -1]"])
    assert f"scene '{path}': grid.cells: expected 2 positive integers, got [10, -1]" in str(
        info.value)
    with pytest.raises(SceneError, match=r"did you mean 'grid\.cells'"):
        load_scene(path, ["grid.cels=3"])
    with pytest.raises(SceneError, match="must be < 1"):
        load_scene(path, ["time.cfl=1.0"])


def test_missing_file_and_unknown_builtin(tmp_path):
    missing = tmp_path / "nope.toml"
    with pytest.raises(SceneError, match="nope.toml") as info:
        load_scene(missing)
    assert "\n" not in str(info.value)
    with pytest.raises(SceneError, match="not a built-in scene"):
        load_scene("no_such_scene")


def test_builtin_bad_override_names_builtin():
    with pytest.raises(SceneError, match=r"^scene 'builtin:hanging_bar': unknown key 'grid\.cell'"):
        load_scene("hanging_bar", ["grid.cell=3"])


def _key_paths(data, prefix=""):
    for key, value in data.items():
        path = f"{prefix}{key}"
        yield path
        if isinstance(value, dict):
            yield from _key_paths(value, path + ".")
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            yield from _key_paths(value[0], path + ".0.")


_PATHS = sorted(set(_key_paths(load_scene("vibrating_bar").data))
                | set(_key_paths(load_scene("hanging_bar").data)))
_VALUES = ["0", "-1", "2.5", "true", '"x"', "[]", "[1, 2]", "[1.0, -2.0, 3.0]", "{}", "{a = 1}",
           "nan", "none", "2dx", "[[1]]", "1e400", '"auto"', '"box"', "[true, false]"]


@settings(max_examples=300, deadline=None)
@given(scene=st.sampled_from(["hanging_bar", "vibrating_bar"]), key=st.sampled_from(_PATHS),
       value=st.sampled_from(_VALUES))
def test_fuzzed_overrides_raise_only_scene_errors(scene, key, value):
    """Any --set on any key either loads or raises a one-line SceneError (never a raw error)."""
    try:
        load_scene(scene, [f"{key}={value}"])
    except SceneError as exc:
        assert "\n" not in str(exc)
