"""The snapshot series as its readers see it (parmpm.io.xdmf, parmpm.io.snapshot_reader):
``load_snapshots`` round trips, VTK's XDMF reader (what ParaView uses) with moving particles and
the domains as cells of the right size, meshio's public reader (what it can and cannot read),
integer ids, units, the run's history in the same file; and a 2-rank run's snapshots, written
as two parts: VTK's reader sees one series, ``load_snapshots`` a 1-rank run's arrays, meshio's
reader refuses them, and a part that fails to write is one line on every rank.
"""
import subprocess
import sys

import h5py
import numpy as np
import pytest

from parmpm.output.domains import domain_corners, domain_sizes
from parmpm.io import SnapshotWriter, load_snapshots
from parmpm.io.history_file import read_history
from parmpm.scene.load import load_scene
from parmpm.shapes import CPDI, CPGIMP, MPM, UGIMP
from parmpm.driver.simulation import Simulation

SCENES = {1: "hanging_bar_1d", 2: "hanging_bar", 3: "hanging_bar_3d"}
TINY = ("time.steps=4", "output.every_steps=2", "output.figure=false")
FIELDS = {"x", "velocity", "displacement", "stress", "F", "volume", "mass", "stretch", "damage",
          "rank", "gid", "domains"}
VTK_CELL = {1: 4, 2: 9, 3: 12}  # VTK_POLY_LINE, VTK_QUAD, VTK_HEXAHEDRON


def run_scene(folder, dim, *overrides):
    scene = load_scene(SCENES[dim], overrides=[*TINY, *(["bodies.0.ppc=2"] if dim == 3 else []),
                                               *overrides])
    sim = Simulation(scene, folder, quiet=True)
    sim.run()
    return sim


@pytest.fixture(scope="module", params=[1, 2, 3])
def run(request, tmp_path_factory):
    """A tiny run of the dim-D hanging bar: (snapshot path, the Simulation after it)."""
    dim = request.param
    folder = tmp_path_factory.mktemp(f"run{dim}")
    sim = run_scene(folder, dim)
    return folder / f"{SCENES[dim]}.xdmf", sim


def vtk_steps(path):
    """(time, {block name: vtkUnstructuredGrid}) at every time VTK's XDMF reader reports."""
    pytest.importorskip("vtkmodules.vtkIOXdmf2")
    from vtkmodules import vtkIOXdmf2
    from vtkmodules.vtkCommonDataModel import vtkCompositeDataSet
    from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline

    try:  # ParaView's default; VTK's wheel has the XDMF 2 reader only
        from vtkmodules.vtkIOXdmf3 import vtkXdmf3Reader as Reader
    except ImportError:
        Reader = vtkIOXdmf2.vtkXdmfReader
    reader = Reader()
    reader.SetFileName(str(path))
    reader.UpdateInformation()
    times = reader.GetOutputInformation(0).Get(vtkStreamingDemandDrivenPipeline.TIME_STEPS())
    for t in times:
        reader.UpdateTimeStep(t)
        out = reader.GetOutputDataObject(0)
        if not out.IsA("vtkMultiBlockDataSet"):  # one grid (no domains): no blocks
            yield t, {"particles": out}
            continue
        yield t, {out.GetMetaData(b).Get(vtkCompositeDataSet.NAME()): out.GetBlock(b)
                  for b in range(out.GetNumberOfBlocks())}


def vtk_sizes(grid) -> np.ndarray:
    """Length, area or volume of every cell, by VTK (a hexahedron's nodes out of order would
    give the wrong volume)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkFiltersVerdict import vtkCellSizeFilter

    f = vtkCellSizeFilter()
    f.SetInputData(grid)
    f.Update()
    data = f.GetOutput().GetCellData()
    return sum(vtk_to_numpy(data.GetArray(name)) for name in ("Length", "Area", "Volume"))


def particle_state(sim):
    """The run's particles in global-id order (a 1-rank run)."""
    P = sim.particles
    order = np.argsort(P.gid)
    return {k: getattr(P, k)[order] for k in ("x", "x0", "F", "r0", "lh0", "vol0", "mass")}


# --- written by a run ---------------------------------------------------------------------------
def test_fields_types_and_attributes(run):
    path, sim = run
    s = load_snapshots(path)
    dim, n = sim.dim, sim.state.n_total
    assert set(s.fields) == FIELDS and s.dim == dim
    assert len(s) == 3 and list(s.steps) == [0, 2, 4] and s.times[0] == 0.0
    last = s.at(-1)
    assert last["gid"].dtype == np.int64 and last["rank"].dtype == np.int32
    np.testing.assert_array_equal(last["gid"], np.arange(n))
    assert last["x"].shape == (n, dim) and last["F"].shape == (n, dim, dim)
    assert last["stress"].shape == (n, dim, dim) and last["volume"].shape == (n,)
    assert last["domains"].shape == (n, 2 ** dim, dim)
    p = particle_state(sim)
    np.testing.assert_array_equal(last["x"], p["x"])
    np.testing.assert_array_equal(last["F"], p["F"])
    np.testing.assert_array_equal(last["displacement"], p["x"] - p["x0"])
    np.testing.assert_array_equal(last["volume"], p["vol0"] * np.linalg.det(p["F"]))
    np.testing.assert_array_equal(last["mass"], p["mass"])
    assert not np.array_equal(s["x"][0], last["x"])  # the bar moves under gravity
    assert s.units["stress"] == "Pa" and s.units["volume"] == ["m", "m^2", "m^3"][dim - 1]
    with h5py.File(path.with_suffix(".h5")) as f:
        assert f.attrs["dim"] == dim and "velocity" in f.attrs["fields"]
        for name, ds in f["step_00000004"].items():
            assert ds.attrs["units"] != "" and ds.attrs["description"] != "", name


def test_domains_are_the_interpolation_domains(run):
    """The domains block holds one cell per particle, of the size parmpm.output.domains computes."""
    path, sim = run
    s = load_snapshots(path)
    p, disc = particle_state(sim), sim.state.disc
    sizes = domain_sizes(sim.dim, disc.method, disc.lcr, p["F"], p["r0"], p["lh0"])
    corners = domain_corners(sim.dim, disc.method, disc.lcr, p["x"], p["F"], p["r0"], p["lh0"])
    if sim.dim < 3:  # the writer's order is domain_corners' (2D: counter-clockwise)
        np.testing.assert_array_equal(s["domains"][-1], corners)
    *_, (_, blocks) = vtk_steps(path)
    grid = blocks["domains"]
    assert grid.GetNumberOfCells() == sim.state.n_total
    assert {grid.GetCellType(i) for i in range(grid.GetNumberOfCells())} == {VTK_CELL[sim.dim]}
    np.testing.assert_allclose(vtk_sizes(grid), sizes, rtol=1e-12)


def test_vtk_reader_sees_moving_particles(run):
    from vtkmodules.util.numpy_support import vtk_to_numpy

    path, sim = run
    s = load_snapshots(path)
    steps = list(vtk_steps(path))
    assert [t for t, _ in steps] == list(s.times)
    for k, (_, blocks) in enumerate(steps):
        assert set(blocks) == {"particles", "domains"}
        grid = blocks["particles"]
        points = vtk_to_numpy(grid.GetPoints().GetData())
        np.testing.assert_array_equal(points[:, :sim.dim], s["x"][k])
        gid = grid.GetPointData().GetArray("gid")
        assert gid.GetDataTypeAsString() in ("long", "long long", "idtype")
        np.testing.assert_array_equal(vtk_to_numpy(gid), np.arange(sim.state.n_total))
        damage = blocks["domains"].GetCellData().GetArray("damage")
        np.testing.assert_array_equal(vtk_to_numpy(damage), s["damage"][k])
    first = vtk_to_numpy(steps[0][1]["particles"].GetPoints().GetData())
    last = vtk_to_numpy(steps[-1][1]["particles"].GetPoints().GetData())
    assert not np.array_equal(first, last)


def test_meshio_public_reader(run):
    """meshio's TimeSeriesReader reads the particles: every snapshot's time and point data
    (positions as the point field ``x``) but only one geometry, the first snapshot's; meshio.read
    reads no time series at all. A snapshot goes to meshio through ``Snapshots.to_meshio``."""
    meshio = pytest.importorskip("meshio")
    path, sim = run
    s = load_snapshots(path)
    with meshio.xdmf.TimeSeriesReader(path) as reader:
        points, cells = reader.read_points_cells()
        np.testing.assert_array_equal(points[:, :sim.dim], s["x"][0])
        assert cells[0].type == "vertex" and len(cells[0].data) == sim.state.n_total
        assert reader.num_steps == len(s)
        for k in range(reader.num_steps):
            t, pd, _ = reader.read_data(k)
            assert t == s.times[k] and pd["gid"].dtype == np.int64
            np.testing.assert_array_equal(pd["x"][:, :sim.dim], s["x"][k])
    with pytest.raises(meshio.ReadError, match="one grid"):
        meshio.xdmf.read(path)
    with pytest.raises(SystemExit):  # meshio.read prints the ReadError, then exits
        meshio.read(path)
    mesh = s.to_meshio(-1, domains=True)
    mesh.write(path.parent / "last.vtu")
    back = meshio.read(path.parent / "last.vtu")
    assert back.cells[0].data.shape == (sim.state.n_total, 2 ** sim.dim)
    np.testing.assert_array_equal(back.cell_data["gid"][0], np.arange(sim.state.n_total))


def test_history_goes_into_the_snapshot_file(run):
    path, _ = run
    s = load_snapshots(path)
    csv = read_history(path.parent / "history.csv")
    np.testing.assert_array_equal(s.history["kinetic"], csv["kinetic"])
    assert s.history["step"].dtype == np.int64
    assert not (path.parent / "history.h5").exists()


def test_no_domains(tmp_path):
    run_scene(tmp_path, 2, "output.domains=false", "output.history=false")
    s = load_snapshots(tmp_path / "hanging_bar.xdmf")
    assert "domains" not in s and s.history is None
    assert "domains" not in (tmp_path / "hanging_bar.xdmf").read_text()
    assert list(vtk_steps(tmp_path / "hanging_bar.xdmf"))[0][1].keys() == {"particles"}


# --- the writer ---------------------------------------------------------------------------------
@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("method", [CPDI, CPGIMP, UGIMP, MPM])
def test_domain_cells_of_any_shape(tmp_path, dim, method):
    """Turned, sheared and capped domains of every interpolator: VTK's cell sizes are
    domain_sizes (in 3D only when the hexahedron's nodes are in VTK's order)."""
    rng = np.random.default_rng(dim)
    n = 6
    F = np.eye(dim) + 0.4 * rng.standard_normal((n, dim, dim))
    F[np.linalg.det(F) < 0, 0] *= -1  # det F > 0
    r0 = 0.05 * (np.eye(dim) + 0.2 * rng.standard_normal((n, dim, dim)))
    r0[np.linalg.det(r0) < 0, :, 0] *= -1
    lh0 = 0.05 * (1 + rng.random((n, dim)))
    x = rng.random((n, dim))
    lcr = 0.06
    with SnapshotWriter(tmp_path, "d", dim) as w:
        w.write(0.0, x, {"gid": np.arange(n)},
                domains=domain_corners(dim, method, lcr, x, F, r0, lh0))
    (_, blocks), = vtk_steps(tmp_path / "d.xdmf")
    np.testing.assert_allclose(vtk_sizes(blocks["domains"]),
                               domain_sizes(dim, method, lcr, F, r0, lh0), rtol=1e-12)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_load_snapshots_round_trip(tmp_path, dim):
    rng = np.random.default_rng(dim)
    n = 5
    written = []
    with SnapshotWriter(tmp_path, "p", dim, fields={"v": {"units": "m/s"}}) as w:
        for k in range(3):
            fields = {"v": rng.random((n, dim)), "F": rng.random((n, dim, dim)),
                      "m": rng.random(n), "id": np.arange(n, dtype=np.int32),
                      "ok": rng.random(n) > 0.5}
            x = rng.random((n, dim))
            corners = rng.random((n, 2 ** dim, dim))
            w.write(0.25 * k, x, fields, step=7 * k, domains=corners)
            written.append((x, fields, corners))
    s = load_snapshots(tmp_path / "p.h5")
    assert list(s.times) == [0.0, 0.25, 0.5] and list(s.steps) == [0, 7, 14]
    assert set(s.fields) == {"x", "v", "F", "m", "id", "ok", "domains"}
    assert s.units["v"] == "m/s" and s.units["m"] == ""
    for k, (x, fields, corners) in enumerate(written):
        np.testing.assert_array_equal(s["x"][k], x)
        for name, a in fields.items():
            got = s[name][k]
            assert got.shape == a.shape, name
            np.testing.assert_array_equal(got, a)
        assert s["id"][k].dtype == np.int32 and s["ok"][k].dtype == np.int8
        order = [0, 1, 3, 2, 4, 5, 7, 6] if dim == 3 else slice(None)
        np.testing.assert_array_equal(s["domains"][k], corners[:, order])
    assert len(s["v"][1:]) == 2 and np.stack(list(s["m"])).shape == (3, n)
    with pytest.raises(KeyError, match="hold"):
        s["nope"]


def test_write_table_replaces(tmp_path):
    with SnapshotWriter(tmp_path, "t", 2) as w:
        w.write(0.0, np.zeros((2, 2)))
        w.write_table("history", {"time": np.arange(3.0)}, {"time": {"units": "s"}})
        w.write_table("history", {"time": np.arange(4.0), "step": np.arange(4)}, {})
    s = load_snapshots(tmp_path / "t.xdmf")
    assert list(s.history) == ["step", "time"] and s.history["time"].size == 4
    with h5py.File(tmp_path / "t.h5") as f:
        assert "units" not in f["history/time"].attrs


def test_not_a_snapshot_file(tmp_path):
    from parmpm.core.errors import ParmpmError

    with h5py.File(tmp_path / "x.h5", "w") as f:
        f["a"] = 1
    with pytest.raises(ParmpmError, match="no parmpm snapshot file"):
        load_snapshots(tmp_path / "x.xdmf")
    with pytest.raises(ParmpmError, match="cannot read"):
        load_snapshots(tmp_path / "missing.h5")


# --- ranks: snapshots written in parts -------------------------------------------------------------
RUN_ARGS = ["-m", "parmpm", "run", "hanging_bar", "--quiet", "--set", "time.steps=6",
            "--set", "output.every_steps=3", "--set", "output.figure=false",
            "--set", "grid.patch_size=4"]


@pytest.fixture(scope="module")
def ranks_runs(tmp_path_factory, mpirun):
    """The same tiny run on 1 rank (one file) and on 2 ranks (two parts): their folders."""
    root = tmp_path_factory.mktemp("ranks")
    for n in (1, 2):
        proc = subprocess.run([mpirun, "-n", str(n), sys.executable, *RUN_ARGS, "-o",
                               str(root / f"r{n}")], capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr[-2000:]
    return root / "r1", root / "r2"


def test_two_ranks_write_two_parts(ranks_runs):
    """One rank keeps the one-file layout; two ranks write a part each (their particles in gid
    order), rank 0's file holds the steps and the history, the index spatial collections."""
    one, two = ranks_runs
    assert not (one / "hanging_bar.parts").exists()
    assert "Spatial" not in (one / "hanging_bar.xdmf").read_text()
    parts = sorted(p.name for p in (two / "hanging_bar.parts").iterdir())
    assert parts == ["part_00000.h5", "part_00001.h5"]
    with h5py.File(two / "hanging_bar.h5") as f:
        assert not any("x" in g for n, g in f.items() if n.startswith("step_"))
        rows = f["step_00000006"].attrs["rows"]
    for k, name in enumerate(parts):
        with h5py.File(two / "hanging_bar.parts" / name) as f:
            gid = f["step_00000006/gid"][()]
            assert gid.size == rows[k] > 0 and np.all(np.diff(gid) > 0)
            assert set(np.unique(f["step_00000006/rank"][()])) == {k}
    xml = (two / "hanging_bar.xdmf").read_text()
    assert xml.count('CollectionType="Spatial"') == 2 * 3  # particles and domains, 3 steps
    assert "hanging_bar.parts/part_00001.h5:/step_00000003/x" in xml


def test_two_ranks_load_what_one_rank_writes(ranks_runs):
    """load_snapshots merges the parts by gid: the arrays are a 1-rank run's, byte for byte
    (the rank aside), and the history is there."""
    one, two = (load_snapshots(r / "hanging_bar.xdmf") for r in ranks_runs)
    np.testing.assert_array_equal(one.times, two.times)
    assert one.fields == two.fields and len(one) == 3 and list(two.steps) == [0, 3, 6]
    for k in range(len(one)):
        a, b = one.at(k), two.at(k)
        for name in one.fields:
            if name != "rank":
                assert a[name].dtype == b[name].dtype and a[name].shape == b[name].shape, name
                assert a[name].tobytes() == b[name].tobytes(), name
        assert set(np.unique(b["rank"])) == {0, 1}
    mesh = two.to_meshio(-1, domains=True)  # raw corners reordered by gid as well
    np.testing.assert_array_equal(mesh.points[:, :2].reshape(-1, 4, 2), one["domains"][-1])
    np.testing.assert_array_equal(one.history["kinetic"], two.history["kinetic"])


def _merged(grids, name, cells=False):
    """One VTK array over the parts' grids, in gid order."""
    from vtkmodules.util.numpy_support import vtk_to_numpy

    data = [g.GetCellData() if cells else g.GetPointData() for g in grids]
    gid = np.concatenate([vtk_to_numpy(d.GetArray("gid")) for d in data])
    if name == "points":
        a = np.concatenate([vtk_to_numpy(g.GetPoints().GetData()) for g in grids])
    else:
        a = np.concatenate([vtk_to_numpy(d.GetArray(name)) for d in data])
    return a[np.argsort(gid, kind="stable")]


def test_vtk_reads_the_parts_as_one_series(ranks_runs):
    """VTK's XDMF reader (ParaView's): one time series; at each step each block is a spatial
    collection of the parts, N points in all that move, and N domain cells."""
    _, two = ranks_runs
    s = load_snapshots(two / "hanging_bar.xdmf")
    n = s["gid"][0].size
    steps = list(vtk_steps(two / "hanging_bar.xdmf"))
    assert [t for t, _ in steps] == list(s.times)
    for k, (_, blocks) in enumerate(steps):
        assert set(blocks) == {"particles", "domains"}
        particles = [blocks["particles"].GetBlock(b) for b in range(2)]
        domains = [blocks["domains"].GetBlock(b) for b in range(2)]
        assert blocks["particles"].GetNumberOfBlocks() == 2
        assert sum(g.GetNumberOfPoints() for g in particles) == n
        assert sum(g.GetNumberOfCells() for g in domains) == n
        assert {g.GetCellType(0) for g in domains} == {VTK_CELL[2]}
        np.testing.assert_array_equal(_merged(particles, "points")[:, :2], s["x"][k])
        np.testing.assert_array_equal(_merged(domains, "damage", cells=True), s["damage"][k])
    first, last = (_merged([b["particles"].GetBlock(j) for j in range(2)], "points")
                   for _, b in (steps[0], steps[-1]))
    assert not np.array_equal(first, last)


def test_meshio_cannot_read_parts(ranks_runs):
    """meshio's TimeSeriesReader wants a uniform grid per time step: a series in parts (spatial
    collections) is its ReadError "Couldn't find the mesh grid", a clean exception. Go through
    load_snapshots(...).to_meshio(k) instead."""
    meshio = pytest.importorskip("meshio")
    _, two = ranks_runs
    with pytest.raises(meshio.ReadError, match="Couldn't find the mesh grid"):
        meshio.xdmf.TimeSeriesReader(two / "hanging_bar.xdmf")
    mesh = load_snapshots(two / "hanging_bar.xdmf").to_meshio(0)
    assert len(mesh.points) == mesh.point_data["gid"].size


PART_FAILS = """
import sys
from mpi4py import MPI
from parmpm.core.errors import ParmpmError
from parmpm.io import xdmf
from parmpm.scene.load import load_scene
from parmpm.driver.simulation import Simulation

free = xdmf.SnapshotWriter._free
def short(self):  # part 1's disk fills after its first snapshot
    return 1000 if self.part == 1 and self.steps >= 1 else free(self)
xdmf.SnapshotWriter._free = short
scene = load_scene("hanging_bar", overrides=["time.steps=6", "output.every_steps=3",
                                             "output.figure=false"])
try:
    Simulation(scene, sys.argv[1], quiet=True, comm=MPI.COMM_WORLD).run()
except ParmpmError as exc:  # one file per rank: two ranks' stdout may interleave under mpirun
    with open(f"{sys.argv[2]}/rank{MPI.COMM_WORLD.Get_rank()}.txt", "w") as f:
        f.write(str(exc))
"""


def test_a_part_that_fails_is_one_line_on_every_rank(tmp_path, mpirun):
    """Part 1 meets a full disk at the second snapshot: both ranks raise the same one line
    naming the part, and the index lists the first snapshot only (all its parts written)."""
    script = tmp_path / "fails.py"
    script.write_text(PART_FAILS)
    out = tmp_path / "o"
    proc = subprocess.run([mpirun, "-n", "2", sys.executable, str(script), str(out),
                           str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = [(tmp_path / f"rank{r}.txt").read_text() for r in (0, 1)]
    assert lines[0] == lines[1] and "\n" not in lines[0]
    part = out / "hanging_bar.parts" / "part_00001.h5"
    assert lines[0].startswith(f"disk full writing '{part}': ")
    assert lines[0].endswith(" MB needed, 0.0 MB free")
    s = load_snapshots(out / "hanging_bar.xdmf")
    assert list(s.steps) == [0] and s["x"][0].shape[0] == s["gid"][0].size
    assert [t for t, _ in vtk_steps(out / "hanging_bar.xdmf")] == [0.0]


# --- the picture --------------------------------------------------------------------------------
@pytest.mark.slow
def test_domains_picture_quick(tmp_path):
    """run_scripts/tools/domains_picture.py --quick: its picture, drawn from the snapshots; the
    uncapped domains cover the bar (their areas sum to Σ V₀ det F), the capped ones less."""
    from study_harness import run_quick

    out = run_quick("tools/domains_picture.py", tmp_path / "out")
    assert (out / "domains.png").read_bytes()[:4] == b"\x89PNG"
    covered = []
    for case in ("lcr_2dx", "lcr_0.8dx_3"):
        last = load_snapshots(out / case / "hanging_bar.xdmf").at(-1)
        c = last["domains"]
        areas = 0.5 * np.abs(np.sum(c[..., 0] * np.roll(c[..., 1], -1, 1)
                                    - c[..., 1] * np.roll(c[..., 0], -1, 1), axis=1))
        covered.append(areas.sum() / last["volume"].sum())
    assert covered[0] == pytest.approx(1.0, rel=1e-12) and covered[1] < 0.9
