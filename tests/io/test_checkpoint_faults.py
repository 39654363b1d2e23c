"""Checkpoint and snapshot files under faults: flipped bits (every corruption either reads back
identical data or is a one-line error naming the file), full disks and read-only folders (one
line, the temporary file removed, earlier checkpoints intact, no crash), pruning by lineage and
the clean-up of leftover temporary files. The files here are one-writer (version 4) checkpoints
written as the run driver writes them, and version 1-3 files as those versions wrote them; the
part files of many writers are tests/driver/test_checkpoint_parts.py's.

The full-filesystem tests mount a small tmpfs (root only; skipped where mounting is not
permitted); the read-only tests mount it read-only (root, who ignores permissions) or take the
write permission off a folder (any other user)."""
import errno
import logging
import os
import shutil
import subprocess
import sys
from collections import namedtuple
from pathlib import Path

import h5py
import numpy as np
import pytest

from parmpm.core.errors import ParmpmError
from parmpm.io import SnapshotWriter
from parmpm.io import checkpoint as ck
from parmpm.io.checkpoint import (FIELDS, CheckpointWriter, attrs_digest, estimate_bytes, prune,
                                  remove_stale_tmp)
from parmpm.io.checkpoint import CheckpointReader
from old_checkpoints import write_v3
from parmpm.io.checkpoint.format import PLASTIC_WIDTH
from parmpm.io.checkpoint.parts import top_tables

DIM = 2
TAIL = {"x": (DIM,), "v": (DIM,), "x0": (DIM,), "lh0": (DIM,),
        "F": (DIM, DIM), "stress": (DIM, DIM), "r0": (DIM, DIM), "rf": (DIM, DIM),
        "affine": (DIM, DIM), "corners": (1 << DIM, DIM), "plastic": (PLASTIC_WIDTH,)}


def _fields(n, seed=0):
    rng = np.random.default_rng(seed)
    out = {}
    for k in FIELDS:
        if k == "gid":
            out[k] = np.arange(n, dtype=np.int64)
        elif k == "mat":
            out[k] = rng.integers(0, 3, n).astype(np.int64)
        else:
            out[k] = rng.standard_normal((n,) + TAIL.get(k, ()))
    return out


#: one patch: the whole file is its rows (the index is then trivial)
LAYOUT = '{"cells": [4, 4], "patch_size": [4, 4], "ghost": 2, "origin": [0, 0, 0], "h": [1, 1, 1]}'


def _attrs(n, lineage=None, v4=True):
    a = {"scene": 'name = "fault"\n[grid]\ncells = [4, 4]\n', "step": 7, "time": 0.25,
         "dt": 1e-3, "vmax": 12.5, "method": "cpdi", "lcr": 0.2, "ranks": 1, "particles": n,
         "dim": DIM, "state": '{"metrics": null, "next_output": 0.5}'}
    if v4:
        a.update(layout=LAYOUT, part_files=1)
    if lineage is not None:
        a["lineage"] = lineage
    return a


def _writer(path, n, data, block_rows=512, lineage=None):
    return CheckpointWriter(path, n, {k: v[:0] for k, v in data.items()}, _attrs(n, lineage),
                            block_rows=block_rows)


def _tables(n):
    return top_tables(np.array([[0, n]]), [0, n], [(".", "")])


def _write(path, n=200, block_rows=64, step=128, seed=0, lineage=None):
    """A one-writer checkpoint written as the run driver writes one: ascending blocks of
    ``step`` rows, digest segments of ``block_rows``."""
    data = _fields(n, seed)
    w = _writer(path, n, data, block_rows, lineage)
    for lo in range(0, n, step):
        w.write(lo, {k: v[lo:lo + step] for k, v in data.items()})
    w.commit(_tables(n))
    return data


def _read_all(path, block):
    """Every field through the restart's read path: CheckpointReader, ``read`` in blocks."""
    r = CheckpointReader(path)
    try:
        out = {"attrs": {k: str(v) for k, v in r.attrs.items()}, "state": r.state}
        for name in FIELDS:
            if r.has(name):
                out[name] = np.concatenate([r.read(name, lo, min(lo + block, r.n))
                                            for lo in range(0, r.n, block)] or [r.read(name)])
        return out
    finally:
        r.close()


def _same(a, b):
    return a.keys() == b.keys() and all(
        a[k] == b[k] if k in ("attrs", "state") else
        (a[k].dtype == b[k].dtype and np.array_equal(a[k], b[k])) for k in a)


def _one_line_naming(exc, path):
    msg = str(exc)
    return "\n" not in msg and str(path) in msg


# --- silent corruption ----------------------------------------------------------------------------
def test_random_single_bit_flips_never_read_different_data(tmp_path):
    """300 single-bit flips (seeded), each on a fresh copy, anywhere in a small checkpoint (4
    digest segments per field): each is a one-line ParmpmError naming the file or reads back
    every field and attribute identical. Before the data digests (version 3), flips in a chunk
    index read whole chunks back as zeros, without an error."""
    good = tmp_path / "checkpoint_00000007.h5"
    _write(good)
    ref = _read_all(good, 128)
    data = good.read_bytes()
    rng = np.random.default_rng(2026)
    bad = tmp_path / "checkpoint_flipped.h5"
    failed = same = 0
    for bit in rng.integers(0, 8 * len(data), 300):
        b = bytearray(data)
        b[bit // 8] ^= 1 << int(bit % 8)
        bad.write_bytes(bytes(b))
        try:
            got = _read_all(bad, 128)
        except ParmpmError as exc:
            assert _one_line_naming(exc, bad), (int(bit), str(exc))
            failed += 1
            continue
        assert _same(got, ref), f"bit {int(bit)} (byte {int(bit) // 8}) read back different data"
        same += 1
    assert failed + same == 300 and failed > 100  # most bytes are data or checked metadata


def test_data_rewritten_through_hdf5_fails_its_digest(tmp_path):
    """Data that HDF5 itself accepts (rewritten through h5py — as a misdirected address would
    read) fail the segment digest; a read inside a segment checks the whole segment."""
    path = tmp_path / "checkpoint_00000007.h5"
    _write(path)
    with h5py.File(path, "r+") as f:
        f["particles/x0"][70:71] = 0.0
    r = CheckpointReader(path)
    np.testing.assert_array_equal(r.read("x0", 0, 64), _fields(200)["x0"][:64])  # block 0 fine
    with pytest.raises(ParmpmError, match=r"particles/x0: rows 64\.\.127 fail their digest") as e:
        r.read("x0", 0, 128)
    assert _one_line_naming(e.value, path)
    with pytest.raises(ParmpmError, match="fail their digest"):
        r.read("x0", 70, 71)  # a read inside a block checks the whole block
    r.close()


def test_changed_digest_table_fails_on_open(tmp_path):
    path = tmp_path / "checkpoint_00000007.h5"
    _write(path)
    with h5py.File(path, "r+") as f:
        f["digests/F"][1, 0] ^= 1
    with pytest.raises(ParmpmError, match="fail their checksum") as e:
        CheckpointReader(path)
    assert _one_line_naming(e.value, path)


def test_wrong_dtype_is_refused_on_open(tmp_path):
    """A dataset of another type (here float32 mass, with the digests made consistent again) is
    refused by its type, before any data are read."""
    path = tmp_path / "checkpoint_00000007.h5"
    _write(path)
    with h5py.File(path, "r+") as f:
        mass = f["particles/mass"][()]
        del f["particles/mass"]
        f["particles"].create_dataset("mass", data=mass.astype(np.float32), chunks=(64,))
    with pytest.raises(ParmpmError, match="particles/mass is of type float32, expected float64"):
        CheckpointReader(path)


def test_lineage_is_covered_by_the_attribute_digest(tmp_path):
    path = tmp_path / "checkpoint_00000007.h5"
    _write(path, lineage="run-a")
    r = CheckpointReader(path)
    assert r.attrs["lineage"] == "run-a"
    r.close()
    with h5py.File(path, "r+") as f:
        f.attrs["lineage"] = "run-b"
    with pytest.raises(ParmpmError, match="attributes .* fail their checksum"):
        CheckpointReader(path)


def _write_old(path, version, n=50, seed=0):
    """A version 1 or 2 file as those versions wrote them (no digests; v1 without rf)."""
    data = _fields(n, seed)
    del data["affine"]  # before version 5
    if version == 1:
        del data["rf"]
    attrs = _attrs(n, v4=False)
    with h5py.File(path, "w") as f:
        f.attrs["format"] = ck.FORMAT
        f.attrs["version"] = version
        for k, v in attrs.items():
            f.attrs[k] = v
        f.attrs["digest"] = attrs_digest({k: f.attrs[k] for k in ck.ATTRS})
        g = f.create_group("particles")
        for k, v in data.items():
            g.create_dataset(k, data=v, chunks=v.shape, fletcher32=True)
    return data


@pytest.mark.parametrize("version", [1, 2])
def test_older_versions_still_read_with_a_warning(tmp_path, caplog, version):
    path = tmp_path / "checkpoint_00000007.h5"
    data = _write_old(path, version)
    with caplog.at_level(logging.WARNING, logger="parmpm.io.checkpoint"):
        got = _read_all(path, 16)
    assert [k for k in FIELDS if k in got] == [k for k in FIELDS if k in data]
    for k in data:
        np.testing.assert_array_equal(got[k], data[k])
    assert f"format version {version}: its data carry no digests" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="parmpm.io.checkpoint"):
        CheckpointReader(path, warn=False).close()  # the other ranks of a restart
    assert caplog.text == ""


def test_version_3_still_reads_and_checks_its_digests(tmp_path, caplog):
    path = tmp_path / "checkpoint_00000007.h5"
    data = _fields(333)
    del data["affine"]  # before version 5
    write_v3(path, data, _attrs(333, lineage="old", v4=False), block_rows=64)
    with caplog.at_level(logging.WARNING, logger="parmpm.io.checkpoint"):
        r = CheckpointReader(path)
    assert caplog.text == "" and r.version == 3 and r.attrs["lineage"] == "old"
    assert r.patch_rows is None and r.patch_counts() is None and not r.has("affine")
    for k in data:
        for lo, hi in ((0, None), (5, 300), (63, 65), (333, 333)):
            np.testing.assert_array_equal(r.read(k, lo, hi), data[k][lo:hi], err_msg=k)
    r.close()
    with h5py.File(path, "r+") as f:
        f["particles/v"][100] = 0.0
    r = CheckpointReader(path)
    with pytest.raises(ParmpmError, match=r"particles/v: rows 64\.\.127 fail their digest"):
        r.read("v", 0, 333)
    r.close()


def test_round_trip_with_unaligned_blocks(tmp_path):
    """Writes of 100 rows over digest segments of 64, reads of any slice: exact; a read takes
    only the segments it touches."""
    path = tmp_path / "checkpoint_00000007.h5"
    data = _write(path, n=333, block_rows=64, step=100)
    r = CheckpointReader(path)
    assert r.version == ck.VERSION == 5 and r.attrs.get("lineage") is None
    for k in FIELDS:
        for lo, hi in ((0, None), (0, 64), (5, 300), (320, 333), (63, 65), (333, 333)):
            np.testing.assert_array_equal(r.read(k, lo, hi), data[k][lo:hi], err_msg=k)
    r.rows_read.clear()
    r.read("x", 64, 128)
    r.read("x", 70, 130)
    assert r.rows_read == {"x": 64 + 128}
    r.close()


def test_writer_refuses_blocks_out_of_order(tmp_path):
    path = tmp_path / "checkpoint_00000007.h5"
    data = _fields(100)
    w = _writer(path, 100, data, block_rows=32)
    with pytest.raises(ParmpmError, match="block at row 50 .expected 0"):
        w.write(50, {k: v[50:] for k, v in data.items()})
    w.abort()
    assert list(tmp_path.iterdir()) == []


# --- size estimate and full disks -----------------------------------------------------------------
@pytest.mark.parametrize("n,block_rows", [(0, 64), (1, 64), (200, 64), (1000, 64), (70000, 65536)])
def test_size_estimate_bounds_the_file(tmp_path, n, block_rows):
    path = tmp_path / "checkpoint_00000007.h5"
    data = _write(path, n=n, block_rows=block_rows, step=4096)
    est = estimate_bytes(n, {k: v[:0] for k, v in data.items()}, _attrs(n), block_rows)
    size = path.stat().st_size
    assert size <= est <= 1.05 * size + 512 * 1024


Usage = namedtuple("Usage", "total used free")


def test_disk_full_before_writing_is_one_line(tmp_path, monkeypatch):
    monkeypatch.setattr(shutil, "disk_usage", lambda p: Usage(10**9, 10**9 - 100_000, 100_000))
    path = tmp_path / "checkpoint_00000007.h5"
    data = _fields(5000)
    with pytest.raises(ParmpmError) as e:
        CheckpointWriter(path, 5000, {k: v[:0] for k, v in data.items()}, _attrs(5000))
    # every field, the optional ones too (plastic: 8 doubles a row, 0.3 MB of the 2.2)
    assert str(e.value) == f"disk full writing '{path}': 2.2 MB needed, 0.1 MB free"
    assert list(tmp_path.iterdir()) == []


def test_disk_filling_while_writing_removes_the_tmp(tmp_path, monkeypatch):
    """Free space checked before each block: a disk that fills while the blocks come in stops
    the writer before HDF5 writes into it; the temporary file is removed."""
    free = [10**9]
    monkeypatch.setattr(shutil, "disk_usage", lambda p: Usage(10**9, 0, free[0]))
    path = tmp_path / "checkpoint_00000007.h5"
    data = _fields(3000)
    w = CheckpointWriter(path, 3000, {k: v[:0] for k, v in data.items()}, _attrs(3000),
                         block_rows=512)
    w.write(0, {k: v[:1024] for k, v in data.items()})
    free[0] = 50_000
    # 1024 rows of every field (the plastic rows too: 64 B each)
    with pytest.raises(ParmpmError, match=f"^disk full writing '{path}': 1.0 MB needed, 0.1 MB free$"):
        w.write(1024, {k: v[1024:2048] for k, v in data.items()})
    w.abort()  # what the driver does after any failure: harmless now
    assert list(tmp_path.iterdir()) == []


def _can_mount():
    return shutil.which("mount") is not None and hasattr(os, "geteuid") and os.geteuid() == 0


@pytest.fixture
def tiny_fs(tmp_path):
    """Mount a tmpfs (``mount(size, ro=False)``) under tmp_path; skip where not permitted."""
    mounted = []

    def mount(size="2m", ro=False):
        where = tmp_path / f"fs{len(mounted)}"
        where.mkdir()
        opts = f"size={size}" + (",ro" if ro else "")
        if not _can_mount() or subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs",
                                               str(where)], capture_output=True).returncode:
            pytest.skip("cannot mount a tmpfs here (needs root)")
        mounted.append(where)
        return where

    yield mount
    for where in mounted:
        subprocess.run(["umount", "-l", str(where)], capture_output=True)


FULL_DISK = """
import sys
from pathlib import Path
sys.path[:0] = [{tests!r}, {tests!r} + "/../harness"]  # as pytest's pythonpath
import test_checkpoint_faults as t
from parmpm.core.errors import ParmpmError
from parmpm.io.checkpoint import space
if {bypass}:  # the free-space check passes: HDF5 itself runs into the full disk
    space.free_bytes = lambda folder: 1 << 50
try:
    t._write(Path({path!r}), n=40000, block_rows=4096, step=8192)
except ParmpmError as exc:
    print(exc)
"""


@pytest.mark.parametrize("bypass", [False, True], ids=["estimate", "enospc"])
def test_full_filesystem_keeps_earlier_checkpoints(tiny_fs, bypass):
    """A real 2 MB filesystem: an earlier checkpoint fits, a 10 MB one does not. Found by the
    estimate, or (bypassed) by the write that fails with ENOSPC: one line on stdout, nothing on
    stderr, exit 0 (before: segfault, rc 139, ~130 lines of HDF5 errors, the .tmp left)."""
    fs = tiny_fs("2m")
    early = fs / "checkpoint_00000001.h5"
    data = _write(early, n=1000, block_rows=256, step=512)
    ref = _read_all(early, 256)
    path = fs / "checkpoint_00000002.h5"
    proc = subprocess.run([sys.executable, "-c", FULL_DISK.format(
        tests=str(Path(__file__).parent), bypass=bypass, path=str(path))],
        capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr[-2000:]
    lines = proc.stdout.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"disk full writing '{path}'"), proc.stdout
    if not bypass:
        assert " MB needed, " in lines[0] and lines[0].endswith(" MB free")
    assert sorted(p.name for p in fs.iterdir()) == [early.name]  # no .tmp
    assert _same(_read_all(early, 256), ref) and np.array_equal(ref["x"], data["x"])


def _read_only_folder(tmp_path, tiny_fs):
    """A folder nobody may write: a read-only mount for root, else a folder without w bit."""
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        return tiny_fs("1m", ro=True)
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o555)
    return d


def test_read_only_folder_checkpoint_is_one_line(tmp_path, tiny_fs):
    folder = _read_only_folder(tmp_path, tiny_fs)
    path = folder / "checkpoint_00000007.h5"
    with pytest.raises(ParmpmError) as e:
        _write(path)
    assert str(e.value) in (f"cannot write checkpoint '{path}': Read-only file system",
                            f"cannot write checkpoint '{path}': Permission denied")
    assert list(folder.iterdir()) == []


def test_read_only_folder_snapshots_are_one_line(tmp_path, tiny_fs):
    folder = _read_only_folder(tmp_path, tiny_fs)
    with pytest.raises(ParmpmError) as e:
        SnapshotWriter(folder, "bar", 2)
    assert str(e.value) in (f"cannot write snapshots '{folder / 'bar.h5'}': Read-only file system",
                            f"cannot write snapshots '{folder / 'bar.h5'}': Permission denied")
    assert e.value.__cause__ is None and e.value.__suppress_context__


# --- snapshots --------------------------------------------------------------------------------------
def _snapshots(folder, steps, n=2000, seed=0):
    rng = np.random.default_rng(seed)
    w = SnapshotWriter(folder, "bar", 2, flush_seconds=0)
    for k in range(steps):
        w.write(0.1 * k, rng.random((n, 2)), {"velocity": rng.random((n, 2)), "mass": rng.random(n)})
    return w


def _steps_readable(folder):
    import meshio

    with meshio.xdmf.TimeSeriesReader(folder / "bar.xdmf") as r:
        r.read_points_cells()
        for k in range(r.num_steps):
            r.read_data(k)
        return r.num_steps


def test_snapshot_disk_full_is_one_line_and_keeps_earlier_steps(tmp_path, monkeypatch):
    w = _snapshots(tmp_path, 3)
    monkeypatch.setattr(shutil, "disk_usage", lambda p: Usage(10**9, 0, 30_000))
    with pytest.raises(ParmpmError) as e:
        w.write(0.3, np.zeros((2000, 2)), {"velocity": np.zeros((2000, 2)), "mass": np.zeros(2000)})
    assert str(e.value) == f"disk full writing '{tmp_path / 'bar.h5'}': 0.2 MB needed, 0.0 MB free"
    assert e.value.__cause__ is None
    w.close()  # what the run loop does in its finally: nothing more, no error
    assert _steps_readable(tmp_path) == 3


SNAP_FULL = """
import sys
from pathlib import Path
sys.path[:0] = [{tests!r}, {tests!r} + "/../harness"]  # as pytest's pythonpath
import test_checkpoint_faults as t
from parmpm.core.errors import ParmpmError
from parmpm.io import SnapshotWriter
SnapshotWriter._free = lambda self: None  # no check: the writes run into the full disk
try:
    t._snapshots(Path({folder!r}), 100)
except ParmpmError as exc:
    print(exc)
"""


def test_snapshots_on_a_real_full_filesystem(tiny_fs):
    """ENOSPC in the middle of a snapshot: one line, no crash, no HDF5 noise, and the series
    still reads with every snapshot before (before: chained tracebacks, then a segfault)."""
    fs = tiny_fs("2m")
    proc = subprocess.run([sys.executable, "-c", SNAP_FULL.format(
        tests=str(Path(__file__).parent), folder=str(fs))],
        capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr[-2000:]
    assert proc.stdout.splitlines() == [f"disk full writing '{fs / 'bar.h5'}' (No space left on device)"]
    assert _steps_readable(fs) >= 5


# --- pruning and leftovers ----------------------------------------------------------------------
def test_prune_keeps_other_lineages_and_unreadable_files(tmp_path):
    for step in (1, 2, 3, 4):
        _write(tmp_path / ck.checkpoint_name(step), n=10, lineage="mine")
    for step in (5, 9):  # another run's, higher-numbered
        _write(tmp_path / ck.checkpoint_name(step), n=10, lineage="other")
    _write(tmp_path / ck.checkpoint_name(6), n=10)  # no lineage
    (tmp_path / ck.checkpoint_name(0)).write_text("not hdf5")
    gone = prune(tmp_path, 2, lineage="mine")
    assert [p.name for p in gone] == [ck.checkpoint_name(1), ck.checkpoint_name(2)]
    assert sorted(p.name for p in tmp_path.glob("checkpoint_*.h5")) == \
        [ck.checkpoint_name(s) for s in (0, 3, 4, 5, 6, 9)]
    assert prune(tmp_path, 1) == []  # one lineage-less file: kept
    assert [p.name for p in prune(tmp_path, 1, lineage="other")] == [ck.checkpoint_name(5)]


def test_remove_stale_tmp(tmp_path):
    for name in ("checkpoint_00000003.h5.tmp", "bar.xdmf.tmp", "checkpoint_00000002.h5",
                 "notes.tmp", "bar.h5"):
        (tmp_path / name).write_text("x")
    gone = remove_stale_tmp(tmp_path)
    assert sorted(p.name for p in gone) == ["bar.xdmf.tmp", "checkpoint_00000003.h5.tmp"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bar.h5", "checkpoint_00000002.h5",
                                                          "notes.tmp"]
    assert remove_stale_tmp(tmp_path / "missing") == []


def test_space_message_shows_the_difference():
    assert ck.space_message(Path("a.h5"), 1_440_000, 100_000) == \
        "disk full writing 'a.h5': 1.4 MB needed, 0.1 MB free"
    assert ck.space_message(Path("a.h5"), 240_000, 230_000) == \
        "disk full writing 'a.h5': 0.24 MB needed, 0.23 MB free"


@pytest.mark.parametrize("call", ["fsync", "replace"])
def test_io_error_at_commit_is_one_line_and_removes_the_tmp(tmp_path, monkeypatch, call):
    """EIO where the data are forced to the device or the file is renamed into place."""
    def fail(*args, **kwargs):
        raise OSError(errno.EIO, os.strerror(errno.EIO))

    path = tmp_path / "checkpoint_00000007.h5"
    monkeypatch.setattr(os, call, fail)
    with pytest.raises(ParmpmError) as e:
        _write(path)
    assert str(e.value) == f"cannot write checkpoint '{path}': Input/output error"
    assert list(tmp_path.iterdir()) == []
