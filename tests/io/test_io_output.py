"""Output round trips: XDMF snapshots (read back with meshio; the readers in depth:
test_snapshot_readers.py), summary.json, PNG figures."""

import json
import logging
import sys

import numpy as np
import pytest

from parmpm.io import (SnapshotWriter, format_summary, load_snapshots, pad_point_data,
                       plot_particles, write_summary)

meshio = pytest.importorskip("meshio")

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_xdmf_round_trip(tmp_path, dim, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the .h5 must land next to the .xdmf, not in the cwd
    out = tmp_path / "out"
    rng = np.random.default_rng(dim)
    n, steps = 7, 3
    written = []
    with SnapshotWriter(out, "particles", dim) as w:
        for k in range(steps):
            x = rng.random((n, dim))
            fields = {
                "v": rng.random((n, dim)),
                "F": rng.random((n, dim, dim)),
                "mass": rng.random(n),
                "id": np.arange(n, dtype=np.int64),
                "corners": rng.random((n, 2 ** dim, dim)),
            }
            w.write(0.5 * k, x, fields)
            written.append((x, fields))
    assert (out / "particles.xdmf").exists() and (out / "particles.h5").exists()
    assert not (tmp_path / "particles.h5").exists()

    with meshio.xdmf.TimeSeriesReader(out / "particles.xdmf") as reader:
        points, cells = reader.read_points_cells()
        assert points.shape == (n, 3)
        np.testing.assert_array_equal(points[:, :dim], written[0][0])
        np.testing.assert_array_equal(points[:, dim:], 0.0)
        assert cells[0].type == "vertex" and len(cells[0].data) == n
        assert reader.num_steps == steps
        for k in range(steps):
            t, pd, _ = reader.read_data(k)
            x, fields = written[k]
            assert t == 0.5 * k
            assert pd["mass"].shape == (n,)
            np.testing.assert_array_equal(pd["mass"], fields["mass"])
            np.testing.assert_array_equal(pd["id"], np.arange(n))
            vec = pd["v"]
            if dim == 1:
                assert vec.shape == (n,)
                np.testing.assert_array_equal(vec, fields["v"][:, 0])
                np.testing.assert_array_equal(pd["F"], fields["F"][:, 0, 0])
            else:
                assert vec.shape == (n, 3)
                np.testing.assert_array_equal(vec[:, :dim], fields["v"])
                F = pd["F"].reshape(n, 3, 3)
                np.testing.assert_array_equal(F[:, :dim, :dim], fields["F"])
            corners = fields["corners"].reshape(n, -1)
            for j in range(corners.shape[1]):
                np.testing.assert_array_equal(pd[f"corners_{j}"], corners[:, j])
            assert pd["id"].dtype == np.int64
            # meshio reads one geometry; the positions of every step are the point field x
            np.testing.assert_array_equal(pd["x"][:, :dim], x)
    # every step has its own (moving) geometry: the x of its own group
    text = (out / "particles.xdmf").read_text()
    for k in range(steps):
        assert f"particles.h5:/step_{k:08d}/x</DataItem>\n        </Geometry>" in text
    s = load_snapshots(out / "particles.xdmf")
    for k, (x, _) in enumerate(written):
        np.testing.assert_array_equal(s["x"][k], x)


def test_xdmf_readable_before_close(tmp_path):
    w = SnapshotWriter(tmp_path, "snap", 2, flush_seconds=0.0)
    w.write(0.0, np.zeros((3, 2)), {"s": np.ones(3)})
    with meshio.xdmf.TimeSeriesReader(tmp_path / "snap.xdmf") as reader:
        assert reader.num_steps == 1
    w.write(1.0, np.ones((3, 2)), {"s": np.ones(3)})
    w.close()
    w.close()  # idempotent
    with pytest.raises(ValueError):
        w.write(2.0, np.ones((3, 2)))
    with meshio.xdmf.TimeSeriesReader(tmp_path / "snap.xdmf") as reader:
        assert reader.num_steps == 2


def test_pad_point_data_shapes():
    def shapes(a, dim):
        return {k: v.shape for k, v in pad_point_data("f", a, 4, dim).items()}

    assert shapes(np.ones((4, 1)), 2) == {"f": (4,)}
    assert shapes(np.ones((4, 1, 1)), 1) == {"f": (4,)}
    assert shapes(np.ones((4, 2)), 2) == {"f": (4, 3)}
    assert shapes(np.ones((4, 3)), 2) == {"f": (4, 3)}
    assert shapes(np.ones((4, 3, 3)), 3) == {"f": (4, 9)}
    assert shapes(np.ones((4, 2, 2)), 2) == {"f": (4, 9)}
    assert shapes(np.ones((4, 4)), 2) == {"f": (4, 9)}  # flattened 2x2 tensor
    assert shapes(np.ones((4, 4, 2)), 2) == {f"f_{j}": (4,) for j in range(8)}  # CPDI corners
    t = pad_point_data("F", np.arange(16.0).reshape(4, 2, 2), 4, 2)["F"].reshape(4, 3, 3)
    np.testing.assert_array_equal(t[:, :2, :2], np.arange(16.0).reshape(4, 2, 2))
    assert pad_point_data("b", np.array([True, False]), 2, 2)["b"].dtype.kind == "i"
    with pytest.raises(ValueError):
        pad_point_data("f", np.ones(3), 4, 2)


def test_summary_round_trip(tmp_path):
    summary = {
        "scene": "hanging_bar",
        "dim": 2,
        "method": "cpdi",
        "update": "usl",
        "lcr": np.float64(0.05),
        "ranks": np.int64(2),
        "particles": 1200,
        "steps": np.int32(3000),
        "time": 0.02,
        "wall_seconds": 4.0,
        "particle_steps_per_second": None,
        "grid": {"cells": np.array([16, 32]), "path": tmp_path / "x.toml"},
        "metrics": {
            "separated": np.bool_(True),
            "separation_time": np.float32(0.5),
            "max_stretch": 4.2,
            "relative_error_static": None,
            "history": np.arange(3.0),
            "bad": float("nan"),
        },
    }
    path = write_summary(tmp_path / "run", summary)
    assert path == tmp_path / "run" / "summary.json"
    data = json.loads(path.read_text())
    assert data["lcr"] == 0.05 and data["ranks"] == 2 and data["steps"] == 3000
    assert data["grid"]["cells"] == [16, 32]
    assert data["grid"]["path"] == str(tmp_path / "x.toml")
    assert data["metrics"]["separated"] is True
    assert data["metrics"]["history"] == [0.0, 1.0, 2.0]
    assert data["metrics"]["bad"] is None  # strict JSON: no NaN
    assert list((tmp_path / "run").iterdir()) == [path]  # no temp file left behind
    # overwrite in place
    write_summary(tmp_path / "run", {"steps": 1})
    assert json.loads(path.read_text()) == {"steps": 1}

    text = format_summary(data)
    lines = text.splitlines()
    assert 5 <= len(lines) <= 8
    assert "hanging_bar" in lines[0] and "(2D)" in lines[0]
    assert "cpdi" in text and "usl" in text and "0.05" in text
    assert "900,000 particle-steps/s" in text  # 1200 * 3000 / 4
    assert "separated = true" in text and "max_stretch = 4.2" in text
    assert "history" not in text and "relative_error_static" not in text  # lists, nulls left out


def test_format_summary_minimal():
    lines = format_summary({"scene_name": "vibrating_bar", "particles": 32, "steps": 10}).splitlines()
    assert len(lines) == 4 and "vibrating_bar" in lines[0]
    text = format_summary({"scene": "s", "particles": 10, "steps": 5, "particle_steps_per_second": 2.5e6})
    assert "2,500,000 particle-steps/s" in text


@pytest.mark.parametrize("dim, corners", [(1, False), (2, False), (2, True), (3, False)])
def test_plot_particles_png(tmp_path, dim, corners):
    pytest.importorskip("matplotlib")
    rng = np.random.default_rng(0)
    n = 20
    x = rng.random((n, dim))
    stretch = 1.0 + rng.random(n)
    c = None
    if corners:
        r = 0.02
        c = x[:, None, :] + r * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])[None]
    path = plot_particles(tmp_path / "fig" / f"p{dim}.png", x, stretch, dim, corners=c, title="t")
    assert path is not None and path.exists()
    assert path.read_bytes()[:8] == PNG_MAGIC


def test_plot_particles_without_matplotlib(tmp_path, monkeypatch, caplog):
    for name in list(sys.modules):
        if name == "matplotlib" or name.startswith("matplotlib."):
            monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import raises ImportError
    with caplog.at_level(logging.WARNING, logger="parmpm.io.figures"):
        assert plot_particles(tmp_path / "p.png", np.zeros((2, 1)), np.ones(2), 1) is None
    assert "matplotlib" in caplog.text
    assert not (tmp_path / "p.png").exists()


def test_format_summary_energy_balance():
    """The history's last balance is one line: residual, its estimate, its share of the energy
    given; a summary without a history has no such line."""
    balance = {"energy_residual": -39.5, "residual_estimate": -40.1, "scale": 3950.0}
    text = format_summary({"scene": "s", "particles": 10, "steps": 5,
                           "energy": {"limit": 1.0, "balance": balance}})
    line = next(x for x in text.splitlines() if x.startswith("energy"))
    assert "-39.5 J" in line and "-40.1 J" in line and "1 % of the 3950 J given" in line
    no_history = format_summary({"scene": "s", "particles": 10, "steps": 5, "energy": {"limit": 1.0}})
    assert "energy" not in no_history


# --- issue 28: a long series does not grow the writer's memory ----------------------------------
def _many_snapshots(w, a, b, n=4, dim=2):
    rng = np.random.default_rng(a)
    fields = {"velocity": rng.random((n, dim)), "F": rng.random((n, dim, dim)),
              "mass": rng.random(n), "gid": np.arange(n), "damage": rng.random(n)}
    for k in range(a, b):
        w.write(0.1 * k, rng.random((n, dim)), fields, step=k,
                domains=rng.random((n, 2 ** dim, dim)))


def test_snapshot_index_is_not_held_in_memory(tmp_path):
    """The XML index waits on disk (parmpm.io.xdmf_index): 200 more snapshots leave the
    Python heap where it was (before issue 28: an ElementTree of ~7 kB per snapshot here), and
    the file is what ElementTree would write for its tree."""
    import gc
    import tracemalloc
    from xml.etree import ElementTree as ET

    w = SnapshotWriter(tmp_path, "long", 2, flush_seconds=3600.0)
    _many_snapshots(w, 0, 20)
    gc.collect()
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        _many_snapshots(w, 20, 220)
        gc.collect()  # what is garbage is not kept
        grown = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    w.close()
    assert grown < 100_000, f"{grown} bytes over 200 snapshots"
    text = (tmp_path / "long.xdmf").read_text()
    tree = ET.ElementTree(ET.fromstring(text))
    ET.indent(tree)
    assert ET.tostring(tree.getroot(), encoding="unicode", xml_declaration=True).replace(
        "<?xml version='1.0' encoding='UTF-8'?>", "<?xml version='1.0' encoding='utf-8'?>") == text
    with meshio.xdmf.TimeSeriesReader(tmp_path / "long.xdmf") as reader:
        assert reader.num_steps == 220
    assert sorted(p.name for p in tmp_path.iterdir()) == ["long.h5", "long.xdmf"]  # no scratch


def test_snapshot_file_metadata_cache_stays_small(tmp_path):
    """HDF5's metadata cache of the series is fixed small: before issue 28 it filled to 2 MB
    of metadata (~50 MB of the process's memory, ~130 kB per snapshot until then)."""
    w = SnapshotWriter(tmp_path, "long", 2, flush_seconds=3600.0)
    _many_snapshots(w, 0, 150)
    max_size, _, current, _ = w._h5.id.get_mdc_size()  # bytes of metadata, as on disk
    w.close()
    assert max_size <= 64 * 1024 and current <= max_size, (max_size, current)


def test_a_failed_snapshot_is_left_out_of_the_index(tmp_path, monkeypatch):
    """A snapshot whose HDF5 write fails half way is not listed (the index holds whole
    snapshots only)."""
    w = SnapshotWriter(tmp_path, "s", 2, flush_seconds=0.0)
    _many_snapshots(w, 0, 2)
    original = w._dataset

    def failing(group, name, *a, **k):
        if name == "mass":
            raise OSError(5, "Input/output error")
        return original(group, name, *a, **k)

    monkeypatch.setattr(w, "_dataset", failing)
    with pytest.raises(Exception, match="Input/output error"):
        _many_snapshots(w, 2, 3)
    w.close()
    with meshio.xdmf.TimeSeriesReader(tmp_path / "s.xdmf") as reader:
        assert reader.num_steps == 2


@pytest.mark.slow
def test_memory_growth_script_quick_run_stays_flat(tmp_path):
    """run_scripts/benchmarks/memory_growth.py --quick (4,000 steps, a snapshot every 100, the vibrating
    bar's metrics every step): its RSS grows by less than 2 MB from step 100 to the end
    (before issue 28: ~6 MB, ~150 kB per snapshot)."""
    import csv

    from study_harness import run_quick

    out = run_quick("benchmarks/memory_growth.py", tmp_path / "mg", extra=["--cases", "both"], timeout=600)
    row = next(csv.DictReader(open(out / "memory_growth.csv")))
    assert float(row["rss_end_mb"]) - float(row["rss_start_mb"]) < 2.0, row
