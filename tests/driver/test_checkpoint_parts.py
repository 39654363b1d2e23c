"""Checkpoints in parts (format version 4): each rank, or group of ranks, writes its own part file
and the top-level ``checkpoint_<step>.h5`` binds them with virtual datasets.

* unit: the grouping rule, segments, the index; a one-writer checkpoint and the collective
  single-file writer (run serially: PyPI's h5py has no MPI, so ``driver="mpio"`` itself is not
  exercised here) read back by patch;
* the crossing scene (migration, re-balancing) written on 1, 3 and 4 ranks and continued on 3, 2
  and 1: bit for bit the run that never stopped, every rank reading exactly its own rows;
* the one-file view: one dataset per field in h5py, also after the folder moved;
* faults: a missing or damaged part is one line naming it (exit 2); a rank killed while writing,
  or a kill after the parts and before the top-level file, leaves the previous checkpoint whole
  and the stale parts are cleared; ``keep`` prunes the parts too; a version-3 file still
  restarts bit for bit.
"""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import h5py
import numpy as np
import pytest
from cli_harness import parmpm_cli
from old_checkpoints import write_v3
from tools.rank_cases import CROSSING

from decomposition import SerialComm
from decomposition.layout import PatchLayout
from parmpm.core.errors import ParmpmError
from parmpm.io.checkpoint import FIELDS as ALL_FIELDS
from parmpm.io.checkpoint import OPTIONAL, parts_folder, remove_stale_tmp, segments_of
from parmpm.driver.checkpoint_writer import load_patches, write_checkpoint, write_collective
from parmpm.io.checkpoint import CheckpointReader, ranks_per_file
from parmpm.io.checkpoint.parts import rank_rows
from parmpm.particles.store import Particles

QUIET = ["--quiet"]
TIMEOUT = 600
CK30, CK60 = "checkpoint_00000030.h5", "checkpoint_00000060.h5"

#: the fields of these (FLIP) runs' checkpoints
FIELDS = tuple(k for k in ALL_FIELDS if k not in OPTIONAL)


# --- unit -----------------------------------------------------------------------------------------
def test_ranks_per_file_rule():
    assert [ranks_per_file(p, "auto") for p in (1, 8, 256, 257, 512, 10_000)] == [1, 1, 1, 2, 2, 40]
    assert ranks_per_file(4, 2) == 2 and ranks_per_file(4, 99) == 4 and ranks_per_file(1, 3) == 1


def test_segments_cut_each_patch_at_block_rows():
    assert segments_of([3, 0, 5, 1], 2).tolist() == [0, 2, 3, 5, 7, 8, 9]
    assert segments_of([], 4).tolist() == [0]
    first, index = rank_rows([(np.array([3, 1]), np.array([2, 5])), (np.array([0]), np.array([4]))], 5)
    assert first.tolist() == [0, 7, 11]
    assert index.tolist() == [[7, 4], [2, 5], [0, 0], [0, 2], [0, 0]]


def _synthetic(n=3000, seed=1, dim=2):
    """Particles spread over the 16 patches of a 16 x 16 grid, the layout and its stand-in disc."""
    lay = PatchLayout((16, 16), (4, 4), 2)
    disc = SimpleNamespace(layout=lay, origin3=np.zeros(3), h3=np.ones(3))
    rng = np.random.default_rng(seed)
    P = Particles(dim, n)
    P.gid[:] = rng.permutation(n)
    P.patch[:] = rng.integers(0, lay.n_patches, n)
    for k in FIELDS:
        if k not in ("gid", "mat"):
            getattr(P, k)[:] = rng.standard_normal(getattr(P, k).shape)
    return P, disc


def _attrs(n, ranks=1):
    return {"scene": "name = 'synthetic'", "step": 7, "time": 0.5, "dt": 1e-3, "vmax": 1.0,
            "method": "cpdi", "lcr": 0.2, "ranks": ranks, "particles": n, "dim": 2, "state": "{}",
            "lineage": "L"}


def _by_gid(P) -> dict:
    o = np.argsort(P.gid)
    return {k: getattr(P, k)[o] for k in FIELDS + (("patch",) if hasattr(P, "patch") else ())}


@pytest.mark.parametrize("how", ["one writer", "collective, serially"])
def test_a_rank_reads_exactly_the_rows_of_its_patches(tmp_path, how):
    P, disc = _synthetic()
    path = tmp_path / "checkpoint_00000007.h5"
    if how == "one writer":
        write_checkpoint(SerialComm(), P, path, P.n, _attrs(P.n), 3, "L", disc)
    else:
        order = np.lexsort((P.gid, P.patch))
        ids, counts = np.unique(P.patch[order], return_counts=True)
        first, index = rank_rows([(ids, counts)], disc.layout.n_patches)
        from parmpm.io.checkpoint.parts import layout_record
        top = {**_attrs(P.n), "layout": layout_record(disc)}
        write_collective(SerialComm(), P, order, path, top, {k: getattr(P, k)[:0] for k in FIELDS},
                         [(ids, counts)], first, index, 3, "L", driver=None)
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # one file, no parts
    r = CheckpointReader(path)
    assert r.version == 5 and r.indexed_for(disc)
    np.testing.assert_array_equal(r.patch_counts(), np.bincount(P.patch, minlength=16))
    mine = np.array([2, 3, 11])
    Q = load_patches(SerialComm(), r, 2, 1, mine)
    sel = np.isin(P.patch, mine)
    assert Q.n == sel.sum() and all(v == Q.n for v in r.rows_read.values())
    assert set(r.rows_read) == set(FIELDS)
    want = _by_gid(SimpleNamespace(**{k: getattr(P, k)[sel] for k in FIELDS + ("patch",)}))
    got = _by_gid(SimpleNamespace(**{k: getattr(Q, k) for k in FIELDS + ("patch",)}))
    for k in FIELDS + ("patch",):
        np.testing.assert_array_equal(got[k], want[k], err_msg=k)
    r.close()


# --- many writers without the solver: synthetic particles dealt out by patch ------------------------
WRITE = """
import sys
sys.path[:0] = [{tests!r}, {tests!r} + "/../harness", {tests!r} + "/../../run_scripts"]  # as pytest's pythonpath
import numpy as np
from pathlib import Path
from decomposition import world
import test_checkpoint_parts as t
from parmpm.core.errors import ParmpmError
from parmpm.io.checkpoint import space
from parmpm.driver.checkpoint_writer import write_checkpoint
comm = world()
if comm.Get_rank() == {full_rank}:  # this rank's disk is (nearly) full
    space.free_bytes = lambda folder: 10_000
P, disc = t._synthetic()
mine = P.patch % comm.Get_size() == comm.Get_rank()
P.permute(np.flatnonzero(mine))
try:
    write_checkpoint(comm, P, Path({path!r}), 3000, t._attrs(3000, comm.Get_size()), 3, "L", disc,
                     {rpf!r})
except ParmpmError as exc:
    print(f"rank {{comm.Get_rank()}}: {{exc}}", flush=True)
"""


def _write_synthetic(mpirun, path, rpf="auto", full_rank=-1):
    proc = subprocess.run([mpirun, "-n", "3", sys.executable, "-c", WRITE.format(
        tests=str(Path(__file__).parent), path=str(path), rpf=rpf, full_rank=full_rank)],
        capture_output=True, text=True, timeout=TIMEOUT)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout  # the ranks' lines, possibly interleaved


@pytest.fixture(scope="module")
def synthetic_parts(tmp_path_factory, mpirun):
    """A 3000-particle checkpoint written by 3 ranks, one part each, and by 3 ranks in files of
    2 ranks (2 parts)."""
    out = {}
    for rpf, parts in (("auto", 3), (2, 2)):
        folder = tmp_path_factory.mktemp(f"synthetic{parts}")
        path = folder / "checkpoint_00000007.h5"
        assert _write_synthetic(mpirun, path, rpf) == ""
        assert sorted(p.name for p in parts_folder(path).iterdir()) == \
            [f"part_{k:05d}.h5" for k in range(parts)]
        out[parts] = path
    return out


def _h5py_view(path) -> dict:
    """Every field as plain h5py reads it from the top-level file, sorted by gid."""
    with h5py.File(path, "r") as f:
        g = f["particles"]
        o = np.argsort(g["gid"][()])
        return {k: g[k][()][o] for k in g}, {k: g[k].is_virtual for k in g}


@pytest.mark.parametrize("parts", [3, 2])
def test_h5py_sees_one_dataset_per_field(synthetic_parts, parts):
    data, virtual = _h5py_view(synthetic_parts[parts])
    want = _by_gid(_synthetic()[0])
    assert sorted(data) == sorted(FIELDS) and all(virtual.values())
    for k in FIELDS:
        np.testing.assert_array_equal(data[k], want[k], err_msg=k)


def test_the_folder_can_be_moved(synthetic_parts, tmp_path):
    moved = tmp_path / "elsewhere" / "deeper"
    shutil.copytree(synthetic_parts[3].parent, moved)
    path = moved / synthetic_parts[3].name
    cwd = os.getcwd()
    os.chdir(tmp_path)  # neither the old folder nor the working directory holds the parts
    try:
        data, _ = _h5py_view(path)
        r = CheckpointReader(path)
        got = r.read("x")
        r.close()
    finally:
        os.chdir(cwd)
    want = _by_gid(_synthetic()[0])
    np.testing.assert_array_equal(data["x"], want["x"])
    assert got.shape == want["x"].shape


def test_a_full_disk_at_one_lead_is_one_line_on_every_rank(synthetic_parts, tmp_path, mpirun):
    """Rank 1 finds its disk full: every rank raises the same line naming its part, the new
    checkpoint's parts are removed and the earlier checkpoint in the folder stays whole."""
    shutil.copytree(synthetic_parts[3].parent, tmp_path, dirs_exist_ok=True)
    earlier = {p: p.read_bytes() for p in sorted(tmp_path.rglob("*.h5"))}
    path = tmp_path / "checkpoint_00000008.h5"
    out = _write_synthetic(mpirun, path, full_rank=1)
    part = parts_folder(path) / "part_00001.h5"
    line = f"disk full writing '{part}': 0.5 MB needed, 0.0 MB free"
    assert all(f"rank {r}: {line}" in out for r in range(3)) and out.count(line) == 3, out
    assert not path.exists() and not parts_folder(path).exists()
    assert {p: p.read_bytes() for p in sorted(tmp_path.rglob("*.h5"))} == earlier
    assert _read_everything(synthetic_parts[3])["x"].shape == (3000, 2)


def _flip(path: Path, at: float, width: int = 16) -> None:
    b = bytearray(path.read_bytes())
    i = int(len(b) * at)
    for j in range(i, min(i + width, len(b))):
        b[j] ^= 0xFF
    path.write_bytes(bytes(b))


def _read_everything(path):
    r = CheckpointReader(path)
    try:
        return {k: r.read(k) for k in FIELDS}
    finally:
        r.close()


def test_random_bit_flips_in_parts_and_top_never_read_different_data(synthetic_parts, tmp_path):
    """200 single-bit flips (seeded), each in a fresh copy of the top-level file or of a part:
    a one-line ParmpmError naming the damaged file, or every field read back identical."""
    src = synthetic_parts[3].parent
    ref = _read_everything(synthetic_parts[3])
    rng = np.random.default_rng(17)
    files = [synthetic_parts[3].name] + [f"{parts_folder(synthetic_parts[3]).name}/part_0000{k}.h5"
                                         for k in range(3)]
    failed = 0
    for trial in range(200):
        work = tmp_path / f"t{trial}"
        shutil.copytree(src, work)
        victim = work / files[trial % 4]
        b = bytearray(victim.read_bytes())
        bit = int(rng.integers(0, 8 * len(b)))
        b[bit // 8] ^= 1 << (bit % 8)
        victim.write_bytes(bytes(b))
        try:
            got = _read_everything(work / synthetic_parts[3].name)
        except ParmpmError as exc:
            assert "\n" not in str(exc) and str(victim) in str(exc), (files[trial % 4], bit, str(exc))
            failed += 1
        else:
            for k in FIELDS:
                assert np.array_equal(got[k], ref[k]), (files[trial % 4], bit, k)
        shutil.rmtree(work)
    assert failed > 60


# --- the solver: write on N ranks, continue on M ------------------------------------------------------
def _cli(mpirun, n, *args, timeout=TIMEOUT):
    return parmpm_cli(*args, ranks=n, mpirun=mpirun, timeout=timeout)


RESTART = """
import json, sys
from pathlib import Path
import parmpm.driver.restart as rs
from decomposition import world
from parmpm.core.log import setup_logging
from parmpm.driver.simulation import Simulation
readers = []
class Counting(rs.CheckpointReader):
    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        readers.append(self)
rs.CheckpointReader = Counting
comm = world()
setup_logging(comm.Get_rank(), comm.Get_size(), quiet=True)
sim = Simulation.from_checkpoint(sys.argv[1], sys.argv[4:], out_dir=sys.argv[2], quiet=True,
                                 comm=comm)
loaded, rows = sim.particles.n, dict(readers[0].rows_read)
sim.run()
Path(sys.argv[3], f"rows_{comm.Get_rank()}.json").write_text(json.dumps([loaded, rows]))
"""


@pytest.fixture(scope="module")
def runs(tmp_path_factory, mpirun):
    """60 steps of the crossing scene on 1, 3 and 4 ranks, a checkpoint every 30 steps."""
    root = tmp_path_factory.mktemp("parts")
    out = {}
    for n in (1, 3, 4):
        d = root / f"cross{n}"
        proc = _cli(mpirun, n, "run", CROSSING, "-o", str(d), *QUIET,
                    "--set", "checkpoint.every_steps=30")
        assert proc.returncode == 0, proc.stderr
        out[n] = d
    return out


def _same_particles(a, b):
    pa, pb = _h5py_view(a)[0], _h5py_view(b)[0]
    assert pa.keys() == pb.keys()
    for k in pa:
        np.testing.assert_array_equal(pa[k], pb[k], err_msg=k)
    with h5py.File(a) as fa, h5py.File(b) as fb:
        for k in ("step", "time", "dt", "vmax"):
            assert fa.attrs[k] == fb.attrs[k], k


def _restart(mpirun, m, path, out, *overrides):
    """Continue ``path`` on ``m`` ranks; each rank's (particles loaded, rows read per field)."""
    counts = Path(str(out) + "_rows")
    counts.mkdir()
    cmd = [sys.executable, "-c", RESTART, str(path), str(out), str(counts), *overrides]
    proc = subprocess.run([mpirun, "-n", str(m)] + cmd, capture_output=True, text=True,
                          timeout=TIMEOUT)
    assert proc.returncode == 0, proc.stderr
    return [json.loads((counts / f"rows_{r}.json").read_text()) for r in range(m)]


@pytest.mark.parametrize("first,then", [(1, 3), (3, 2), (4, 1)])
def test_restart_n_to_m_is_bit_identical_and_reads_only_its_own_rows(runs, tmp_path, mpirun,
                                                                     first, then):
    path = runs[first] / CK30
    per_rank = _restart(mpirun, then, path, tmp_path)
    _same_particles(runs[first] / CK60, tmp_path / CK60)
    _same_particles(runs[1] / CK60, tmp_path / CK60)
    with h5py.File(path) as f:
        n, parts = int(f.attrs["particles"]), int(f.attrs["part_files"])
    assert parts == first
    assert sum(loaded for loaded, _ in per_rank) == n
    for loaded, rows in per_rank:  # every field: exactly this rank's rows, nothing more
        assert rows == {k: loaded for k in FIELDS}, (loaded, rows)


def test_another_patch_grid_reads_every_position_and_continues(runs, tmp_path, mpirun):
    """A restart that overrides the patch size cannot use the index: every rank reads every
    position to find its patches (as before version 4), then its rows."""
    path = runs[3] / CK30
    per_rank = _restart(mpirun, 2, path, tmp_path, "grid.patch_size=4")
    with h5py.File(path) as f:
        n = int(f.attrs["particles"])
    assert sum(loaded for loaded, _ in per_rank) == n
    for loaded, rows in per_rank:
        assert rows["x"] >= n + loaded and rows["gid"] >= loaded
    assert (tmp_path / CK60).is_file()  # another discretisation: not the same bits (measured)


def test_old_format_restarts_bit_identically(runs, tmp_path, mpirun):
    """The 1-rank step-30 checkpoint rewritten as version 3 wrote it (global-id order, fixed
    blocks): continued on 2 ranks, the same step 60."""
    data, _ = _h5py_view(runs[1] / CK30)
    with h5py.File(runs[1] / CK30) as f:
        attrs = {k: f.attrs[k] for k in ("scene", "step", "time", "dt", "vmax", "method", "lcr",
                                         "ranks", "particles", "dim", "state", "lineage")}
    old = tmp_path / "old"
    old.mkdir()
    assert "affine" not in data  # a FLIP run carries none (version 3 had no such field)
    write_v3(old / CK30, data, attrs, block_rows=64)
    _restart(mpirun, 2, old / CK30, tmp_path / "r")
    _same_particles(runs[1] / CK60, tmp_path / "r" / CK60)


def test_a_moved_run_folder_restarts(runs, tmp_path):
    moved = tmp_path / "moved"
    shutil.copytree(runs[3], moved)
    proc = _cli(None, 1, "restart", str(moved / CK30), "-o", str(tmp_path / "r"), *QUIET)
    assert proc.returncode == 0, proc.stderr
    _same_particles(runs[1] / CK60, tmp_path / "r" / CK60)


@pytest.mark.parametrize("how", ["missing", "damaged", "foreign"])
def test_a_bad_part_is_one_line_naming_it(runs, tmp_path, mpirun, how):
    work = tmp_path / "w"
    shutil.copytree(runs[3], work)
    part = parts_folder(work / CK30) / "part_00001.h5"
    if how == "missing":
        part.unlink()
    elif how == "damaged":
        _flip(part, 0.6)
    else:  # the same part of another checkpoint
        shutil.copy(parts_folder(work / CK60) / "part_00001.h5", part)
    proc = _cli(mpirun, 2, "restart", str(work / CK30), "-o", str(tmp_path / "r"), *QUIET)
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("parmpm: error:")]
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert f"part '{part}'" in lines[0] and "Traceback" not in proc.stderr, proc.stderr
    assert {"missing": "no such file", "damaged": "damaged",
            "foreign": "another checkpoint"}[how] in lines[0]


KILL = """
import os, sys
from parmpm.io import checkpoint
from parmpm.driver.checkpoint_writer import groups as checkpoint_gather
from parmpm.cli.main import main
how = os.environ["KILL_HOW"]
write, top = checkpoint.CheckpointWriter.write, checkpoint_gather.write_top
def killed_write(self, lo, block):  # rank 1's part of step 10, after its first block
    write(self, lo, block)
    if how == "part" and "checkpoint_00000010.parts" in str(self.path) and "part_00001" in str(self.path):
        self.f.flush()
        os._exit(9)
def killed_top(path, *args, **kwargs):  # every part written, the top-level file not yet
    if how == "top" and path.name == "checkpoint_00000010.h5":
        os._exit(9)
    return top(path, *args, **kwargs)
checkpoint.CheckpointWriter.write = killed_write
checkpoint_gather.write_top = killed_top
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize("how", ["part", "top"])
def test_a_kill_while_writing_leaves_the_previous_checkpoint_whole(tmp_path, mpirun, how):
    d = tmp_path / "run"
    proc = subprocess.run([mpirun, "-n", "2", sys.executable, "-c", KILL, "run", CROSSING,
                           "-o", str(d), *QUIET, "--set", "checkpoint.every_steps=5",
                           "--set", "time.steps=20"],
                          capture_output=True, text=True, timeout=TIMEOUT,
                          env={**os.environ, "KILL_HOW": how})
    assert proc.returncode != 0
    assert not (d / "checkpoint_00000010.h5").exists()
    stale = parts_folder(d / "checkpoint_00000010.h5")
    assert stale.is_dir()
    before = {p: p.read_bytes() for p in sorted(parts_folder(d / "checkpoint_00000005.h5").iterdir())}
    assert len(before) == 2
    gone = remove_stale_tmp(d)  # what the next run claiming the folder does
    assert stale in gone and not stale.exists()
    assert {p: p.read_bytes() for p in before} == before
    proc = _cli(mpirun, 2, "restart", str(d / "checkpoint_00000005.h5"), "-o", str(tmp_path / "r"),
                "--set", "time.steps=10", *QUIET)
    assert proc.returncode == 0, proc.stderr


def test_keep_prunes_the_parts_too(tmp_path, mpirun):
    d = tmp_path / "run"
    proc = _cli(mpirun, 2, "run", CROSSING, "-o", str(d), *QUIET, "--set", "time.steps=40",
                "--set", "checkpoint.every_steps=10", "--set", "checkpoint.keep=2")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in d.glob("checkpoint_*")) == [
        "checkpoint_00000030.h5", "checkpoint_00000030.parts",
        "checkpoint_00000040.h5", "checkpoint_00000040.parts"]


# --- a checkpoint's parts stay in its own .parts folder (issue 28, item 8) -------------------------
def _write_in_parts(path: Path, n_parts: int = 2, names=None, where=None) -> None:
    """A checkpoint in ``n_parts`` parts written here, as the leads and rank 0 write one, but with
    the part table and virtual datasets naming ``names`` (relative to ``path``'s folder; default
    the writer's own) and each part file written at ``where[k]`` (default: where it is named):
    what a crafted file with valid (keyless) digests looks like."""
    from parmpm.io.checkpoint import PART_FORMAT, CheckpointWriter, part_name
    from parmpm.io.checkpoint.parts import layout_record, top_tables, write_top

    P, disc = _synthetic()
    order = np.lexsort((P.gid, P.patch))
    fields = {k: getattr(P, k)[order] for k in FIELDS}
    patch = P.patch[order]
    cut = np.searchsorted(patch, [disc.layout.n_patches * k // n_parts for k in range(n_parts + 1)])
    cut[-1] = P.n
    names = names or [f"{parts_folder(path).name}/{part_name(k)}" for k in range(n_parts)]
    where = where or [path.parent / name for name in names]
    like = {k: v[:0] for k, v in fields.items()}
    files = []
    for k in range(n_parts):
        lo, hi = int(cut[k]), int(cut[k + 1])
        ids, counts = np.unique(patch[lo:hi], return_counts=True)
        Path(where[k]).parent.mkdir(parents=True, exist_ok=True)
        w = CheckpointWriter(Path(where[k]), hi - lo, like,
                             {"part": k, "parts": n_parts, "first_row": lo, "rows": hi - lo,
                              "step": 7, "lineage": "L"}, segments=segments_of(counts),
                             fmt=PART_FORMAT)
        w.write(0, {f: v[lo:hi] for f, v in fields.items()})
        files.append((names[k], w.commit(None)))
    ids, counts = np.unique(patch, return_counts=True)
    _, index = rank_rows([(ids, counts)], disc.layout.n_patches)
    top = {**_attrs(P.n), "layout": layout_record(disc), "part_files": n_parts,
           "ranks_per_file": 1}
    write_top(path, top, like, [(name, int(cut[k]), int(cut[k + 1] - cut[k]))
                                for k, (name, _) in enumerate(files)],
              P.n, top_tables(index, cut, files))


def _read_all(path: Path) -> np.ndarray:
    r = CheckpointReader(path)
    try:
        return r.read("x")
    finally:
        r.close()


def test_parts_written_here_read_back(tmp_path):
    """The crafting helper writes a sound checkpoint (so the refusals below are for the names)."""
    path = tmp_path / "checkpoint_00000007.h5"
    _write_in_parts(path)
    assert sorted(p.name for p in parts_folder(path).iterdir()) == ["part_00000.h5",
                                                                    "part_00001.h5"]
    np.testing.assert_array_equal(np.sort(_read_all(path)[:, 0]),
                                  np.sort(_synthetic()[0].x[:, 0]))


@pytest.mark.parametrize("crafted", ["absolute", "dotdot", "another folder", "dot", "nested",
                                     "backslash"])
def test_a_part_named_outside_its_folder_is_refused_alike_whether_it_exists(tmp_path, crafted):
    """Before: the names were joined to the folder unchecked, so a crafted checkpoint (valid,
    keyless digests) restarted from parts anywhere, and its error told whether a path existed.
    Now any name but ``<checkpoint>.parts/<file>`` is one line, the same whether that path
    exists or not."""
    lines = []
    for exists in (True, False):
        d = tmp_path / str(exists)
        path = d / "run" / "checkpoint_00000007.h5"
        outside = d / "elsewhere" / "part_00001.h5"
        name = {"absolute": str(outside), "dotdot": "../elsewhere/part_00001.h5",
                "another folder": "checkpoint_00000003.parts/part_00001.h5", "dot": ".",
                "nested": "checkpoint_00000007.parts/sub/part_00001.h5",
                "backslash": "checkpoint_00000007.parts/..\\part_00001.h5"}[crafted]
        target = {"absolute": outside, "dotdot": outside}.get(crafted, path.parent / name)
        if crafted == "dot":
            target = outside  # (the file of a "." part can be nowhere: written aside)
        _write_in_parts(path, names=["checkpoint_00000007.parts/part_00000.h5", name],
                        where=[parts_folder(path) / "part_00000.h5", target])
        if not exists:
            Path(target).unlink()
        with pytest.raises(ParmpmError) as info:
            _read_all(path)
        lines.append(str(info.value).replace(str(d), "D"))
    assert lines[0] == lines[1]
    assert "\n" not in lines[0] and "part 1 is named" in lines[0], lines[0]
    assert "not a file in 'checkpoint_00000007.parts/'" in lines[0], lines[0]


def test_a_part_that_is_a_link_out_of_its_folder_is_refused_alike(tmp_path):
    lines = []
    for exists in (True, False):
        d = tmp_path / str(exists)
        path = d / "checkpoint_00000007.h5"
        _write_in_parts(path)
        link = parts_folder(path) / "part_00001.h5"
        outside = d / "elsewhere" / "part_00001.h5"
        outside.parent.mkdir()
        if exists:
            link.rename(outside)
        else:
            link.unlink()
        link.symlink_to(Path("..") / "elsewhere" / "part_00001.h5")
        with pytest.raises(ParmpmError) as info:
            _read_all(path)
        lines.append(str(info.value).replace(str(d), "D"))
    assert lines[0] == lines[1] and "a link that leads out of" in lines[0], lines[0]
    # a link inside the folder (and a parts folder that is itself a link) still reads
    d = tmp_path / "inside"
    path = d / "checkpoint_00000007.h5"
    _write_in_parts(path)
    store = tmp_path / "store"
    parts_folder(path).rename(store)
    parts_folder(path).symlink_to(store)
    (store / "part_00001.h5").rename(store / "real_00001.h5")
    (store / "part_00001.h5").symlink_to("real_00001.h5")
    assert _read_all(path).shape == (3000, 2)


def test_a_crafted_checkpoint_is_one_line_from_the_cli(tmp_path):
    path = tmp_path / "checkpoint_00000007.h5"
    _write_in_parts(path, names=["checkpoint_00000007.parts/part_00000.h5", "/etc/hostname"],
                    where=[parts_folder(path) / "part_00000.h5", tmp_path / "x" / "p.h5"])
    proc = _cli(None, 1, "restart", str(path), "-o", str(tmp_path / "r"), *QUIET)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert "'/etc/hostname', not a file in" in lines[0] and not (tmp_path / "r").exists()
