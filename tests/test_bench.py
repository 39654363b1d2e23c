"""``parmpm bench`` and ``run_scripts/mpi_scaling.py``: the benchmark scene, the result's keys and
their consistency (shares of the step in [0, 1], particle counts), and the scaling script's smoke
mode under ``mpirun -n 1`` and ``-n 2`` (skipped without an ``mpirun`` next to this Python)."""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from parmpm.bench import add_arguments, build_bench_scene, run_bench
from parmpm.errors import ParmpmError

REPO = Path(__file__).resolve().parents[1]
MPIRUN = Path(sys.executable).parent / "mpirun"
PHASES = ("p2g", "accumulate", "grid", "fill", "g2p", "migrate", "reduce")


def bench_args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return parser.parse_args(list(argv))


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_scene_block_and_margin(dim):
    scene = build_bench_scene(dim, "mpm", particles=5000, ppc=2, steps=4)
    data = scene.data
    body = data["bodies"][0]
    h = data["grid"]["cell_size"][0]
    n = round((body["max"][0] - body["min"][0]) / h)
    assert abs((2 * n) ** dim - 5000) / 5000 < 0.3  # (n·ppc)^dim ≈ particles
    for k in range(dim):
        assert body["min"][k] >= 4 * h - 1e-12
        assert data["grid"]["cells"][k] * h - body["max"][k] >= 4 * h - 1e-12
    assert data["gravity"]["g"] == [0.0] * dim
    assert all(v == "free" for k, v in data["boundary"].items() if not k.endswith("_regions"))
    assert not data["boundary"]["fixed_regions"]
    assert not data["output"]["snapshots"] and not data["output"]["figure"]
    assert build_bench_scene(dim, "cpdi", 5000, 2, 4).lcr == pytest.approx(2 * h)


def test_parse_particles_and_bad_values():
    assert bench_args("--particles", "1e6").particles == 1_000_000
    assert bench_args().particles == 1_000_000 and bench_args().method == "cpdi"
    with pytest.raises(SystemExit):
        bench_args("--particles", "lots")
    with pytest.raises(ParmpmError, match="--steps"):
        build_bench_scene(2, "cpdi", 1000, 2, steps=1)


@pytest.mark.parametrize("argv", [
    ("--dim", "2", "--method", "cpdi", "--particles", "2000", "--steps", "3"),
    ("--dim", "1", "--method", "mpm", "--particles", "500", "--steps", "3"),
    ("--dim", "3", "--method", "mpm", "--particles", "1000", "--steps", "3"),
])
def test_run_bench_serial(argv, tmp_path, capsys):
    args = bench_args(*argv, "--json", str(tmp_path / "bench.json"), "--out", str(tmp_path / "out"))
    r = run_bench(args, None)
    assert r["ranks"] == 1 and r["dim"] == args.dim and r["method"] == args.method
    assert r["steps"] == 3 and r["timed_steps"] == 2
    assert r["particles"] == sum(r["decomposition"]["particles_per_rank"])
    assert abs(r["particles"] - args.particles) / args.particles < 0.3
    assert r["seconds_per_step"] == pytest.approx(r["particles"] / r["particle_steps_per_second"])
    assert r["jit_warmup_seconds"] >= 0 and r["particles_migrated"] == 0
    assert set(r["phase_share"]) == set(PHASES) | {"halo"}
    for share in r["phase_share"].values():
        assert 0.0 <= share <= 1.0
    assert 0.0 <= r["halo_share"] <= 1.0 and 0.0 <= r["migrate_share"] <= 1.0
    assert r["halo_share"] == pytest.approx(r["phase_share"]["accumulate"] + r["phase_share"]["fill"])
    assert sum(r["phase_share"][p] for p in PHASES) <= 1.0 + 1e-9  # one rank: phases add up
    assert json.loads((tmp_path / "bench.json").read_text())["particles"] == r["particles"]
    assert (tmp_path / "out" / "summary.json").is_file()
    assert "time per step" in capsys.readouterr().out


@pytest.mark.mpi
@pytest.mark.skipif(not MPIRUN.is_file(), reason="no mpirun next to sys.executable")
def test_mpi_scaling_quick(tmp_path):
    out = tmp_path / "scaling.csv"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
    proc = subprocess.run([sys.executable, str(REPO / "run_scripts" / "mpi_scaling.py"), "--quick",
                           "--ranks", "1,2", "--csv", str(out)],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = list(csv.DictReader(out.open()))
    assert [int(r["ranks"]) for r in rows] == [1, 2]
    assert len({r["particles"] for r in rows}) == 1
    assert float(rows[0]["efficiency"]) == pytest.approx(1.0)
    for r in rows:
        assert float(r["seconds_per_step"]) > 0
        assert 0.0 <= float(r["halo_share"]) <= 1.0 and 0.0 <= float(r["migrate_share"]) <= 1.0
    assert "eff." in proc.stdout


def test_cli_bench_error_is_one_line(capsys):
    import parmpm.__main__ as cli

    assert cli.main(["bench", "--steps", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("parmpm: error: bench: --steps must be >= 2")
