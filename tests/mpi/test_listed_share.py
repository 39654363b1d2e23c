"""Mesh and particle-file bodies on several ranks (issue 43, set-up O(N/P)): rank 0 alone reads
the file, every other rank receives only its own particles' rows, and the set-up is the one-rank
set-up bit for bit — every particle field by global id, the overlap warning's line, a particle
outside the grid one error on every rank.

Each rank count is one ``mpirun`` of ``tests/mpi/listed_share_check.py`` over the same scenes
(:func:`parmpm.scene.agreement.load_shared_scene` then :func:`parmpm.driver.set_up.set_up`)."""
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mesh_harness import polar, polar_tri, square_tri, write
from mpi_launch import MPI_MARKS, mpirun

pytestmark = MPI_MARKS
ROOT = Path(__file__).resolve().parents[2]
MATERIALS = """
[materials.soft]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e5
poisson_ratio = 0.3
[materials.stiff]
model = "neo_hookean"
density = 2000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
"""


def _scenes(folder: Path) -> list[Path]:
    """A meshed annulus (split 2) after a box it overlaps; a disk of a triangle fan and quads
    (two blocks: 3 and 4 particles per element); the spinning blob's particle file (two
    materials, velocities, F); a particle file with a row outside the grid (the scene's check, on
    rank 0 alone: its line raised on every rank); the annulus with its 151st of 192 triangles
    inverted (on 3 ranks in rank 2's slice of the elements); a small square mesh in one patch of
    16 cells (ranks idle: the advice counts it at 8) and a particle file of the same particles
    (the advice counted by rank 0 alone)."""
    from parmpm.geometry.mesh import mesh_particles

    pts, tris = polar_tri(0.5, 1.5, 4, 24)
    mesh = write(folder, "ring.vtu", pts, [("triangle", tris)])
    dpts, quads, fan = polar(0.0, 1.0, 3, 16)
    disk = write(folder, "disk.vtu", dpts, [("triangle", fan), ("quad", quads)])
    flipped = tris.copy()
    flipped[150] = flipped[150][[0, 2, 1]]
    inverted = write(folder, "inverted.vtu", pts, [("triangle", flipped)])
    spts, stris = square_tri(4)
    spts = (spts - [1.0, -1.0]) * 0.25 + 0.1  # [0.1, 0.6]^2
    small = write(folder, "small.vtu", spts, [("triangle", stris)])
    sx, svol, _ = mesh_particles(spts, [("triangle", stris)])
    np.savez(folder / "small.npz", x=sx, volume=svol)
    blob = shutil.copy(ROOT / "tests" / "data" / "spinning_blob.csv", folder / "blob.csv")
    x = np.array([[0.2, 0.2], [0.4, 0.3], [5.0, 0.1]])
    np.savez(folder / "outside.npz", x=x, volume=np.full(3, 1e-3))
    grid = '[grid]\norigin = [-2.0, -2.0]\ncell_size = 0.1\ncells = [40, 40]\npatch_size = 2\n'
    bodies = {
        "mesh": '[[bodies]]\nshape = "box"\nmin = [-1.5, -0.5]\nmax = [0.0, 0.5]\n'
                'material = "soft"\n[[bodies]]\nshape = "mesh"\n'
                f'file = "{mesh}"\nsplit = 2\nmaterial = "stiff"\nvelocity = [1.0, 0.5]\n',
        "blob": f'[[bodies]]\nshape = "particles"\nfile = "{blob}"\n',
        "outside": f'[[bodies]]\nshape = "particles"\nfile = "{folder / "outside.npz"}"\n'
                   'material = "soft"\n',
        "mixed": f'[[bodies]]\nshape = "mesh"\nfile = "{disk}"\nmaterial = "soft"\n',
        "inverted": f'[[bodies]]\nshape = "mesh"\nfile = "{inverted}"\nmaterial = "soft"\n',
        "idle_mesh": f'[[bodies]]\nshape = "mesh"\nfile = "{small}"\nmaterial = "soft"\n',
        "idle_file": f'[[bodies]]\nshape = "particles"\nfile = "{folder / "small.npz"}"\n'
                     'material = "soft"\n',
    }
    patch = {"idle_mesh": 16, "idle_file": 16}
    out = []
    for name, text in bodies.items():
        path = folder / f"{name}.toml"
        here = grid.replace("patch_size = 2", f"patch_size = {patch.get(name, 2)}")
        path.write_text(f'name = "{name}"\ndim = 2\n{here}{MATERIALS}{text}[time]\nsteps = 1\n',
                        encoding="utf-8")
        out.append(path)
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("listed")
    scenes = _scenes(folder)
    out = {}
    for n in (1, 3):
        where = folder / f"np{n}"
        where.mkdir()
        proc = subprocess.run([mpirun(), "-n", str(n), sys.executable,
                               str(ROOT / "tests" / "mpi" / "listed_share_check.py"), str(where),
                               *map(str, scenes)], capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, f"{n} ranks failed:\n{proc.stderr[-3000:]}"
        out[n] = (where, json.loads((where / "report.json").read_text(encoding="utf-8")))
    return out


@pytest.mark.parametrize("name", ["mesh", "mixed", "blob"])
def test_three_ranks_set_up_the_one_rank_particles_bit_for_bit(runs, name):
    one, three = (np.load(runs[n][0] / f"{name}.npz") for n in (1, 3))
    assert one["gid"].size > 100 and sorted(one.files) == sorted(three.files)
    np.testing.assert_array_equal(one["gid"], np.arange(one["gid"].size))
    for k in one.files:
        np.testing.assert_array_equal(three[k], one[k], err_msg=f"{name}: {k}")
    ranks = runs[3][1][name]["ranks"]
    assert all(r["own"] > 0 for r in ranks) and sum(r["own"] for r in ranks) == one["gid"].size


@pytest.mark.parametrize("name", ["mesh", "blob"])
def test_only_rank_0_reads_a_body_file(runs, name):
    ranks = runs[3][1][name]["ranks"]
    assert sum(ranks[0]["reads"].values()) > 0, ranks[0]
    for r in ranks[1:]:
        assert sum(r["reads"].values()) == 0, ranks  # no mesh or particle file read there


@pytest.mark.parametrize("name", ["mesh", "mixed"])
def test_each_rank_makes_only_its_slice_of_a_mesh(runs, name):
    """On 3 ranks no rank makes a mesh body's every particle: each makes a third (to an
    element), and rank 0's scene check made none (its element checks are the set-up's)."""
    # the annulus: 192 triangles of 3 particles, split 2: 12 each; the disk: 16 of 3, 32 quads of 4
    n, most = {"mesh": (192 * 12, 12), "mixed": (16 * 3 + 32 * 4, 4)}[name]
    ranks = runs[3][1][name]["ranks"]
    made = [r["made"] for r in ranks]
    assert sum(made) == n and max(made) - min(made) <= most, made
    assert all(r["reads"]["_mesh"] == 0 for r in ranks), ranks


def test_a_bad_element_is_the_one_rank_line_on_every_rank(runs):
    """The 151st triangle inverted: one rank's scene check and three ranks' slices (rank 2's)
    say the same line."""
    one = runs[1][1]["inverted"]["ranks"][0]["problem"]
    assert one is not None and "bodies.0.file: mesh '" in one and "element 150 " in one, one
    assert "is inverted" in one, one
    assert [r["problem"] for r in runs[3][1]["inverted"]["ranks"]] == [one] * 3


def test_the_idle_ranks_advice_counts_a_mesh_made_in_slices(runs):
    """A square mesh in one patch of 16 cells leaves 2 of 3 ranks idle; the advice counts its
    particles at 8 cells per patch from every rank's slice, and says what the same particles
    read from a file (counted by rank 0 alone) say."""
    mesh, file = ([w for w in runs[3][1][k]["warnings"] if "no work" in w]
                  for k in ("idle_mesh", "idle_file"))
    assert len(mesh) == 1 and "grid.patch_size = 8" in mesh[0], mesh
    assert mesh == file


def test_the_overlap_warning_is_the_one_ranks(runs):
    one, three = (runs[n][1]["mesh"]["warnings"] for n in (1, 3))
    said = [w for w in one if "bodies.0 and bodies.1 overlap" in w]
    assert len(said) == 1, one
    assert [w for w in three if "overlap" in w] == said


def test_a_file_body_outside_the_grid_is_rank_0s_one_line_on_every_rank(runs):
    one = runs[1][1]["outside"]["ranks"][0]["problem"]
    assert one is not None and "bodies.0.file: body 0 spans [0.2, 5.0] on axis 0" in one, one
    assert [r["problem"] for r in runs[3][1]["outside"]["ranks"]] == [one] * 3


@pytest.mark.slow
def test_setup_files_study_quick(tmp_path):
    """``run_scripts/benchmarks/setup_files.py --quick``: on 2 ranks, loading the scene raises
    rank 1's memory by next to nothing (it never reads the file) and rank 0's by the file's read."""
    from study_harness import read_csv, run_quick

    out = run_quick("benchmarks/setup_files.py", tmp_path / "out", timeout=300)
    rows = read_csv(out / "setup_files.csv")
    for case in ("mesh", "particles"):
        r0, r1 = ([r for r in rows if (r["case"], r["ranks"], r["rank"]) == (case, "2", k)][0]
                  for k in ("0", "1"))
        assert float(r1["load_mb"]) < 0.25 * float(r0["load_mb"]), (r0, r1)
        assert float(r1["total_mb"]) < float(r0["total_mb"]), (r0, r1)
