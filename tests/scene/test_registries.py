"""The registries of interpolators, material models and metrics kinds: the scene schema reads its
names from them, the help texts and the README show them, and reading a scene compiles nothing."""

import subprocess
import sys
from pathlib import Path

import pytest

import parmpm
from parmpm.scene import reference as scene_module
from parmpm.core.errors import SceneError
from parmpm.materials import MODELS
from parmpm.output.metrics import (METRIC_KINDS, NO_METRICS, make_metrics, metric_names, register_metrics,
                            separation_kinds)
from parmpm.shapes import (BSPLINE, CPDI, CPDI2, CPGIMP, INTERPOLATORS, MPM, UGIMP,
                           UNBOUNDED_DEFAULT_GHOST, interpolator_names, interpolator_table)

ROOT = Path(__file__).resolve().parents[2]


def test_reading_a_scene_loads_no_numba():
    """``import parmpm.scene.schema`` / ``parmpm.scene.load`` and resolving every built-in scene
    (damage, metrics, every interpolator) leave numba unloaded."""
    code = (
        "import sys\n"
        "import parmpm.scene.schema, parmpm.scene.load, parmpm.shapes, parmpm.output.metrics, parmpm.materials\n"
        "assert 'numba' not in sys.modules, 'import'\n"
        "for name in parmpm.scene.load.builtin_scenes():\n"
        "    for interp in parmpm.shapes.INTERPOLATORS:\n"
        "        parmpm.scene.load.load_scene(name, [f'method.interpolator={interp}', 'boundary.regions_with_splines=true'])\n"
        "assert 'numba' not in sys.modules, 'load_scene'\n"
        "print('ok')\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr[-2000:]


# --- interpolators -------------------------------------------------------------------------------
def test_interpolator_codes_are_the_kernels_codes():
    from parmpm.shapes import support

    codes = [i.code for i in INTERPOLATORS.values()]
    assert len(set(codes)) == len(codes)
    assert (support.MPM, support.CPGIMP, support.CPDI) == (MPM, CPGIMP, CPDI)  # the registry's
    assert {n: i.code for n, i in INTERPOLATORS.items()} == {"mpm": MPM, "ugimp": UGIMP,
                                                             "cpgimp": CPGIMP, "cpdi": CPDI,
                                                             "bspline": BSPLINE, "cpdi2": CPDI2}
    for name, interp in INTERPOLATORS.items():
        assert interp.name == name and interp.summary and interp.weight


@pytest.mark.parametrize("lcr, min_dx, cpdi", [(None, 0.5, UNBOUNDED_DEFAULT_GHOST), (1.0, 0.5, 2),
                                                (0.6, 1.0, 1), (1.5, 0.5, 3), (0.75, 0.25, 3)])
def test_ghost_widths(lcr, min_dx, cpdi):
    widths = {n: i.ghost_width(lcr, min_dx) for n, i in INTERPOLATORS.items()}
    assert widths == {"mpm": 0, "ugimp": 1, "cpgimp": UNBOUNDED_DEFAULT_GHOST, "cpdi": cpdi,
                      "bspline": 1, "cpdi2": cpdi}
    for interp in INTERPOLATORS.values():
        if not interp.bounded:
            assert interp.ghost_width(lcr, min_dx) == UNBOUNDED_DEFAULT_GHOST


@pytest.mark.parametrize("name", list(INTERPOLATORS))
def test_schema_accepts_every_registered_interpolator(name):
    assert parmpm.load_scene("hanging_bar", [f"method.interpolator={name}",
                                             "boundary.regions_with_splines=true"]).data["method"][
        "interpolator"] == name


def test_schema_names_the_registered_choices():
    with pytest.raises(SceneError) as err:
        parmpm.load_scene("hanging_bar", ["method.interpolator=teapot"])
    assert "one of " + ", ".join(f'"{n}"' for n in INTERPOLATORS) in str(err.value)
    with pytest.raises(SceneError) as err:
        parmpm.load_scene("hanging_bar", ["materials.rubber.model=teapot"])
    assert "one of " + ", ".join(f'"{n}"' for n in MODELS) in str(err.value)
    with pytest.raises(SceneError) as err:
        parmpm.load_scene("hanging_bar", ["metrics.kind=teapot"])
    assert "one of " + ", ".join(f'"{n}"' for n in metric_names()) in str(err.value)


# --- metrics -------------------------------------------------------------------------------------
def test_metric_kinds_load_their_classes():
    from parmpm.output.metrics import METRICS

    assert metric_names() == (*METRIC_KINDS, NO_METRICS)
    assert set(METRICS) == set(METRIC_KINDS)
    for name, entry in METRIC_KINDS.items():
        cls = METRICS[name]
        assert cls.__name__ == entry.cls and cls.kind == name and entry.summary
        assert cls.needs_components is entry.counts_pieces
    assert separation_kinds() == tuple(k for k, e in METRIC_KINDS.items() if e.counts_pieces)


def test_an_unregistered_metrics_class_is_refused():
    with pytest.raises(TypeError, match="does not name"):
        @register_metrics("teapot")
        class Teapot:
            pass
    with pytest.raises(TypeError, match="does not name"):
        @register_metrics("hanging_bar")
        class HangingBarMetrics:  # the registered name, but not the registered module
            pass


def test_stop_on_separation_only_for_the_kinds_that_count_pieces():
    for name in METRIC_KINDS:
        over = [f"metrics.kind={name}", "metrics.stop_on_separation=true"]
        if name == "tension_bar":
            continue  # needs grips; hanging_bar stands for the kinds that count pieces
        if name in separation_kinds():
            assert parmpm.load_scene("hanging_bar", over).data["metrics"]["stop_on_separation"]
        else:
            with pytest.raises(SceneError, match="metrics track separation"):
                parmpm.load_scene("hanging_bar", over)


def test_make_metrics_none():
    spec = parmpm.load_scene("hanging_bar", ["metrics.kind=none"]).spec
    assert make_metrics(spec, None, None) is None


# --- documentation -------------------------------------------------------------------------------
def _words(text: str) -> str:
    return " ".join(text.split())


def test_scene_reference_lists_the_registered_names():
    doc = _words(scene_module.__doc__)
    assert "``interpolator`` (" + " | ".join(f'"{n}"' for n in INTERPOLATORS) in doc
    assert "``model`` (" + " | ".join(f'"{n}"' for n in MODELS) + ")" in doc
    assert "``kind`` (" + " | ".join(f'"{n}"' for n in metric_names()) in doc


def test_readme_and_cli_show_the_registry():
    from parmpm.cli.parser import build_parser

    assert interpolator_table() in (ROOT / "README.md").read_text(encoding="utf-8")
    assert f"({interpolator_names()} " in build_parser().description
