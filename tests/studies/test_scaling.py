"""``run_scripts/benchmarks/scaling.py`` (strong and weak scaling, cost model) and ``run_scripts/models/cost_model.py``.

* The cost model's formulas against hand-computed cases: the halo bytes of one 2D and 3D patch
  face, the nodes of edge/corner pairs, a rank's halo nodes against a brute-force count over its
  patches, E(1) = 1 with no communication, E falling with P at fixed N, the fits recovering known
  α, β and α_r from synthetic data, t_p counting unknown (new) bench phases as compute.
* The script's ``--quick`` mode under ``mpirun -n 1`` and ``-n 2`` (skipped without an
  ``mpirun`` next to this Python): both CSVs, the JSON of constants and both PNGs, with E(1) = 1,
  the halo formula equal to the measured ``halo_bytes_per_step`` on 2 ranks, positive constants
  and the 1e8-particle cube infeasible on 1e4 ranks. ~15 s.
"""
from __future__ import annotations

import csv
import importlib.util
import itertools
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
SCRIPTS = REPO / "run_scripts"
MPIRUN = Path(sys.executable).parent / "mpirun"


def _load(path: str):
    name = path.rsplit("/", 1)[-1]
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{path}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


cm = _load("models/cost_model")


# --- the formulas ----------------------------------------------------------------------------------
def test_face_halo_bytes_by_hand():
    # 2D, 32-cell patches, ghost 2: (g + 1) + g = 5 node rows of 32 nodes cross a face, per
    # halo operation; accumulate 1 + 2·2 = 5 doubles per node, fill 2·2 = 4
    assert cm.pair_halo_nodes((1, 0), 32, 2) == 5 * 32
    assert cm.directed_halo_nodes((1, 0), 32, 2) == 2 * 32      # A's rows in B's ghost layer
    assert cm.directed_halo_nodes((-1, 0), 32, 2) == 3 * 32     # incl. the shared node row
    assert cm.face_halo_bytes(32, 2, 2) == 8 * (5 + 4) * 5 * 32 == 11520
    # 3D, 16-cell patches: 7 + 6 doubles per node, 5 layers of 16×16
    assert cm.face_halo_bytes(16, 2, 3) == 8 * 13 * 5 * 256
    # MUSL exchanges a second momentum / velocity: 1 + 3d and 3d
    assert cm.halo_components(2, "musl") == (7, 6) and cm.halo_ops("musl") == 5


def test_edge_and_corner_pairs():
    assert cm.pair_halo_nodes((1, 1), 32, 2) == 2 * 2 + 3 * 3   # g² + (g+1)²
    assert cm.pair_halo_nodes((1, -1), 32, 2) == 2 * (2 * 3)    # g(g+1) both ways
    assert cm.pair_halo_nodes((1, 1, 0), 16, 1) == (1 + 4) * 16
    # a partial patch (4 owned nodes) caps the transverse extent
    got = cm.directed_halo_nodes((1, 0), np.array([[32, 32], [32, 4]]), 2)
    assert list(got) == [64, 8]


@pytest.mark.parametrize("dim,s,g,k", [(2, 4, 1, 2), (2, 32, 2, 3), (3, 5, 2, 2), (3, 16, 2, 3)])
def test_rank_halo_nodes_brute_force(dim, s, g, k):
    """H(k) equals the sum over every (inside, outside) patch pair of a k^d block."""
    total = 0
    for a in itertools.product(range(k), repeat=dim):
        for off in cm.neighbour_offsets(dim):
            b = [x + o for x, o in zip(a, off)]
            if not all(0 <= x < k for x in b):
                total += cm.directed_halo_nodes(-np.array(off), s, g)
    assert cm.rank_halo_nodes(k, s, g, dim) == pytest.approx(total)
    assert cm.rank_halo_nodes(1, s, g, dim) == (s + 2 * g + 1) ** dim - s ** dim


def test_one_rank_is_ideal_and_efficiency_falls_with_ranks():
    m = cm.Machine(alpha=3e-6, beta=5e9, alpha_r=4e-6)
    one = cm.predict_cube(1e9, 1, 1e-6, m)
    assert one["efficiency"] == 1.0 and one["latency"] == one["bandwidth"] == one["reduce"] == 0.0
    zero = cm.step_time(1e6, 1, 2e-7, m)
    assert zero["total"] == pytest.approx(0.2) and zero["compute_share"] == 1.0
    E = [cm.predict_cube(1e9, P, 1e-6, m)["efficiency"] for P in (1, 2, 8, 64, 512, 4096, 30000)]
    assert all(e1 > e2 for e1, e2 in zip(E, E[1:])), E
    assert 0.0 < E[-1] < 1.0
    # more ranks than patches: no prediction
    assert math.isnan(cm.predict_cube(1e8, 10_000, 1e-6, m)["efficiency"])
    # a given imbalance is used as is
    assert cm.predict_cube(1e9, 100, 1e-6, m, imbalance=0.25)["imbalance"] == 0.25


def test_step_time_terms():
    m = cm.Machine(alpha=2e-6, beta=1e9, alpha_r=5e-6)
    T = cm.step_time(1000, 4, 1e-6, m, halo_bytes=1e6, n_msg=10, imbalance=0.1)
    assert T["compute"] == pytest.approx(250 * 1e-6 * 1.1)
    assert T["latency"] == pytest.approx(20e-6)
    assert T["bandwidth"] == pytest.approx(1e-3)
    assert T["reduce"] == pytest.approx(2 * 5e-6)    # ⌈log2 4⌉ stages
    assert T["total"] == pytest.approx(sum(T[k] for k in ("compute", "latency", "bandwidth", "reduce")))
    net = cm.network_machine(m, 1.5e-6, 12.5e9)
    assert net.alpha == pytest.approx(3.5e-6) and net.beta == 1e9 and net.alpha_r == pytest.approx(6.5e-6)


def test_fits_recover_known_constants():
    n = np.array([8 * 2 ** k for k in range(20)], float)
    alpha, beta = 2.5e-6, 6e9
    t = alpha + n / beta
    a, b = cm.fit_latency_bandwidth(n, t)
    assert a == pytest.approx(alpha, rel=1e-9) and b == pytest.approx(beta, rel=1e-9)
    noisy = t * (1.0 + 0.05 * np.random.default_rng(1).standard_normal(n.size))
    a, b = cm.fit_latency_bandwidth(n, noisy)
    assert a == pytest.approx(alpha, rel=0.1) and b == pytest.approx(beta, rel=0.1)
    P = [1, 2, 4, 8, 16]
    assert cm.fit_reduction(P, [0.0 + 3e-6 * math.ceil(math.log2(p)) for p in P]) == pytest.approx(3e-6)
    with pytest.raises(ValueError):
        cm.fit_reduction([1], [1e-6])


def test_t_p_reads_phases_generically():
    result = {"seconds_per_step": 1.0, "particles": 1000,
              "phase_seconds_per_step": {"p2g": 0.4, "sort": 0.1, "accumulate": 0.05, "fill": 0.02,
                                         "g2p": 0.3, "reduce": 0.03, "halo": 0.07}}
    # accumulate, fill and reduce are communication; "sort" (new) is work; "halo" is their sum
    assert cm.compute_time_per_particle(result) == pytest.approx((1.0 - 0.1) / 1000)


# --- the script ------------------------------------------------------------------------------------
def _rows(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.mpi
@pytest.mark.skipif(not MPIRUN.is_file(), reason="no mpirun next to sys.executable")
@pytest.mark.slow
def test_scaling_quick(tmp_path):
    out = tmp_path / "scaling"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
    proc = subprocess.run([sys.executable, str(SCRIPTS / "benchmarks" / "scaling.py"), "--quick", "--ranks", "1,2",
                           "--out", str(out)],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "halo check" in proc.stdout and "predicted strong-scaling efficiency" in proc.stdout

    rows = _rows(out / "scaling.csv")
    assert [(r["kind"], int(r["ranks"])) for r in rows] == [("strong", 1), ("strong", 2),
                                                             ("weak", 1), ("weak", 2)]
    strong = [r for r in rows if r["kind"] == "strong"]
    weak = [r for r in rows if r["kind"] == "weak"]
    assert strong[0]["particles"] == strong[1]["particles"]
    assert int(weak[1]["particles"]) / int(weak[0]["particles"]) == pytest.approx(2.0, rel=0.1)
    assert float(strong[0]["efficiency"]) == 1.0 and float(weak[0]["efficiency"]) == 1.0
    for r in rows:
        # the efficiency is the formula's (per-rank throughput against the 1-rank run's), not a
        # bound on it: a bound judged the machine (1.84 measured once, the 1-rank run slowed by
        # the other pytest worker), and timings are benchmarks' business, not tests'
        base = strong[0] if r["kind"] == "strong" else weak[0]
        per_rank = float(r["particles"]) / (int(r["ranks"]) * float(r["seconds_per_step"]))
        assert float(r["seconds_per_step"]) > 0 and float(r["efficiency"]) == pytest.approx(
            per_rank * float(base["seconds_per_step"]) / float(base["particles"]), rel=1e-9)
        assert r["oversubscribed"] == str(int(r["ranks"]) > (os.cpu_count() or 1))
        shares = {k: float(v) for k, v in r.items() if k.startswith("share_") and v != ""}
        assert {"share_p2g", "share_g2p"} <= set(shares)
        # a share is the slowest rank's phase time over the loop's wall time less the kernels
        # compiled in it: a phase that meets a kernel mid-run, or a rank the OS stalls in its last
        # phase of a --quick run's few steps, can take it past 1 (CI saw it once, on a loaded
        # machine), so only what holds on any machine is checked here
        assert all(math.isfinite(v) and v >= 0.0 for v in shares.values())
        # the face/edge/corner formula reproduces the halo code's bytes (0 on one rank)
        assert float(r["halo_bytes_model"]) == pytest.approx(float(r["halo_bytes_per_step"]), rel=1e-12)
    assert int(strong[1]["halo_bytes_per_step"]) > 0
    # each rank's computing time: spread over ranks, and inside the (slowest rank's) step
    two = json.loads(next(out.glob("bench_2d_P2_*.json")).read_text())
    work = two["rank_work_seconds_per_step"]
    assert 0 < work["min"] <= work["mean"] <= work["max"] <= two["seconds_per_step"]
    assert two["work_imbalance"] == pytest.approx(work["max"] / work["mean"])

    const = json.loads((out / "cost_model.json").read_text())
    m = const["measured"]
    assert set(m["t_p_seconds"]) == {"2", "3"} and all(v > 0 for v in m["t_p_seconds"].values())
    assert m["alpha_seconds"] > 0 and m["beta_bytes_per_second"] > 0 and m["alpha_r_seconds_per_stage"] > 0
    assert "assumed" in const["assumed"]["network"]
    assert const["halo_check"][0]["ratio"] == pytest.approx(1.0)
    probe = json.loads((out / "probe_2.json").read_text())
    assert probe["pingpong"]["bytes"][0] == 8 and probe["pingpong"]["bytes"][-1] == 4 * 2 ** 20
    assert probe["pingpong"]["seconds"][-1] > probe["pingpong"]["seconds"][0]

    model = _rows(out / "cost_model.csv")
    pred = [r for r in model if r["kind"] == "prediction" and r["network"] == "assumed_ib"]
    assert {float(r["particles"]) for r in pred} == {1e8, 1e9, 1e10}
    assert {int(r["ranks"]) for r in pred} >= {100, 1000, 10000}
    for r in pred:
        e = float(r["efficiency"]) if r["efficiency"] else math.nan
        assert math.isnan(e) or 0.0 < e <= 1.0
        if float(r["particles"]) == 1e8 and int(r["ranks"]) == 10000:
            assert math.isnan(e)  # ~3 000 patches cannot feed 10 000 ranks
    checks = [r for r in model if r["kind"].startswith("check_")]
    assert [float(r["efficiency"]) for r in checks if r["ranks"] == "1"] == [1.0, 1.0]
    for name in ("scaling.png", "cost_model.png"):
        size = (out / name).stat().st_size
        assert 20_000 < size < 300_000, (name, size)
