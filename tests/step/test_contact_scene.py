"""Contact's scene keys, examples and restart (issue 31): every ``[contact]`` mistake is one
line; the documented examples run as written (the rings bounce apart, the block stops at μ g);
a contact run continued from a checkpoint on another rank count is bit-identical.
"""
from __future__ import annotations

import csv
import subprocess
from pathlib import Path

import numpy as np
import pytest
from cli_harness import parmpm_cli
from mpi_launch import needs_mpi
from test_checkpoint import _same
from test_contact import BASE_SCENE, G, slid, slide_scene

from parmpm import Simulation
from parmpm.core.errors import SceneError
from parmpm.scene.load import load_scene, scene_from_toml

BASE = BASE_SCENE
EXAMPLES = Path(__file__).resolve().parents[2] / "docs" / "examples"


@pytest.mark.parametrize("old, new, fragment", [
    ("friction = 0.3", "friction = -1", "contact.friction: expected a number >= 0"),
    ("friction = 0.3", "friction = nan", "contact.friction"),
    ("friction = 0.3", "friction = inf", "contact.friction"),
    ("friction = 0.3", 'friction = "glue"', "contact.friction"),
    ("friction = 0.3", "friction = [0.3]", "contact.friction"),
    ("friction = 0.3", 'normal = "sideways"', "contact.normal"),
    ("friction = 0.3", 'gap = "surface"', "contact.gap"),
    ("friction = 0.3", "gap = 1", "contact.gap"),
    ("friction = 0.3", "fields = [[0], [3]]", "contact.fields.1.0: expected a body index"),
    ("friction = 0.3", "fields = [[0], [0]]", "contact.fields.1.0: body 0 is already in"),
    ("friction = 0.3", "fields = [[0]]", "contact.fields: bodies [1] are in no field"),
    ("friction = 0.3", "fields = [[0, 1]]", "contact.fields: expected at least two fields"),
    ("friction = 0.3", "fields = [[0], []]", "contact.fields.1: expected a nonempty list"),
    ("friction = 0.3", "fields = []", "contact.fields: expected a list"),
    ("friction = 0.3", "fields = [0, 1]", "contact.fields.0: expected a nonempty list"),
    ("friction = 0.3", "fields = [[0.5], [1]]", "contact.fields.0.0"),
    ("friction = 0.3", "bodies = [[0], [1]]", "unknown key 'contact.bodies'"),
    ("friction = 0.3", 'names = ["a"]', "contact.names: expected a list of 2 names"),
    ("friction = 0.3", 'names = "a"', "contact.names: expected a list of 2 names"),
    ("friction = 0.3", 'names = ["a", "a"]', 'contact.names.1: "a" is used twice'),
    ("friction = 0.3", 'names = ["a", "b c"]', "contact.names.1: expected 1 to 40 letters"),
    ("friction = 0.3", 'names = ["a", ""]', "contact.names.1: expected 1 to 40 letters"),
    ("friction = 0.3", 'names = ["a", 2]', "contact.names.1"),
    ("friction = 0.3", 'names = ["wall0", "b"]\n[[walls]]\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]',
     'contact.names.0: "wall0" is used twice'),
])
def test_bad_contact_is_one_line(old, new, fragment):
    text = 'name = "bad"\n' + BASE.replace(old, new)
    with pytest.raises(SceneError) as err:
        scene_from_toml(text)
    message = str(err.value)
    assert fragment in message and "\n" not in message


#: the base scene with a damageable material (what crack faces need)
DAMAGED = BASE.replace('poisson_ratio = 0.3\n',
                       'poisson_ratio = 0.3\ndamage = { onset = 1.1, fracture = 1.3 }\n', 1)


@pytest.mark.parametrize("base, old, new, fragment", [
    (DAMAGED, "friction = 0.3", "cracks = 1", "contact.cracks: expected true or false"),
    (DAMAGED, "friction = 0.3", 'cracks = "yes"', "contact.cracks: expected true or false"),
    (DAMAGED, "friction = 0.3", "crack_damage = 0.5",
     "contact.crack_damage: used only with contact.cracks = true"),
    (DAMAGED, "friction = 0.3", "cracks = true\ncrack_damage = 0", "contact.crack_damage"),
    (DAMAGED, "friction = 0.3", "cracks = true\ncrack_damage = 1.5", "contact.crack_damage"),
    (DAMAGED, "friction = 0.3", "cracks = true\ncrack_damage = nan", "contact.crack_damage"),
    (DAMAGED, "friction = 0.3", 'cracks = true\ncrack_damage = "full"', "contact.crack_damage"),
    (BASE, "friction = 0.3", "cracks = true", "contact.cracks: no material has a damage model"),
    (DAMAGED.replace("fracture = 1.3", 'fracture = 1.3, softening = "exponential"'),
     "friction = 0.3", "cracks = true", "contact.crack_damage: exponential softening never"),
    (DAMAGED, "friction = 0.3", "cracks = true\nfields = [[0], [1], [0]]",
     "contact.fields.2.0: body 0 is already in"),
])
def test_bad_crack_keys_are_one_line(base, old, new, fragment):
    text = 'name = "bad"\n' + base.replace(old, new)
    with pytest.raises(SceneError) as err:
        scene_from_toml(text)
    message = str(err.value)
    assert fragment in message and "\n" not in message


def test_crack_fields_default_to_one_field_of_every_body_and_read_back():
    """With cracks one field is allowed (its far side is the second), and is the default; at
    most 8 body fields (16 velocity fields in all); the resolved scene reads back."""
    sc = scene_from_toml('name = "c"\n' + DAMAGED.replace("friction = 0.3", "cracks = true"))
    c = sc.spec.contact
    assert c.fields == ((0, 1),) and c.cracks and c.crack_damage == 1.0
    assert c.velocity_fields == 2
    again = scene_from_toml(sc.to_toml())
    assert again.spec.contact == c
    plain = scene_from_toml('name = "p"\n' + BASE)
    assert "cracks" not in plain.data["contact"]  # older scenes resolve as they did
    nine = DAMAGED.replace("friction = 0.3", "cracks = true\nfields = "
                           + str([[0], [1]] + [[0]] * 7))
    with pytest.raises(SceneError, match="contact.fields: expected a list of at most 8"):
        scene_from_toml('name = "n"\n' + nine)


def test_contact_must_be_a_table():
    text = 'name = "bad"\ncontact = 1\n' + BASE.replace("[contact]\nfriction = 0.3", "")
    with pytest.raises(SceneError, match="contact: expected a table"):
        scene_from_toml(text)


def test_one_body_cannot_have_contact():
    text = 'name = "one"\n' + BASE[:BASE.index("[[bodies]]", BASE.index("[[bodies]]") + 1)] \
        + "[contact]\n"
    with pytest.raises(SceneError, match="contact: expected at least two fields"):
        scene_from_toml(text)


# ------------------------------------------------------------------ the examples

def test_rings_example_bounces_apart(tmp_path):
    """docs/examples/rings_contact.toml as written: the rings (±30 m/s) meet, flatten and move
    apart (−16.0 and +16.0 m/s at 4 ms, measured), momentum at round-off; contact takes energy
    (work_contact < 0)."""
    sc = load_scene(EXAMPLES / "rings_contact.toml",
                    overrides=["output.snapshots=false", "output.figure=false"])
    Simulation(sc, tmp_path / "rings", quiet=True).run()
    with open(tmp_path / "rings" / "history.csv") as f:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
    end = rows[-1]
    assert end["left.v.x.mean"] < -10.0 and end["right.v.x.mean"] > 10.0
    assert abs(end["momentum_x"]) < 1e-12 * end["mass"] * 30.0
    assert end["work_contact"] < 0.0


def test_spheres_example_collide_and_part(tmp_path):
    """docs/examples/spheres_contact.toml as written (3D, off-centre, μ = 0.2, the spheres
    seeded in shells): their surfaces meet at 0.5461 s (centres 0.3 m apart along x and 0.06 m
    across, closing at 0.2 m/s: ``(0.3 − 0.2 t)² + 0.06² = 0.2²``); in contact from 0.555 s
    (measured; 0.460 s with lattice spheres, whose outline bulges) to 1.11 s, apart at the end,
    the first sphere turned back and pushed sideways (−0.055, −0.035, 0) m/s, momentum at
    round-off."""
    sc = load_scene(EXAMPLES / "spheres_contact.toml",
                    overrides=["output.snapshots=false", "output.figure=false",
                               "output.history.every_steps=1"])
    Simulation(sc, tmp_path / "spheres", quiet=True).run()
    with open(tmp_path / "spheres" / "history.csv") as f:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
    touching = [r["time"] for r in rows if r["contact0.force_x"] != 0.0]
    meet = (0.3 - (0.2 ** 2 - 0.06 ** 2) ** 0.5) / 0.2
    assert abs(touching[0] - meet) < 0.02 and touching[-1] < rows[-1]["time"]
    m = rows[-1]["mass"] / 2
    v = [v0 + rows[-1][f"contact0.impulse_{a}"] / m for v0, a in zip((0.1, 0.0, 0.0), "xyz")]
    assert v[0] < -0.03 and v[1] < -0.01
    assert max(abs(r[f"momentum_{a}"]) for r in rows for a in "xyz") < 1e-12 * m * 0.1


def test_block_on_block_example_stops_at_mu_g(tmp_path):
    """docs/examples/block_on_block.toml, quick (0.2 s): the upper block's speed falls at μ g
    (2 %)."""
    sc = load_scene(EXAMPLES / "block_on_block.toml",
                    overrides=["output.snapshots=false", "output.figure=false", "time.end=0.2"])
    Simulation(sc, tmp_path / "blocks", quiet=True).run()
    with open(tmp_path / "blocks" / "history.csv") as f:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
    t, v = slid(rows)
    assert -np.polyfit(t, v, 1)[0] == pytest.approx(0.3 * G, rel=0.02)


# ------------------------------------------------------------------ restart


def cli(n: int, *args: str) -> subprocess.CompletedProcess:
    """``python -m parmpm ARGS --quiet``, under ``mpirun -n n`` when n > 1."""
    return parmpm_cli(*args, "--quiet", ranks=n)


@needs_mpi
@pytest.mark.mpi
def test_contact_restart_is_bit_identical(tmp_path):
    """A contact run checkpointed at step 50 on one rank and continued on two reaches step 100
    exactly as the run straight through (a particle's field is its body's, from its global id:
    nothing else to carry; the ledger's contact impulses are in the checkpoint's state)."""
    a, b = tmp_path / "a", tmp_path / "b"
    sets = ["--set", "output.snapshots=false", "--set", "output.figure=false", "--set",
            "grid.patch_size=5", "--set", "time.steps=100", "--set", "checkpoint.every_steps=50"]
    proc = cli(1, "run", str(EXAMPLES / "block_on_block.toml"), "-o", str(a), *sets)
    assert proc.returncode == 0, proc.stderr
    proc = cli(2, "restart", str(a / "checkpoint_00000050.h5"), "-o", str(b))
    assert proc.returncode == 0, proc.stderr
    _same(a / "checkpoint_00000100.h5", b / "checkpoint_00000100.h5")
    rows = {}
    for run_dir in (a, b):
        with open(run_dir / "history.csv") as f:
            rows[run_dir] = [r for r in csv.DictReader(f)][-1]
    assert rows[a]["contact1.impulse_x"] == rows[b]["contact1.impulse_x"]


@needs_mpi
@pytest.mark.mpi
def test_crack_restart_is_bit_identical(tmp_path):
    """The broken bar checkpointed after its break on one rank and continued on three ends as
    the run straight through: the sides are found afresh each step from what a checkpoint holds
    (positions, damage), nothing else to carry."""
    a, b = tmp_path / "a", tmp_path / "b"
    sets = ["--set", "output.snapshots=false", "--set", "output.figure=false", "--set",
            "grid.patch_size=10", "--set", "time.steps=500", "--set", "checkpoint.every_steps=250"]
    proc = cli(1, "run", str(EXAMPLES / "broken_bar.toml"), "-o", str(a), *sets)
    assert proc.returncode == 0, proc.stderr
    proc = cli(3, "restart", str(a / "checkpoint_00000250.h5"), "-o", str(b))
    assert proc.returncode == 0, proc.stderr
    _same(a / "checkpoint_00000500.h5", b / "checkpoint_00000500.h5")


def test_named_fields_name_their_history_columns(tmp_path):
    """``contact.names`` renames each field's columns, nothing else: the named run's
    ``left.impulse_x`` is the unnamed run's ``contact0.impulse_x``; with cracks each field's far
    side is ``<name>_far``."""
    out = {}
    block = slide_scene(0.3).replace("end = 0.2", "end = 0.02")
    for tag, extra in (("plain", ""), ("named", '\nnames = ["left", "right"]')):
        sc = scene_from_toml(f'name = "{tag}"\n' + block + extra,
                             overrides=["output.snapshots=false", "output.figure=false"])
        Simulation(sc, tmp_path / tag, quiet=True).run()
        with open(tmp_path / tag / "history.csv") as f:
            out[tag] = list(csv.DictReader(f))
    plain, named = out["plain"][-1], out["named"][-1]
    assert "left.impulse_x" in named and "contact0.impulse_x" not in named
    assert float(plain["contact1.impulse_y"]) > 0.1  # the block presses on the table
    for a, b in (("left", "contact0"), ("right", "contact1")):
        for col in ("force_x", "impulse_x", "impulse_y"):
            assert named[f"{a}.{col}"] == plain[f"{b}.{col}"]
    cracked = scene_from_toml('name = "c"\n' + DAMAGED.replace(
        "friction = 0.3", 'cracks = true\nfields = [[0], [1]]\nnames = ["a", "b"]'))
    assert cracked.spec.contact.column_names() == ("a", "b", "a_far", "b_far")


@pytest.mark.parametrize("update", ["usl", "musl"])
def test_the_fields_g2p_finds_every_next_patch_as_the_migration_would(tmp_path, monkeypatch,
                                                                     update):
    """With contact, each field's G2P finds its particles' next patches, as one field's does:
    the migration then skips its own search. Checked at every step of the rings example
    against that search run anyway (the same patches, the same count of particles that
    changed patch), and the search is skipped at every step (it once ran for every contact
    step: 0.17 of 5.1 ms per step on two disks of 22,620 particles)."""
    import parmpm.step.migration as migration

    checked, real = [], migration.Migration.locate_and_send

    def twice(self):
        located = self.located
        assert located is not None  # G2P found them
        before = self.new_patch.copy()
        D, lay = self.disc, self.disc.layout
        checked.append(migration.locate_patches(D.dim, self.P.rows.x, D.origin3, D.inv_h3,
                                                lay.cells3, lay.psize3, lay.patches_per_axis,
                                                self.P.rows.patch, self.new_patch,
                                                self.P.order()))
        assert np.array_equal(before, self.new_patch)
        assert tuple(checked[-1]) == (-1, located[1])
        return real(self)

    monkeypatch.setattr(migration.Migration, "locate_and_send", twice)
    sc = load_scene(EXAMPLES / "rings_contact.toml",
                    overrides=["output.snapshots=false", "output.figure=false",
                               "output.history=false", "time.end=0.002",
                               f"method.update=\"{update}\""])
    Simulation(sc, tmp_path / "rings", quiet=True).run()
    assert len(checked) > 10 and sum(m for _, m in checked) > 0  # particles changed patch
