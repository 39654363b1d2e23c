"""Particle files (issue 30): CSV, .npz and HDF5 tables written here with the standard library,
numpy and h5py read back bit for bit; a parmpm snapshot series and checkpoint (written by
parmpm's own writer and by a short run) read back with the scene's known count and volume; every
bad input is one SceneError line naming the file, the column or dataset and the row."""
import csv

import h5py
import numpy as np
import pytest

from parmpm.core.errors import SceneError
from parmpm.io.particle_file import ParticleData, data, read_particle_file

RNG = np.random.default_rng(30)
AXES = "xyz"


def _arrays(n, dim, seed=0):
    """Known particles: positions, volumes > 0, velocities, names, F with det F > 0."""
    rng = np.random.default_rng(seed)
    F = np.eye(dim) + 0.1 * rng.standard_normal((n, dim, dim))
    assert np.all(np.linalg.det(F) > 0)
    return {"x": rng.standard_normal((n, dim)) * 3.0, "volume": rng.uniform(0.1, 2.0, n),
            "v": rng.standard_normal((n, dim)), "material": np.array(["rock", "ice"] * (n // 2)
                                                                   + ["rock"] * (n % 2)),
            "F": F}


def _write_csv(path, a, dim, delimiter=","):
    """``a`` as a CSV table with the csv module: every float as its shortest round-trip repr."""
    head = list(AXES[:dim]) + ["volume"] + [f"v{c}" for c in AXES[:dim]] + ["material"] + [
        f"F{i}{j}" for i in range(1, dim + 1) for j in range(1, dim + 1)]
    with open(path, "w", newline="") as f:
        f.write("# written by the test\n\n")
        w = csv.writer(f, delimiter=delimiter)
        w.writerow(head)
        for k in range(len(a["volume"])):
            w.writerow([repr(float(c)) for c in a["x"][k]] + [repr(float(a["volume"][k]))]
                       + [repr(float(c)) for c in a["v"][k]] + [a["material"][k]]
                       + [repr(float(c)) for c in a["F"][k].reshape(-1)])


def _same(p: ParticleData, a):
    np.testing.assert_array_equal(p.x, a["x"])
    np.testing.assert_array_equal(p.volume, a["volume"])
    np.testing.assert_array_equal(p.velocity, a["v"])
    np.testing.assert_array_equal(p.F, a["F"])
    assert p.material.tolist() == list(a["material"])
    assert p.x.dtype == p.volume.dtype == p.F.dtype == np.float64


# --- round trips ------------------------------------------------------------------------------
@pytest.mark.parametrize("dim", [1, 2, 3])
def test_csv_round_trip(tmp_path, dim):
    a = _arrays(7, dim, seed=dim)
    _write_csv(tmp_path / "p.CSV", a, dim)
    _same(read_particle_file(tmp_path / "p.CSV", dim), a)


def test_csv_whitespace_columns_any_order_case(tmp_path):
    text = ("# comment\n  VOLUME   Y  x  \n\n 0.5 2.25 -1e3\n# inner comment\n1.5 -0.0 4\n")
    (tmp_path / "w.csv").write_text(text)
    p = read_particle_file(tmp_path / "w.csv", 2)
    np.testing.assert_array_equal(p.x, [[-1000.0, 2.25], [4.0, -0.0]])
    np.testing.assert_array_equal(p.volume, [0.5, 1.5])
    assert p.velocity is None and p.material is None and p.F is None
    np.testing.assert_array_equal(p.reference_volume(), p.volume)
    with pytest.raises(ValueError):  # frozen arrays
        p.x[0, 0] = 1.0


def test_npz_round_trip_and_integer_arrays(tmp_path):
    a = _arrays(9, 3)
    np.savez(tmp_path / "p.npz", **a)
    _same(read_particle_file(tmp_path / "p.npz", 3), a)
    np.savez(tmp_path / "i.npz", x=np.array([[1, 2], [3, 4]]), volume=np.array([1, 2], np.int32))
    p = read_particle_file(tmp_path / "i.npz", 2)
    np.testing.assert_array_equal(p.x, [[1.0, 2.0], [3.0, 4.0]])
    assert p.x.dtype == np.float64 and p.volume.tolist() == [1.0, 2.0]


@pytest.mark.parametrize("strings", ["vlen", "fixed"])
def test_hdf5_root_round_trip(tmp_path, strings):
    a = _arrays(6, 2)
    with h5py.File(tmp_path / "p.hdf5", "w") as f:
        for k in ("x", "volume", "v", "F"):
            f[k] = a[k]
        if strings == "vlen":
            f.create_dataset("material", data=np.array(a["material"].tolist(), dtype=object),
                             dtype=h5py.string_dtype())
        else:
            f["material"] = np.char.encode(a["material"], "utf-8")  # fixed-length bytes
    _same(read_particle_file(tmp_path / "p.hdf5", 2), a)


def test_reference_volume_and_describe(tmp_path):
    F = np.array([[[2.0, 0.0], [0.0, 1.5]], [[1.0, 0.5], [0.0, 1.0]]])  # det 3 and 1
    np.savez(tmp_path / "d.npz", x=np.array([[0.0, -1.0], [2.0, 0.5]]),
             volume=np.array([3.0, 0.25]), F=F, material=np.array(["b", "a"]))
    p = read_particle_file(tmp_path / "d.npz", 2)
    np.testing.assert_allclose(p.reference_volume(), [1.0, 0.25], rtol=1e-15)
    assert p.describe() == (f"particle file '{tmp_path / 'd.npz'}': 2 particles, total volume "
                            "3.25, bounds x [0, 2], y [-1, 0.5]; F; material a (1), b (1)")
    assert p.describe() == read_particle_file(tmp_path / "d.npz", 2).describe()


# --- a parmpm snapshot series written by parmpm's writer --------------------------------------
def _snapshot(tmp_path, dim=2, n=5, steps=(0, 40), fields=("velocity", "F", "volume", "gid")):
    """A series of ``steps`` through :class:`parmpm.io.SnapshotWriter` (no MPI), rows shuffled
    against the global ids as a gathered rank's rows can be; the arrays in gid order."""
    from parmpm.io import SnapshotWriter

    out = {}
    perm = RNG.permutation(n)
    with SnapshotWriter(tmp_path, "s", dim) as w:
        for k, step in enumerate(steps):
            a = _arrays(n, dim, seed=10 + k)
            a["volume"] = a["volume"] * np.linalg.det(a["F"])
            pd = {"velocity": a["v"][perm], "F": a["F"][perm], "volume": a["volume"][perm],
                  "gid": perm.astype(np.int64), "mass": np.ones(n)}
            w.write(0.01 * k, a["x"][perm], {f: pd[f] for f in fields + ("mass",)}, step=step)
            out[step] = a
    return tmp_path / "s.h5", out


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_snapshot_last_and_named_step(tmp_path, dim):
    path, known = _snapshot(tmp_path, dim)
    p = read_particle_file(path, dim)
    for key, ref in (("x", "x"), ("volume", "volume"), ("velocity", "v"), ("F", "F")):
        np.testing.assert_array_equal(getattr(p, key), known[40][ref])
    assert p.material is None
    assert "snapshot step 40 (t = 0.01 s; snapshot 2 of 2)" in p.source
    q = read_particle_file(tmp_path / "s.xdmf", dim, step=0)
    np.testing.assert_array_equal(q.x, known[0]["x"])
    assert "snapshot step 0" in q.source


def test_snapshot_in_parts(tmp_path):
    """A series written in parts, as by two ranks (:mod:`parmpm.io.xdmf`, "Parts"): part 0 holds
    gids 1, 3, part 1 gids 0, 2, 4; read back in gid order."""
    from parmpm.io import SnapshotWriter

    a = _arrays(5, 2, seed=3)
    rows = [np.array([1, 3]), np.array([0, 2, 4])]
    writers = [SnapshotWriter(tmp_path, "s", 2, part=k) for k in range(2)]
    with SnapshotWriter(tmp_path, "s", 2, parts=2) as index:
        records = [w.write(0.5, a["x"][g], {"volume": a["volume"][g], "gid": g}, step=12)
                   for w, g in zip(writers, rows)]
        index.add(records)
    for w in writers:
        w.close()
    assert (tmp_path / "s.parts" / "part_00001.h5").exists()
    p = read_particle_file(tmp_path / "s.xdmf", 2)
    np.testing.assert_array_equal(p.x, a["x"])
    np.testing.assert_array_equal(p.volume, a["volume"])
    assert p.velocity is None and p.F is None and "snapshot step 12" in p.source


# --- a short run of a built-in scene: its snapshots and checkpoint ----------------------------
@pytest.fixture(scope="module")
def bar_run(tmp_path_factory):
    """hanging_bar_1d for 2 steps: the bar [-1, 0] m, 0.1 m cells, 3 particles per cell,
    so 30 particles of 1/30 m (1D: volume per unit cross-section), 1 m in all; material 'bar'."""
    from parmpm.cli.main import main

    out = tmp_path_factory.mktemp("bar") / "run"
    rc = main(["run", "hanging_bar_1d", "--out", str(out), "--quiet",
               "--set", "time.end=0.002", "--set", "output.every=0.001",
               "--set", "output.figure=false", "--set", "output.history.enabled=false",
               "--set", "checkpoint.at_end=true"])
    assert rc in (0, None)
    return out


def test_run_snapshot_and_checkpoint(bar_run):
    first = read_particle_file(bar_run / "hanging_bar_1d.xdmf", 1, step=0)
    last = read_particle_file(bar_run / "hanging_bar_1d.h5", 1)
    ck = read_particle_file(bar_run / "checkpoint_00000002.h5", 1)
    spacing = 0.1 / 3
    assert first.n == last.n == ck.n == 30
    # step 0: F = I, the seeded grid of particle centres, each volume 0.1/3
    np.testing.assert_allclose(first.x[:, 0], -1.0 + spacing * (np.arange(30) + 0.5), rtol=0,
                               atol=1e-14)
    np.testing.assert_allclose(first.volume, spacing, rtol=1e-14)
    assert abs(first.volume.sum() - 1.0) < 1e-13
    # step 2: the bar has stretched (volume > 1) but V / det F is still the seeded 1 m
    assert "snapshot step 2" in last.source and last.volume.sum() > 1.0
    assert abs(last.reference_volume().sum() - 1.0) < 1e-13
    assert "checkpoint of step 2" in ck.source
    assert ck.material.tolist() == ["bar"] * 30
    np.testing.assert_array_equal(ck.x, last.x)  # the same step, both in global-id order
    np.testing.assert_array_equal(ck.velocity, last.velocity)
    np.testing.assert_array_equal(ck.F, last.F)
    np.testing.assert_allclose(ck.volume, last.volume, rtol=1e-15)
    with pytest.raises(SceneError, match=r"is the checkpoint of step 2, not of step 5"):
        read_particle_file(bar_run / "checkpoint_00000002.h5", 1, step=5)
    with pytest.raises(SceneError, match=r"is a 1D parmpm checkpoint; this scene is 2D"):
        read_particle_file(bar_run / "checkpoint_00000002.h5", 2)


# --- every bad input: one line naming the file, the column or dataset, the row ---------------
def _error(path, dim=2, **kw) -> str:
    with pytest.raises(SceneError) as e:
        read_particle_file(path, dim, **kw)
    msg = str(e.value)
    assert "\n" not in msg and f"'{path}'" in msg, msg
    return msg


def _check(msg, *parts):
    for part in parts:
        assert part in msg, (part, msg)


HEAD = "x, y, volume\n"
CSV_CASES = {  # name: (text, expected parts of the message)
    "only_comments": ("# nothing\n\n", ["is empty (no header row)"]),
    "header_only": (HEAD + "# no rows\n", ["holds no particles"]),
    "no_volume": ("x, y\n1, 2\n", ["line 1: no column 'volume'"]),
    "typo": ("x, y, volme\n1, 2, 3\n", ["unknown column 'volme'", "did you mean 'volume'?"]),
    "far_off": ("x, y, volume, colour\n1, 2, 3, 4\n", ["unknown column 'colour'", "expected one of"]),
    "z_in_2d": ("x, y, z, volume\n1, 2, 3, 4\n", ["column 'z' is for a 3D scene, this scene is 2D"]),
    "F33_in_2d": ("x, y, volume, F33\n1, 2, 3, 1\n", ["column 'F33' is for a 3D scene"]),
    "duplicate": ("x, y, X, volume\n1, 2, 3, 4\n", ["column 'X' appears twice (columns 1 and 3)"]),
    "empty_name": ("x, y, volume,\n1, 2, 3,\n", ["column 4 of the header has no name"]),
    "numbers_first": ("1, 2, 3\n4, 5, 6\n", ["must be a header", "'1'"]),
    "field_count": (HEAD + "1, 2, 3\n# c\n1, 2\n", ["line 4: 2 fields; expected 3"]),
    "not_a_number": (HEAD + "1, 2, 3\n1, abc, 3\n", ["line 3, column 'y': 'abc' is not a number"]),
    "empty_value": (HEAD + "1, , 3\n", ["line 2, column 'y': '' is not a number"]),
    "nan": (HEAD + "1, 2, 3\n4, 5, 6\nnan, 1, 1\n", ["line 4, column 'x': 'nan' is not a finite"]),
    "inf_volume": (HEAD + "1, 2, inf\n", ["line 2, column 'volume': 'inf' is not a finite"]),
    "zero_volume": (HEAD + "1, 2, 3\n1, 2, 0\n", ["line 3, column 'volume': volume 0.0 is not > 0"]),
    "negative_volume": (HEAD + "1, 2, -1e-9\n", ["line 2", "volume -1e-09 is not > 0"]),
    "partial_v": ("x, y, volume, vx\n1, 2, 3, 4\n", ["columns vx but not vy", "all 2 velocity"]),
    "partial_F": ("x, y, volume, F11, F22\n1, 2, 3, 1, 1\n", ["F11, F22 but not F12, F21",
                                                                 "all 4 F columns"]),
    "inverted_F": ("x, y, volume, F11, F12, F21, F22\n0, 0, 1, 1, 0, 0, 1\n0, 0, 1, -1, 0, 0, 1\n",
                   ["line 3, columns F11 F12 F21 F22: det F = -1.0 is not > 0"]),
    "empty_material": (HEAD.replace("\n", ", material\n") + "1, 2, 3, bar\n1, 2, 3,  \n",
                       ["line 3, column 'material': empty material name"]),
}


@pytest.mark.parametrize("case", sorted(CSV_CASES))
def test_csv_errors(tmp_path, case):
    text, parts = CSV_CASES[case]
    (tmp_path / f"{case}.csv").write_text(text)
    _check(_error(tmp_path / f"{case}.csv"), *parts)


def test_file_errors(tmp_path):
    _check(_error(tmp_path / "missing.csv"), "no such file")
    (tmp_path / "d.csv").mkdir()
    _check(_error(tmp_path / "d.csv"), "is a directory")
    (tmp_path / "e.npz").write_bytes(b"")
    _check(_error(tmp_path / "e.npz"), "is empty (0 bytes)")
    (tmp_path / "p.txt").write_text(HEAD + "1, 2, 3\n")
    _check(_error(tmp_path / "p.txt"), "unknown suffix '.txt'", ".csv, .npz, .h5")
    (tmp_path / "g.csv").write_bytes(b"x, y, volume\n\xff\xfe\x00garbage")
    _check(_error(tmp_path / "g.csv"), "is not UTF-8 text (byte 0xff at offset 13)")
    (tmp_path / "g.npz").write_bytes(RNG.bytes(300))
    _check(_error(tmp_path / "g.npz"), "is not a readable .npz archive")
    (tmp_path / "g.h5").write_bytes(RNG.bytes(300))
    _check(_error(tmp_path / "g.h5"), "is not a readable HDF5 file")
    (tmp_path / "ok.csv").write_text(HEAD + "1, 2, 3\n")
    _check(_error(tmp_path / "ok.csv", step=3), "is a CSV table (no steps)")


NPZ_CASES = {  # name: (arrays, expected parts)
    "x_2_columns_in_3d": ({"x": np.zeros((4, 2)), "volume": np.ones(4)},
                          ["array 'x' has shape (4, 2) (2 coordinates per particle); this scene is 3D"]),
    "x_flat": ({"x": np.zeros(4), "volume": np.ones(4)}, ["array 'x' has shape (4,) (1-dimensional); this scene is 3D: expected (N, 3)"]),
    "no_x": ({"volume": np.ones(4)}, ["no array 'x'"]),
    "typo": ({"x": np.zeros((4, 3)), "volum": np.ones(4)}, ["unknown array 'volum'",
                                                            "did you mean 'volume'?"]),
    "strings_for_x": ({"x": np.full((2, 3), "1.0"), "volume": np.ones(2)},
                      ["array 'x' holds strings (dtype <U3); expected numbers"]),
    "bool_volume": ({"x": np.zeros((2, 3)), "volume": np.ones(2, bool)},
                    ["array 'volume' holds dtype bool"]),
    "numbers_for_material": ({"x": np.zeros((2, 3)), "volume": np.ones(2), "material": np.ones(2)},
                             ["array 'material' holds numbers (dtype float64)"]),
    "rows_differ": ({"x": np.zeros((4, 3)), "volume": np.ones(3)},
                    ["array 'volume' has shape (3,); expected (4,) (4 particles"]),
    "F_2d_in_3d": ({"x": np.zeros((2, 3)), "volume": np.ones(2), "F": np.ones((2, 2, 2))},
                   ["array 'F' has shape (2, 2, 2); expected (2, 3, 3)"]),
    "nan_v": ({"x": np.zeros((4, 3)), "volume": np.ones(4), "v": np.where(np.arange(12).reshape(4, 3)
                                                                          == 7, np.nan, 0.0)},
              ["row 2, array 'v': value nan is not a finite number"]),
    "inf_x": ({"x": np.array([[0, 0, 0], [0, -np.inf, 0.0]]), "volume": np.ones(2)},
              ["row 1, array 'x': value -inf"]),
    "zero_rows": ({"x": np.zeros((0, 3)), "volume": np.ones(0)}, ["array 'x' holds no particles"]),
    "negative_volume": ({"x": np.zeros((3, 3)), "volume": np.array([1.0, 2.0, -3.0])},
                        ["row 2, array 'volume': volume -3.0 is not > 0"]),
    "flat_F": ({"x": np.zeros((2, 3)), "volume": np.ones(2),
                "F": np.stack([np.eye(3), np.diag([1.0, 1.0, 0.0])])},
               ["row 1, array 'F': det F = 0.0 is not > 0"]),
}


@pytest.mark.parametrize("case", sorted(NPZ_CASES))
def test_npz_errors(tmp_path, case):
    arrays, parts = NPZ_CASES[case]
    np.savez(tmp_path / f"{case}.npz", **arrays)
    _check(_error(tmp_path / f"{case}.npz", 3), *parts)


def test_npz_object_array(tmp_path):
    np.savez(tmp_path / "o.npz", x=np.zeros((2, 1)), volume=np.ones(2),
             material=np.array(["a", None], dtype=object))
    _check(_error(tmp_path / "o.npz", 1), "array 'material' is an object array")


def test_hdf5_errors(tmp_path):
    with h5py.File(tmp_path / "g.h5", "w") as f:
        f["x"], f["volume"] = np.zeros((2, 2)), np.ones(2)
        f.create_group("extra")
    _check(_error(tmp_path / "g.h5"), "'extra' at the root is a group")
    with h5py.File(tmp_path / "s.h5", "w") as f:
        f.create_dataset("x", data=np.array([["1", "2"]], dtype=object), dtype=h5py.string_dtype())
        f["volume"] = np.ones(1)
    _check(_error(tmp_path / "s.h5"), "dataset 'x' holds strings")
    with h5py.File(tmp_path / "m.h5", "w") as f:
        f["x"], f["volume"], f["material"] = np.zeros((2, 2)), np.ones(2), np.arange(2)
    _check(_error(tmp_path / "m.h5"), "dataset 'material' holds numbers (dtype int64)")
    with h5py.File(tmp_path / "n.h5", "w") as f:
        f["x"], f["volume"] = np.zeros((2, 2)), np.array([1.0, np.nan])
    _check(_error(tmp_path / "n.h5"), "row 1, dataset 'volume': value nan is not a finite")
    _check(_error(tmp_path / "n.h5", step=0), "holds one set of particles (no steps)")


def test_too_many_particles(tmp_path, monkeypatch):
    """2**31 + 1 rows of an HDF5 dataset (never written: allocated late, the file stays small)
    are refused from the shape alone; CSV and .npz through a lowered limit."""
    with h5py.File(tmp_path / "big.h5", "w") as f:
        f.create_dataset("x", shape=(2**31 + 1, 2), dtype="f8")
        f.create_dataset("volume", shape=(2**31 + 1,), dtype="f8")
    assert (tmp_path / "big.h5").stat().st_size < 1 << 20
    _check(_error(tmp_path / "big.h5"), "dataset 'x' holds 2147483649 particles; at most 2147483648")
    monkeypatch.setattr(data, "MAX_PARTICLES", 3)
    (tmp_path / "c.csv").write_text(HEAD + "1, 2, 3\n" * 4)
    _check(_error(tmp_path / "c.csv"), "the table holds 4 particles; at most 3")
    np.savez(tmp_path / "c.npz", x=np.zeros((4, 2)), volume=np.ones(4))
    _check(_error(tmp_path / "c.npz"), "array 'x' holds 4 particles; at most 3")


def test_snapshot_errors(tmp_path):
    path, _ = _snapshot(tmp_path, dim=2, steps=(0, 10, 20, 30, 40))
    _check(_error(path, 3), "is a 2D parmpm snapshot series; this scene is 3D")
    _check(_error(path, 2, step=7), "has no snapshot of step 7; its steps are 0, 10, 20 ... 40")
    other = tmp_path / "other"
    other.mkdir()
    bare, _ = _snapshot(other, dim=2, fields=("velocity",))
    _check(_error(bare, 2), "snapshot step 40 has no field 'volume'")
    with h5py.File(tmp_path / "d.h5", "w") as f:  # the format attribute, nothing else
        f.attrs["format"] = "parmpm snapshots"
    _check(_error(tmp_path / "d.h5", 2), "is a damaged parmpm snapshot series (KeyError")
    with h5py.File(tmp_path / "c.h5", "w") as f:
        f.attrs["format"] = "parmpm-checkpoint"
    _check(_error(tmp_path / "c.h5", 2), "damaged: missing scene, step")

