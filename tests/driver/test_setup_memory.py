"""Set-up memory is O(N/P): no rank ever builds a whole-scene particle array, and the results
are those of one rank.

For every body kind (1D, 2D and 3D boxes, turned boxes, a disk, a sphere) and every metrics
kind, each scene runs on 1 rank (one block of seeds: the whole body) and on 2 and 3 ranks with
blocks of :data:`SMALL_BLOCK` lattice points. On every rank, the largest particle array seeding
built (:data:`parmpm.particles.seeding.WATCH`: positions, patch ids, masks, global ids) is at most the
rank's own particles plus one block, the metrics hold no particle field and no array of the
scene's size, and the final state and summary equal the 1-rank run's, bit for bit.

This file is also the driver the test launches::

    mpirun -n 3 python tests/driver/test_setup_memory.py OUT_DIR BLOCK
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

OFF = ["output.snapshots=false", "output.figure=false"]
CASES = {
    "box_1d": ["hanging_bar_1d", ["grid.patch_size=4", "bodies.0.ppc=12", "time.steps=10"]],
    "box_2d": ["hanging_bar", ["grid.patch_size=4", "time.steps=10"]],
    "box_3d": ["hanging_bar_3d", ["grid.patch_size=3", "bodies.0.ppc=2", "time.steps=3"]],
    "turned": ["tension_bar", ["grid.patch_size=8", "bodies.0.angle=5.0", "bodies.2.angle=10.0",
                               "time.steps=10"]],
    "disk": ["spinning_disk", ["grid.patch_size=6", "time.steps=10", "metrics.every_steps=5"]],
    "disk_idle": ["spinning_disk", ["grid.patch_size=24", "time.steps=5"]],  # one patch
    "sphere": ["hanging_bar_3d", ["bodies.0={shape='sphere', center=[0.5, -0.5, 0.5], "
                                  "radius=0.45, material='bar', ppc=2}", "grid.patch_size=3",
                                  "time.steps=3"]],
    "manufactured": ["manufactured", ["grid.patch_size=5", "time.steps=10"]],
    "vibrating": ["vibrating_bar", ["grid.patch_size=16", "time.steps=20"]],  # 3 ranks: one idle
}
SMALL_BLOCK = 16  # = seeding.ALIGN: the smallest block, the most of them
FIELDS = ("gid", "x", "v", "F", "stress", "damage")


def _largest_metric_array(metrics) -> int:
    """The most rows of any array the metrics object keeps (0 when it keeps none)."""
    rows = [np.shape(v)[0] for v in vars(metrics).values()
            if isinstance(v, np.ndarray) and np.ndim(v) > 0]
    return max(rows, default=0)


def main() -> None:
    from decomposition import world
    from parmpm import Simulation, load_scene
    from parmpm.particles import seeding
    from parmpm.driver.warm_up import compile_first
    from parmpm.core.log import setup_logging

    out, block = Path(sys.argv[1]), int(sys.argv[2])
    comm = world()
    setup_logging(comm.Get_rank(), comm.Get_size(), quiet=True)
    seeding.BLOCK = block
    for name, (scene, overrides) in CASES.items():
        sc = load_scene(scene, OFF + overrides)
        compile_first(sc, comm)  # rank 0 and 1 seed the scene (small) or a tiny one: not counted
        seeding.WATCH.reset()
        sim = Simulation(sc, out / name, quiet=True, comm=comm, overwrite=True)
        m = sim.state.metrics
        mine = {"own": sim.particles.n, "largest": seeding.WATCH.largest,
                "metric_rows": _largest_metric_array(m),
                "metric_fields": [k for k in ("x0", "mass") if getattr(m, k, None) is not None]}
        summary = sim.run()
        P = sim.particles
        g = sim.gather({"gid": P.gid, "x": P.x, "v": P.v, "F": P.F, "stress": P.stress,
                        "damage": P.damage})
        ranks = comm.gather(mine, root=0)
        if comm.Get_rank() == 0:
            np.savez(out / f"{name}.npz", summary=json.dumps(summary), ranks=json.dumps(ranks), **g)


@pytest.fixture(scope="module")
def runs(tmp_path_factory, mpirun):
    root = tmp_path_factory.mktemp("setup_memory")
    out, procs = {}, {}
    for n, block in ((1, 1 << 16), (2, SMALL_BLOCK), (3, SMALL_BLOCK)):  # side by side
        out[n] = root / f"np{n}"
        out[n].mkdir()
        procs[n] = subprocess.Popen([mpirun, "-n", str(n), sys.executable, __file__, str(out[n]),
                                     str(block)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                    text=True)
    for n, proc in procs.items():
        try:
            _, err = proc.communicate(timeout=300)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
        assert proc.returncode == 0, f"{n} ranks failed:\n{err[-3000:]}"
    return out


def _load(folder: Path, case: str):
    data = np.load(folder / f"{case}.npz")
    return ({k: data[k] for k in FIELDS}, json.loads(str(data["summary"])),
            json.loads(str(data["ranks"])))


@pytest.mark.parametrize("case", list(CASES))
def test_no_rank_holds_the_whole_scene_and_results_are_one_ranks(runs, case):
    from parmpm.particles.seeding import ALIGN

    ref, ref_summary, _ = _load(runs[1], case)
    n_total = ref["gid"].size
    assert ref_summary["steps"] > 0 and n_total == ref_summary["particles"]
    for n in (2, 3):
        got, summary, ranks = _load(runs[n], case)
        assert summary["ranks"] == n and len(ranks) == n
        for r, info in enumerate(ranks):
            bound = info["own"] + SMALL_BLOCK + ALIGN - 1
            assert info["largest"] <= bound, (case, n, r, info)
            assert info["metric_fields"] == [], (case, n, r, info)
            assert info["metric_rows"] < max(n_total, 2), (case, n, r, info)
        for k in FIELDS:
            np.testing.assert_array_equal(got[k], ref[k], err_msg=f"{case}: {k} on {n} ranks")
        for k in ("metrics", "final", "steps", "time"):
            assert summary[k] == ref_summary[k], f"{case}: summary {k} differs on {n} ranks"


@pytest.mark.slow
def test_setup_memory_study_quick(tmp_path):
    """``run_scripts/benchmarks/setup_memory.py --quick``: on 2 ranks the largest rank's set-up memory is
    well under the 1-rank run's (about half, plus a constant)."""
    from study_harness import read_csv, run_quick

    out = run_quick("benchmarks/setup_memory.py", tmp_path / "out", timeout=300)
    rows = read_csv(out / "setup_memory.csv")
    two = [r for r in rows if r["ranks"] == "2"]
    assert {r["case"] for r in two} == {"disk", "box"}
    for r in two:
        assert float(r["share_setup_mb"]) < 0.75, r
    assert (out / "setup_memory.png").exists()


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "harness"))
    from mpi_script import run_or_abort

    run_or_abort(main)
