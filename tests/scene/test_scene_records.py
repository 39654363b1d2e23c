"""The scene as typed, frozen records (parmpm.scene.records): every key of the resolved scene
reaches a field, nothing in a record can change, and a misspelt field name in the code that
reads them is found by reading the source, before anything runs."""
import ast
import copy
import dataclasses
import pickle
import types
import typing
from collections.abc import Mapping
from pathlib import Path

import pytest

import parmpm
from parmpm.scene.load import scene_from_toml
from parmpm.scene.records import SceneSpec, Time, build

ROOT = Path(__file__).resolve().parents[2]

#: a 3D scene with the optional tables the built-in scenes leave out: a sphere spinning about a
#: vector with a velocity gradient, a turned box, damage that never freezes, APIC (no
#: method.flip), walls and loads with time functions (held node regions are refused with B-splines:
#: ``tests/grid/test_walls.py``), every kind of probe, explicit schedules
EVERYTHING = """
name = "everything"
dim = 3
[grid]
origin = [-0.5, -0.5, -0.5]
cell_size = 0.1
cells = [20, 20, 20]
patch_size = [8, 8, 8]
ghost = 2
exterior = 1
[materials.soft]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1e6
poisson_ratio = 0.3
[materials.soft.damage]
onset = 1.1
fracture = 1.5
softening = "exponential"
freeze = "never"
[materials.hard]
model = "linear_elastic"
density = 2000.0
youngs_modulus = 1e7
poisson_ratio = 0.2
[[bodies]]
shape = "sphere"
center = [0.5, 0.5, 0.5]
radius = 0.3
material = "soft"
ppc = [2, 2, 3]
velocity = [0.1, 0.0, 0.0]
angular_velocity = [0.0, 0.0, 1.0]
velocity_gradient = [[0.1, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, -0.1]]
[[bodies]]
min = [-0.4, -0.4, -0.4]
max = [0.0, 0.0, 0.0]
angle = 15.0
material = "hard"
[method]
interpolator = "bspline"
transfer = "apic"
update = "usl"
[gravity]
g = [0.0, 0.0, -9.81]
ramp_time = 0.01
[damping]
coefficient = 0.5
[boundary]
z_min = "fixed"
x_max = "slip"
[[walls]]
point = [0.0, 0.0, -0.45]
normal = [0.0, 0.1, 1.0]
friction = 0.3
velocity = [0.0, 0.0, 0.01]
time = {function = "table", points = [[0.0, 0.0], [0.05, 1.0]]}
[[loads]]
kind = "traction"
body = 1
region = {min = [-0.5, -0.5, -0.5], max = [1.5, 1.5, 1.5]}
value = [0.0, 0.0, 100.0]
time = {function = "smooth_step", duration = 0.02}
[[loads]]
name = "poke"
kind = "point"
at = [0.0, 0.0, 0.0]
value = [1.0, 0.0, 0.0]
[time]
end = 0.1
steps = 50
cfl = 0.3
dt_max = 1e-3
max_energy_growth = "off"
[output]
every = 0.01
figure = false
[output.history]
every_steps = 5
[[output.history.probes]]
name = "centre"
point = [0.5, 0.5, 0.5]
fields = ["u.x", "stress.zz"]
[[output.history.probes]]
name = "corner"
region = {min = [-0.4, -0.4, -0.4], max = [0.0, 0.0, 0.0]}
field = "J"
stats = ["max"]
[[output.history.probes]]
name = "ball"
body = 0
field = "damage"
[[output.history.probes]]
name = "steel"
material = "hard"
field = "v.z"
[metrics]
kind = "none"
[decomposition]
rebalance_threshold = 0.2
rebalance_cooldown = 10
[checkpoint]
every_steps = 10
every = 0.05
wall_minutes = 30.0
keep = 2
at_end = true
ranks_per_file = 4
"""


def _scenes():
    out = {name: parmpm.load_scene(name) for name in parmpm.builtin_scenes()}
    out["everything"] = scene_from_toml(EVERYTHING, "everything.toml")
    out["no history"] = parmpm.load_scene("hanging_bar", ["output.history=false",
                                                          "checkpoint.every_steps=5"])
    return out


SCENES = _scenes()


def _plain(value):
    """A record's value as the serialised form holds it: tuples as lists."""
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value


def _reaches(table: dict, record, path: str) -> None:
    """Every key of ``table`` (a part of the resolved scene) is a field of ``record`` holding the
    same value (derived from the dict: a key the records lack fails here)."""
    for key, value in table.items():
        where = f"{path}.{key}" if path else key
        if isinstance(record, Mapping):
            assert key in record, where
            got = record[key]
        else:
            assert key in {f.name for f in dataclasses.fields(record)}, where
            got = getattr(record, key)
        if isinstance(value, dict):
            _reaches(value, got, where)
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            assert isinstance(got, tuple) and len(got) == len(value), where
            for k, (item, rec) in enumerate(zip(value, got)):
                _reaches(item, rec, f"{where}.{k}")
        else:
            assert _plain(got) == value and type(_plain(got)) is type(value), where


def _values(record):
    """Every value held anywhere in a record (the records themselves included)."""
    yield record
    if isinstance(record, Mapping):
        for v in record.values():
            yield from _values(v)
    elif isinstance(record, tuple):
        for v in record:
            yield from _values(v)
    elif dataclasses.is_dataclass(record):
        for f in dataclasses.fields(record):
            yield from _values(getattr(record, f.name))


@pytest.mark.parametrize("name", list(SCENES))
def test_every_key_of_the_resolved_scene_reaches_a_record_field(name):
    scene = SCENES[name]
    _reaches(scene.data, scene.spec, "")


@pytest.mark.parametrize("name", list(SCENES))
def test_nothing_in_a_record_can_change(name):
    spec = SCENES[name].spec
    for value in _values(spec):
        assert not isinstance(value, (list, dict, set)), value
        if dataclasses.is_dataclass(value):
            first = dataclasses.fields(value)[0].name
            with pytest.raises(dataclasses.FrozenInstanceError):
                setattr(value, first, None)
            with pytest.raises((AttributeError, TypeError)):  # slots: no new attribute either
                value.misspelt = 1
    with pytest.raises(TypeError):
        spec.materials["new"] = next(iter(spec.materials.values()))


def test_the_records_read_back_and_compare_as_the_scene_does():
    scene = SCENES["everything"]
    again = scene_from_toml(scene.to_toml(), "again.toml")
    assert again.spec == scene.spec and again.data == scene.data
    assert pickle.loads(pickle.dumps(scene.spec)) == copy.deepcopy(scene.spec) == scene.spec
    spec = scene.spec
    assert spec.method.flip is None and spec.bodies[1].center is None
    assert spec.boundary.faces == (("free", "slip"), ("free", "free"), ("fixed", "free"))
    assert spec.lcr is None and spec.min_dx == 0.1 == scene.min_dx
    assert spec.bodies[0].bounds() == ([0.2, 0.2, 0.2], [0.8, 0.8, 0.8])
    bar = SCENES["hanging_bar"]  # cpdi, l_cr "2dx"
    assert bar.spec.lcr == bar.lcr == 2 * bar.min_dx


def test_a_key_without_a_field_is_a_type_error():
    time = dict(SCENES["hanging_bar"].data["time"])
    assert build(Time, time) == SCENES["hanging_bar"].spec.time
    with pytest.raises(TypeError, match="Time has no field for key"):
        build(Time, {**time, "cfl_max": 0.5})
    del time["cfl"]
    with pytest.raises(TypeError, match="cfl"):
        build(Time, time)


# ---------------------------------------------------------------- the readers: a lint

#: modules where a name ``spec`` is something else (importlib's module spec, the l_cr text)
OTHER_SPECS = ("parmpm/core/cache_key.py", "parmpm/scene/check.py")


def _steps(node: ast.AST) -> list:
    """The attribute chain ending at ``node`` from its root: ``spec.bodies[0].min`` gives
    ``[("name", "spec"), (".", "bodies"), ("[]", None), (".", "min")]``."""
    out = []
    while True:
        if isinstance(node, ast.Attribute):
            out.append((".", node.attr))
            node = node.value
        elif isinstance(node, ast.Subscript):
            out.append(("[]", None))
            node = node.value
        else:
            out.append(("name", getattr(node, "id", None)))
            return out[::-1]


def _item(hint):
    """What indexing a field of type ``hint`` gives: the record of ``tuple[Rec, ...]`` or
    ``Mapping[str, Rec]``."""
    args = typing.get_args(hint)
    if typing.get_origin(hint) is tuple and args and dataclasses.is_dataclass(args[0]):
        return args[0]
    if typing.get_origin(hint) is Mapping:
        return args[1]
    return None


def _record(hint):
    """The record a field of type ``hint`` holds (``Rec`` or ``Rec | None``), else the hint."""
    if dataclasses.is_dataclass(hint):
        return hint
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        return next((a for a in typing.get_args(hint) if dataclasses.is_dataclass(a)), hint)
    return hint


def _misspelt(steps: list) -> str | None:
    """The first name after ``spec`` in ``steps`` that the records do not have."""
    names = [name for _, name in steps]
    if "spec" not in names:
        return None
    kind, current = None, SceneSpec
    for kind, name in steps[names.index("spec") + 1:]:
        if kind == "[]":
            current = _item(current)
        elif dataclasses.is_dataclass(current):
            hints = typing.get_type_hints(current)
            if name in {f.name for f in dataclasses.fields(current)}:
                current = _record(hints[name])
            elif hasattr(current, name):  # a property or method (bounds, lcr, faces)
                return None
            else:
                return f"{current.__name__}.{name}"
        else:
            return None  # past the records: a value (a tuple's .index, a str's .upper)
        if current is None:
            return None
    return None


def test_the_code_reads_only_fields_the_records_have():
    """Every ``spec.a.b...`` chain in parmpm/ names fields (or properties) of
    :class:`parmpm.scene.records.SceneSpec` and its records: a misspelt name fails here, in the
    source, not as an AttributeError deep in a run."""
    found, wrong = 0, []
    for path in sorted((ROOT / "parmpm").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        if rel in OTHER_SPECS:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Attribute):
                steps = _steps(node)
                found += ("name", "spec") in steps or (".", "spec") in steps
                bad = _misspelt(steps)
                if bad:
                    wrong.append(f"{rel}:{node.lineno}: {bad}")
    assert found > 50  # the lint sees the readers
    assert not sorted(set(wrong)), sorted(set(wrong))


def test_the_lint_finds_a_misspelt_name():
    tree = ast.parse("sim.spec.time.cfll + spec.bodies[0].vibration.mode + spec.materials['a'].rho")
    bad = {_misspelt(_steps(n)) for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
    assert {"Time.cfll", "Material.rho"} <= bad and "Vibration.mode" not in bad
