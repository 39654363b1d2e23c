"""Compiling the kernels ahead (``parmpm compile``), the first-run notice, and rank 0 compiling
first under MPI (:mod:`parmpm.driver.warm_up`).

The cold-cache tests give numba an empty ``NUMBA_CACHE_DIR`` of their own, so they compile for
real (tens of seconds: marked ``slow``): the notice shows exactly when numba compiles, never
when it loads, and after ``parmpm compile`` a run of the same dimension and method compiles
nothing.
"""
from __future__ import annotations

import json
import os
import subprocess
import tempfile
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

import parmpm.driver.warm_up as comp
from parmpm.cli.compile import run_compile
from parmpm.scene.load import scene_from_toml

REPO = Path(__file__).resolve().parents[2]
TIMEOUT_S = 900


@pytest.mark.parametrize("dim", comp.DIMS)
def test_the_tiny_scenes_are_valid_scenes(dim):
    for method in comp.METHODS:
        for update, transfer in [(u, t) for u in (*comp.COMPILED_UPDATES, "auto")
                                 for t in comp.transfers_of(method)]:
            scene = scene_from_toml(comp.tiny_scene_toml(dim, method, update, transfer))
            data = scene.data
            assert data["dim"] == dim and data["method"]["interpolator"] == method
            assert data["method"]["transfer"] == transfer
            assert data["time"]["steps"] == 2 and data["metrics"]["kind"] == "hanging_bar"
            assert len(data["output"]["history"]["probes"]) == 2


class FakeComm:
    """What compile_first asks of a communicator: rank, size and a barrier's request."""

    def __init__(self, rank: int, size: int = 2):
        self.rank, self.size, self.barriers = rank, size, 0

    def Get_rank(self):
        return self.rank

    def Get_size(self):
        return self.size

    def Ibarrier(self):
        self.barriers += 1
        return type("Done", (), {"Test": lambda self: True})()


@pytest.fixture
def warm_ups(monkeypatch):
    """compile_first's warm-ups recorded instead of run: a tiny run's case, or ("scene", its
    text, outputs) for a scene warmed up as itself; a scene's particles are its ``particles``."""
    calls = []
    monkeypatch.setattr(comp, "_WARMED", set())
    monkeypatch.setattr(comp, "warm_up", lambda *key, plastic=False:
                        calls.append(key + (("plastic",) if plastic else ())) or 0.1)
    monkeypatch.setattr(comp, "scene_warm_up", lambda scene, outputs=True:
                        calls.append(("scene", scene.to_toml(), outputs)) or 0.1)
    monkeypatch.setattr(comp, "particles_estimate", lambda spec: spec.particles)
    return calls


BIG = comp.SCENE_WARM_UP_PARTICLES + 1


def _data(dim=2, method="cpdi", update="auto", transfer="flip", model="neo_hookean",
          particles=BIG):
    """What compile_first reads of a scene: its records (``scene.spec``) and its text."""
    spec = SimpleNamespace(dim=dim, method=SimpleNamespace(interpolator=method, update=update,
                                                           transfer=transfer),
                           materials={"m": SimpleNamespace(model=model)}, particles=particles)
    text = f"{dim}D {method} {update} {transfer} {model} {particles}"
    return SimpleNamespace(spec=spec, to_toml=lambda: text)


def test_a_small_scene_is_warmed_up_as_itself_by_two_ranks(warm_ups):
    """Rank 0 runs the scene (outputs, then steps), rank 1 takes its steps alone, a third rank
    only waits; once per scene and process."""
    small = _data(particles=comp.SCENE_WARM_UP_PARTICLES)
    text = small.to_toml()
    comms = [FakeComm(r, size=3) for r in range(3)]
    for comm in comms:
        comp._WARMED.clear()  # each rank is a process of its own
        comp.compile_first(small, comm)
    comp.compile_first(small, comms[0])  # the same scene again in this process: nothing
    assert warm_ups == [("scene", text, True), ("scene", text, False)]
    assert [c.barriers for c in comms] == [1, 1, 1]


def test_the_scene_warm_up_compiles_only_what_the_scene_runs(tmp_path):
    """The default scene (cpdi, USL, one material without damage) warmed up as itself, both
    halves, in a process of its own: the specialised transfers for rows in canonical order and
    nothing else; the tiny run of everything a step can switch on (the warm-up before) also
    compiled the variant for a lazy order and the MUSL re-map, 19 s of the default scene's 59."""
    code = (
        "import json\n"
        "import parmpm.driver.warm_up as comp\n"
        "from parmpm.scene.load import load_scene\n"
        "from parmpm.transfer.kernels2d import cpdi\n"
        "scene = load_scene('hanging_bar')\n"
        "comp.scene_warm_up(scene, outputs=False)\n"
        "comp.scene_warm_up(scene, outputs=True)\n"
        "print(json.dumps({k.py_func.__name__: [str(s) for s in k.signatures] for k in\n"
        "                  (cpdi.p2g_cpdi, cpdi.p2g_momentum_cpdi, cpdi.g2p_cpdi)}))\n")
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=TIMEOUT_S)
    assert proc.returncode == 0, proc.stderr
    sigs = json.loads(proc.stdout.strip().splitlines()[-1])
    assert sigs["p2g_momentum_cpdi"] == []
    for name in ("p2g_cpdi", "g2p_cpdi"):
        assert len(sigs[name]) == 1
        # the order: none (rows in canonical order), not an index of uint64 rows
        assert "Boxes(array(int64, 1d, C), none, " in sigs[name][0]
    assert not list(tmp_path.iterdir())  # its output went to a temporary folder, removed


def test_rank_0_compiles_first_once_per_case(warm_ups):
    comm = FakeComm(0)
    comp.compile_first(_data(), comm)
    comp.compile_first(_data(), comm)  # the same case again in this process: nothing
    comp.compile_first(_data(3, "mpm"), comm)
    comp.compile_first(_data(2, "bspline", transfer="mls"), comm)  # its own kernels: a case
    comp.compile_first(_data(2, "bspline"), comm)
    assert warm_ups == [(2, "cpdi", "auto", "flip"), (3, "mpm", "auto", "flip"),
                        (2, "bspline", "auto", "mls"), (2, "bspline", "auto", "flip")]
    assert comm.barriers == 4


def test_a_plastic_scene_stages_the_plastic_pass_once(warm_ups):
    """The plastic pass is compiled by rank 0's tiny plastic run, once for every dimension and
    method; an elastic scene never runs it."""
    comm = FakeComm(0)
    comp.compile_first(_data(), comm)
    comp.compile_first(_data(3, "bspline", model="j2"), comm)
    comp.compile_first(_data(2, "mpm", model="drucker_prager"), comm)
    assert warm_ups == [(2, "cpdi", "auto", "flip"), (3, "bspline", "auto", "flip"),
                        (2, "cpdi", "usl", "flip", "plastic"), (2, "mpm", "auto", "flip")]
    assert "j2" in comp.tiny_scene_toml(2, "cpdi", "usl", plastic=True)
    assert "j2" not in comp.tiny_scene_toml(2, "cpdi", "usl")


def test_the_tiny_plastic_run_runs():
    """Its scene is valid and yields (so the return maps are compiled, not just the pass)."""
    from parmpm.driver.simulation import Simulation
    from parmpm.scene.load import scene_from_toml

    scene = scene_from_toml(comp.tiny_scene_toml(*comp.PLASTIC_CASE, plastic=True))
    with tempfile.TemporaryDirectory() as tmp:
        sim = Simulation(scene, tmp, quiet=True)
        sim.run()
        P = sim.particles
        for row in (0, 1):  # both models (rows in name order: soft DP, solid J2)
            assert P.plastic[P.mat == row, 6].max() > 0.0


def test_transfers_are_compiled_only_where_the_method_takes_them():
    assert comp.transfers_of("bspline") == ("flip", "apic", "mls")
    assert comp.transfers_of("cpdi") == ("flip",)
    with pytest.raises(ValueError, match="transfer 'mls'"):
        comp.tiny_scene_toml(2, "mpm", "usl", "mls")


def test_a_selection_with_no_case_is_a_one_line_error(warm_ups):
    """``parmpm compile --methods cpdi --transfer mls`` compiles nothing: an error, not "0 cases"."""
    import argparse

    from parmpm.core.errors import ParmpmError

    args = argparse.Namespace(dim=[2], methods=["cpdi", "mpm"], update=["usl"], transfer=["mls"])
    with pytest.raises(ParmpmError, match="--transfer mls applies to none of --methods cpdi mpm"):
        run_compile(args, None)
    assert warm_ups == []


def test_the_other_ranks_only_wait_for_the_tiny_run(warm_ups):
    comm = FakeComm(1)
    comp.compile_first(_data(), comm)
    assert warm_ups == [] and comm.barriers == 1


def test_one_rank_needs_no_staging(warm_ups):
    comp.compile_first(_data(), FakeComm(0, size=1))
    comp.compile_first(_data(), None)
    assert warm_ups == []


def test_a_failed_warm_up_still_releases_the_others(monkeypatch):
    monkeypatch.setattr(comp, "_WARMED", set())
    monkeypatch.setattr(comp, "particles_estimate", lambda spec: spec.particles)

    def broken(*key, plastic=False):
        raise RuntimeError("no compiler today")

    monkeypatch.setattr(comp, "warm_up", broken)
    comm = FakeComm(0)
    comp.compile_first(_data(), comm)  # a debug message; the run compiles as before
    assert comm.barriers == 1


def _cli(*args: str, cache: Path, cwd: Path, launcher=()) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO), NUMBA_CACHE_DIR=str(cache))
    return subprocess.run([*launcher, sys.executable, "-m", "parmpm", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=TIMEOUT_S)


def _cache_state(cache: Path) -> dict:
    """Every index and data file of numba's cache, with its size and modification time."""
    return {str(p.relative_to(cache)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in cache.rglob("*.nb[ic]")}


@pytest.fixture(scope="module")
def cold_cache(tmp_path_factory, mpirun):
    """One cold cache shared by the two tests below (a cold compile costs about a minute; they
    had one each): two ranks on the empty cache (rank 0 and rank 1 warm up with the scene itself
    while the others wait), ``parmpm compile`` of the same case twice, and a one-rank run.
    Returns the folder, the cache, the case and the four commands' results."""
    tmp = tmp_path_factory.mktemp("cold")
    cache = tmp / "cache"
    case = ("--dim", "1", "--methods", "mpm", "--update", "musl")
    run_args = ("run", "hanging_bar_1d", "--set", "method.interpolator=mpm", "--set",
                "time.steps=3", "-v")  # auto: musl
    two = _cli(*run_args, "-o", "out2", cache=cache, cwd=tmp, launcher=(mpirun, "-n", "2"))
    compiles = [_cli("compile", *case, cache=cache, cwd=tmp) for _ in range(2)]
    one = _cli(*run_args, "-o", "out1", cache=cache, cwd=tmp)
    return SimpleNamespace(tmp=tmp, cache=cache, two=two, compiles=compiles, one=one)


@pytest.mark.slow
def test_a_cold_cache_is_compiled_before_the_run_then_every_run_loads_it(cold_cache):
    """Two ranks on the empty cache: the scene's warm-up compiles, and the run itself then
    compiles nothing (not even the separation count's kernels that only several ranks call);
    ``parmpm compile`` of the same case then finds every kernel cached, twice (in 1D the
    generic loops serve every feature the tiny run switches on: the scene's warm-up compiled the
    same set); and a one-rank run compiles nothing."""
    proc, cache = cold_cache.two, cold_cache.cache
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("compiling kernels (first run") == 1
    assert str(cache) in proc.stderr
    after = proc.stderr.split("rank 0 warmed up the kernels")[1]
    late = [line.split("compiled ")[1].split()[0] for line in after.splitlines()
            if "DEBUG parmpm.driver.warm_up: compiled " in line]
    assert late == []
    for again in cold_cache.compiles:
        assert again.returncode == 0, again.stderr
        assert "compiling kernels" not in again.stderr and "every kernel was cached" in again.stderr
    run = cold_cache.one
    assert run.returncode == 0, run.stderr
    assert "compiling kernels" not in run.stderr and "compiled " not in run.stderr


@pytest.mark.slow
def test_after_parmpm_compile_a_many_rank_run_compiles_nothing(cold_cache, mpirun):
    """Eight ranks on the 1D bar (four patches, two holding particles): ranks without a patch,
    ranks with one, a patch-set change, halo exchanges and migration. Each of these once made
    numba compile kernels in the middle of the run that ``parmpm compile`` (and the one-rank
    warm-up of the staged compile) had not: an empty grid view, or one of a single patch, is
    typed as a contiguous array (other variants of P2G, G2P and the halo copies, compiled by
    every idle rank at once); a patch-set change moves the particles' runs (``move_runs``).
    After ``parmpm compile`` of the case (the fixture's, which found the cache complete), the
    run writes nothing into the cache."""
    cache, tmp = cold_cache.cache, cold_cache.tmp
    assert all(c.returncode == 0 for c in cold_cache.compiles)
    before = _cache_state(cache)
    assert before
    run = _cli("run", "hanging_bar_1d", "--set", "method.interpolator=mpm", "--set",
               "time.steps=200", "-o", "out8", "-v", cache=cache, cwd=tmp,
               launcher=(mpirun, "-n", "8"))
    assert run.returncode == 0, run.stderr
    dec = json.loads((tmp / "out8" / "summary.json").read_text())["decomposition"]
    assert 0 in dec["patches_per_rank"] and 1 in dec["patches_per_rank"]  # the paths it takes
    assert dec["patch_set_changes"] >= 1
    after = _cache_state(cache)
    assert sorted(k for k in after if before.get(k) != after[k]) == []
    assert "compiling kernels" not in run.stderr
