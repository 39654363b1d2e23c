"""The plastic materials' scene keys (issue 42, item 5): a j2 or drucker_prager material resolves
with every key of its model and hardening law filled in, its record carries them, and the
resolved scene reads back as it was. The bad values are in ``tests/scene/test_bad_inputs.py``
(``test_issue42_plastic_keys_are_one_line``)."""
import dataclasses
from pathlib import Path

import pytest

from parmpm.materials import MODELS, PLASTIC_MODELS
from parmpm.materials.plasticity.drucker_prager import MATCHINGS
from parmpm.materials.plasticity.hardening import HARDENING
from parmpm.scene import reference
from parmpm.scene.load import builtin_scenes, load_scene, scene_from_toml
from parmpm.scene.materials import (DRUCKER_PRAGER_KEYS, HARDENING_KEYS, J2_KEYS, MATERIAL_KEYS,
                                    MODEL_KEYS)
from parmpm.scene.records import Material

ELASTIC = {"density": 7800.0, "youngs_modulus": 2e11, "poisson_ratio": 0.3}
PLASTIC_FIELDS = ("yield_stress", "hardening", "hardening_modulus", "hardening_exponent",
                  "strength_coefficient", "rate_coefficient", "reference_rate", "friction_angle",
                  "dilatancy_angle", "cohesion", "matching", "tension_cutoff",
                  "volume_correction", "friction_angle_2", "inertial_number_0", "grain_diameter",
                  "grain_density")


def inline(model: str, **keys) -> str:
    """``materials.bar={...}``: hanging_bar's material replaced by ``model`` with ``keys``."""
    items = {"model": model, **ELASTIC, **keys}
    text = ", ".join(f'{k} = "{v}"' if isinstance(v, str) else
                     f"{k} = {str(v).lower()}" if isinstance(v, bool) else f"{k} = {v!r}"
                     for k, v in items.items())
    return f"materials.bar={{{text}}}"


@pytest.mark.parametrize("model,given,resolved", [
    ("j2", dict(yield_stress=250e6),  # linear, perfectly plastic: H = 0
     dict(yield_stress=250e6, hardening="linear", hardening_modulus=0.0)),
    ("j2", dict(yield_stress=250e6, hardening_modulus=2e9),
     dict(yield_stress=250e6, hardening="linear", hardening_modulus=2e9)),
    ("j2", dict(yield_stress=250e6, hardening="swift", strength_coefficient=600e6,
                hardening_exponent=0.2),
     dict(yield_stress=250e6, hardening="swift", strength_coefficient=600e6,
          hardening_exponent=0.2)),
    ("j2", dict(yield_stress=250e6, hardening="swift", strength_coefficient=100e6,
                hardening_exponent=1),  # σ_y0 > A: ε0 = 2.5, finite and positive
     dict(yield_stress=250e6, hardening="swift", strength_coefficient=100e6,
          hardening_exponent=1.0)),
    ("j2", dict(yield_stress=250e6, hardening="johnson_cook", hardening_exponent=0.5),
     dict(yield_stress=250e6, hardening="johnson_cook", hardening_modulus=0.0,
          hardening_exponent=0.5, rate_coefficient=0.0, reference_rate=1.0)),
    ("j2", dict(yield_stress=250e6, hardening="johnson_cook", hardening_modulus=300e6,
                hardening_exponent=0.3, rate_coefficient=0.02, reference_rate=1e-3),
     dict(yield_stress=250e6, hardening="johnson_cook", hardening_modulus=300e6,
          hardening_exponent=0.3, rate_coefficient=0.02, reference_rate=1e-3)),
    ("drucker_prager", dict(friction_angle=30),  # c = 0: sand; no cut-off given: the apex
     dict(friction_angle=30.0, dilatancy_angle=0.0, cohesion=0.0, matching="plane_strain",
          tension_cutoff=None, volume_correction=False)),
    ("drucker_prager", dict(friction_angle=0, cohesion=1e4),  # von Mises-like: no apex
     dict(friction_angle=0.0, dilatancy_angle=0.0, cohesion=1e4, matching="plane_strain",
          tension_cutoff=None, volume_correction=False)),
    ("drucker_prager", dict(friction_angle=35.0, dilatancy_angle=5, cohesion=2e4,
                            matching="outer", tension_cutoff=1e4),
     dict(friction_angle=35.0, dilatancy_angle=5.0, cohesion=2e4, matching="outer",
          tension_cutoff=1e4, volume_correction=False)),
    ("drucker_prager", dict(friction_angle=30.0, cohesion=1e4, matching="inner",
                            tension_cutoff=0),
     dict(friction_angle=30.0, dilatancy_angle=0.0, cohesion=1e4, matching="inner",
          tension_cutoff=0.0, volume_correction=False)),
    ("drucker_prager", dict(friction_angle=19.8, volume_correction=True),
     dict(friction_angle=19.8, dilatancy_angle=0.0, cohesion=0.0, matching="plane_strain",
          tension_cutoff=None, volume_correction=True)),
    ("drucker_prager", dict(friction_angle=19.8, friction_angle_2=31, inertial_number_0=0.279,
                            grain_diameter=1.25e-3),  # mu(I): the grains' density defaults
     dict(friction_angle=19.8, dilatancy_angle=0.0, cohesion=0.0, matching="plane_strain",
          tension_cutoff=None, volume_correction=False, friction_angle_2=31.0,
          inertial_number_0=0.279, grain_diameter=1.25e-3, grain_density=None)),
    ("drucker_prager", dict(friction_angle=19.8, friction_angle_2=31, inertial_number_0=1,
                            grain_diameter=1e-3, grain_density=2700, volume_correction=True),
     dict(friction_angle=19.8, dilatancy_angle=0.0, cohesion=0.0, matching="plane_strain",
          tension_cutoff=None, volume_correction=True, friction_angle_2=31.0,
          inertial_number_0=1.0, grain_diameter=1e-3, grain_density=2700.0)),
])
def test_a_plastic_material_resolves_with_its_defaults(model, given, resolved):
    """Every key of the model (and of its hardening law) in the resolved scene, floats as
    floats; the record carries them and None for the keys the model does not use; the
    resolved scene read back gives the same data and records."""
    scene = load_scene("hanging_bar", [inline(model, **given)])
    data = scene.data["materials"]["bar"]
    assert data == {"model": model, **ELASTIC, **resolved}
    assert all(type(v) is type(resolved[k]) for k, v in data.items() if k in resolved)
    record = scene.spec.materials["bar"]
    for name in PLASTIC_FIELDS:
        assert getattr(record, name) == resolved.get(name), name
    assert record.damage is None and record.model == model
    again = scene_from_toml(scene.to_toml(), "again.toml")
    assert again.data == scene.data and again.spec == scene.spec
    assert again.spec.materials["bar"] == record


def test_an_elastic_material_is_resolved_as_before():
    """No plastic key in an elastic material's resolved table (older resolved scenes and
    checkpoints stay as they were); its record has None for every plastic field."""
    for name in builtin_scenes():
        scene = load_scene(name)
        for mat, record in scene.spec.materials.items():
            table = scene.data["materials"][mat]
            assert set(table) <= {"model", "density", "youngs_modulus", "poisson_ratio", "damage"}
            assert all(getattr(record, f) is None for f in PLASTIC_FIELDS), (name, mat)
    assert [f.name for f in dataclasses.fields(Material)][5:] == list(PLASTIC_FIELDS)


def test_the_key_lists_follow_the_registries():
    assert set(MODEL_KEYS) == set(MODELS) | set(PLASTIC_MODELS)  # a new model needs its keys
    assert set(HARDENING_KEYS) == set(HARDENING)
    assert set().union(*HARDENING_KEYS.values()) == set(J2_KEYS) - {"yield_stress", "hardening"}
    assert set(J2_KEYS) | set(DRUCKER_PRAGER_KEYS) <= set(MATERIAL_KEYS)
    assert set(J2_KEYS) | set(DRUCKER_PRAGER_KEYS) == set(PLASTIC_FIELDS)


def test_the_scene_reference_documents_every_plastic_key():
    doc = " ".join(reference.__doc__.split())
    for key in (*J2_KEYS, *DRUCKER_PRAGER_KEYS):
        assert f"``{key}`` (" in doc, key
    for name in PLASTIC_MODELS:
        assert f'``model = "{name}"``' in doc, name
    assert " | ".join(f'"{n}"' for n in HARDENING) in doc
    assert " | ".join(f'"{n}"' for n in MATCHINGS) in doc


def test_the_plasticity_page_example_resolves(tmp_path):
    """docs/concepts/plasticity.md's materials, given to two bodies of a minimal scene."""
    page = (Path(__file__).resolve().parents[2] / "docs" / "concepts" / "plasticity.md").read_text(
        encoding="utf-8")
    example = page.split("## Scene keys", 1)[1].split("```toml\n", 1)[1].split("```", 1)[0]
    path = tmp_path / "plastic.toml"
    path.write_text("dim = 2\n[grid]\ncell_size = 0.1\ncells = [20, 20]\n" + example
                    + "[[bodies]]\nmin = [0.2, 0.2]\nmax = [0.8, 0.8]\nmaterial = 'steel'\n"
                    "[[bodies]]\nmin = [1.2, 1.2]\nmax = [1.8, 1.8]\nmaterial = 'sand'\n"
                    "[time]\nend = 0.1\n", encoding="utf-8")
    materials = load_scene(path).spec.materials
    assert materials["steel"].hardening == "swift" and materials["steel"].rate_coefficient is None
    assert materials["sand"].matching == "plane_strain" and materials["sand"].tension_cutoff is None
