"""Smoke tests of three study scripts in ``--quick`` mode, each asserting what its docstring claims
(every assertion is a property of the results that could have come out otherwise):

* ``run_scripts/rotation.py`` — a spinning disk: cpGIMP's ``l0·|F_kk|`` domains collapse near 90°
  and 270° (total area < 10 % of the initial) and recover near 180°, while CPDI's keep their
  area within 1 % all the way round and its stress stays well below cpGIMP's; and the same CSVs
  on 2 MPI ranks (except ``wall_seconds``).
* ``run_scripts/update_order.py`` — USL against MUSL: 1D CPDI domain lengths sum to the bar's
  length to round-off with USL and not with MUSL (which also lets the seed's 1D bar separate and
  its 2D bar run away); the same accuracy at the scenes' CFL; on the vibrating bar USL's
  CFL limit is lower than MUSL's for CPDI.
* ``run_scripts/speed_accuracy.py`` — rows for every method on both problems, second-order
  convergence of CPDI and cpGIMP on the manufactured solution, and the smallest errors (the end
  of the Pareto front) are CPDI's or cpGIMP's.
"""
from __future__ import annotations

import csv
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPTS = REPO / "run_scripts"
METHODS = ("mpm", "ugimp", "cpgimp", "cpdi")


def mpirun() -> str | None:
    beside = Path(sys.executable).parent / "mpirun"
    return str(beside) if beside.exists() else shutil.which("mpirun")


def _run(script: str, out: Path, prefix=(), extra=(), timeout=150) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    path = os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))
    env = dict(os.environ, PYTHONPATH=path)
    cmd = [*prefix, sys.executable, str(SCRIPTS / script), "--quick", "--out", str(out), *extra]
    proc = subprocess.run(cmd, cwd=out.parent, env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return out


def _csv(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _f(value: str) -> float:
    return float(value) if value not in ("", None) else math.nan


def _png_ok(path: Path) -> None:
    assert path.is_file() and 20_000 < path.stat().st_size < 300_000, (path, path.stat().st_size)


# --- rotation ----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def rotation(tmp_path_factory):
    out = _run("rotation.py", tmp_path_factory.mktemp("rotation") / "out")
    return out, {r["method"]: r for r in _csv(out / "rotation.csv")}


def test_rotation_cpgimp_domains_collapse_cpdi_keep_their_area(rotation):
    out, rows = rotation
    assert set(rows) == set(METHODS)
    gimp, cpdi = rows["cpgimp"], rows["cpdi"]
    # F_kk = cos θ: cpGIMP's total domain area near 90° and 270° is a few per mille at most...
    assert _f(gimp["area_ratio_near_90"]) < 0.1 and _f(gimp["area_ratio_near_270"]) < 0.1
    # ...and comes back in between (cos² 180° = 1)
    assert _f(gimp["area_ratio_near_180"]) > 0.5
    # CPDI's R = F·R0 turns with the material: area within 1 % all the way round
    assert _f(cpdi["area_ratio_max_dev"]) < 0.01 and _f(cpdi["min_area_ratio"]) > 0.9
    assert abs(_f(cpdi["turns"]) - 1.0) < 1e-9
    # and its stress stays well below cpGIMP's (the others' are as large as cpGIMP's)
    assert _f(cpdi["stress_ratio_max"]) < 0.5 * _f(gimp["stress_ratio_max"])
    for m in ("mpm", "ugimp"):
        assert _f(cpdi["stress_ratio_max"]) < 0.5 * _f(rows[m]["stress_ratio_max"])
    hist = [h for h in _csv(out / "rotation_history.csv") if h["method"] == "cpgimp"]
    angles = [_f(h["angle_deg"]) for h in hist]
    assert min(angles) == 0.0 and max(angles) >= 359.0
    _png_ok(out / "rotation.png")


@pytest.mark.mpi
@pytest.mark.skipif(mpirun() is None, reason="no mpirun (install the 'mpich' extra)")
def test_rotation_two_ranks_give_the_same_csv(rotation, tmp_path):
    out, _ = rotation
    got = _run("rotation.py", tmp_path / "np2", prefix=[mpirun(), "-n", "2"])
    for name in ("rotation.csv", "rotation_history.csv"):
        a, b = _csv(out / name), _csv(got / name)
        assert len(a) == len(b) > 0
        for r1, r2 in zip(a, b):
            r1.pop("wall_seconds", None), r2.pop("wall_seconds", None)
            assert r1 == r2, name


# --- update order ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def update_order(tmp_path_factory):
    out = _run("update_order.py", tmp_path_factory.mktemp("update_order") / "out")
    return out, _csv(out / "update_order.csv")


def _pick(rows, **kw):
    found = [r for r in rows if all(r[k] == str(v) for k, v in kw.items())]
    assert found, kw
    return found


def test_cpdi_domains_tile_the_1d_bar_with_usl_only(update_order):
    _, rows = update_order
    for problem in ("vibrating_bar", "hanging_bar"):
        usl, = _pick(rows, study="tiling", problem=problem, update="usl")
        musl, = _pick(rows, study="tiling", problem=problem, update="musl")
        # USL: Σ 2a_p equals the bar's length to round-off, at every output time
        assert _f(usl["tiling_sum_rel_max"]) < 1e-12 and _f(usl["tiling_gap_max_cells"]) < 1e-10
        # MUSL: positions from the first grid solve, stretches from the second: no tiling
        assert _f(musl["tiling_sum_rel_max"]) > 1e-7 and _f(musl["tiling_gap_max_cells"]) > 1e-5
    hang_usl, = _pick(rows, study="tiling", problem="hanging_bar", update="usl")
    hang_musl, = _pick(rows, study="tiling", problem="hanging_bar", update="musl")
    assert hang_usl["outcome"] == "held" and hang_musl["outcome"] == "separated"
    assert _f(hang_musl["tiling_sum_rel_max"]) > 1e-3
    seed_usl, = _pick(rows, study="seed_bar", method="cpdi", update="usl")
    seed_musl, = _pick(rows, study="seed_bar", method="cpdi", update="musl")
    assert seed_usl["outcome"] == "held" and seed_musl["outcome"] != "held"


def test_usl_and_musl_equally_accurate_at_the_scenes_cfl(update_order):
    _, rows = update_order
    for problem in ("manufactured", "vibrating_bar"):
        for m in METHODS:
            for r in _pick(rows, study="accuracy", problem=problem, method=m, update="usl"):
                twin, = _pick(rows, study="accuracy", problem=problem, method=m, update="musl",
                              cells=r["cells"])
                assert r["status"] == twin["status"] == "ok"
                ratio = _f(r["error"]) / _f(twin["error"])
                assert abs(ratio - 1.0) < 0.15, (r["case"], r["error"], twin["error"])


def test_usl_cfl_limit_is_lower_on_the_vibrating_bar(update_order):
    _, rows = update_order
    lim = {(r["method"], r["update"]): r
           for r in _pick(rows, study="cfl_limit", problem="vibrating_bar")}
    for m in METHODS:  # MUSL: bounded and accurate over the whole scan
        assert _f(lim[(m, "musl")]["cfl_accurate_limit"]) == 0.99
        assert _f(lim[(m, "usl")]["cfl_accurate_limit"]) < 0.99
    assert 0.5 <= _f(lim[("cpdi", "usl")]["cfl_accurate_limit"]) < 0.9
    # beyond it, CPDI with USL creates energy on the vibrating bar
    bad = _pick(rows, study="cfl", problem="vibrating_bar", method="cpdi", update="usl", cfl=0.99)[0]
    assert bad["status"] == "unstable" or _f(bad["energy_growth"]) > 1.5
    _png_ok(update_order[0] / "update_order.png")


# --- speed / accuracy --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def speed(tmp_path_factory):
    out = _run("speed_accuracy.py", tmp_path_factory.mktemp("speed") / "out")
    return out, _csv(out / "speed_accuracy.csv")


def test_speed_accuracy_rows_and_pareto_front(speed):
    out, rows = speed
    for problem in ("manufactured", "hanging_bar"):
        mine = [r for r in rows if r["problem"] == problem]
        assert {r["method"] for r in mine} == set(METHODS)
        for key in ("on_front_psteps", "on_front_time"):
            front = [r for r in mine if r[key] == "True"]
            assert front and all(math.isfinite(_f(r["error"])) for r in front)
        ok = [r for r in mine if math.isfinite(_f(r["error"]))]
        best = min(ok, key=lambda r: _f(r["error"]))
        # the smallest error of the study is CPDI's or cpGIMP's: the end of both fronts
        assert best["method"] in ("cpdi", "cpgimp") and best["on_front_psteps"] == "True"
        assert best["on_front_time"] == "True"
        for r in mine:
            assert int(r["particle_steps"]) == int(r["particles"]) * int(r["steps"]) > 0
            assert _f(r["step_seconds"]) > 0
    man = [r for r in rows if r["problem"] == "manufactured"]
    assert all(math.isfinite(_f(r["error"])) for r in man)
    for m in ("cpdi", "cpgimp"):  # second order under refinement, 8 -> 16 cells
        for ppc in ("1", "2"):
            e = {r["cells"]: _f(r["error"]) for r in man if r["method"] == m and r["ppc"] == ppc}
            assert math.log2(e["8"] / e["16"]) > 1.6, (m, ppc, e)
    bar = [r for r in rows if r["problem"] == "hanging_bar"]
    assert not any(r["separated"] == "True" for r in bar if r["method"] == "cpdi")
    for ppc in ("1", "2"):  # CPDI: second order on the static bar, 10 -> 20 cells
        e = {r["cells"]: _f(r["error"]) for r in bar if r["method"] == "cpdi" and r["ppc"] == ppc}
        assert abs(math.log2(e["10"] / e["20"]) - 2.0) < 0.2, (ppc, e)
    assert any(r["separated"] == "True" for r in bar if r["method"] == "mpm")
    _png_ok(out / "speed_accuracy.png")
