"""A restart owns its inputs (issue 41): the bodies' global-id ranges and what the body files
gave come from the checkpoint (:mod:`parmpm.scene.recorded_files`), so a restart continues bit for
bit — contact, loads and probes on the right particles — with its particle file changed, moved or
deleted, and on another number of ranks. Before, the restart seeded the scene again to find the
ranges: a changed file put the loads and probes on other particles, a moved one stopped it."""
from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest
from cli_harness import parmpm_cli

from parmpm.core.errors import SceneError
from parmpm.scene import body_files, recorded_files
from parmpm.scene.body_files import keys as body_file_keys
from parmpm.scene.load import scene_from_toml

SCENE = """
name = "owned"
dim = 2
[grid]
cell_size = 0.05
cells = [24, 12]
patch_size = 4
[materials.soft]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e5
poisson_ratio = 0.3
[[bodies]]
shape = "particles"
file = "blob.csv"
material = "soft"
velocity = [2.0, 0.0]
[[bodies]]
shape = "box"
min = [0.5, 0.2]
max = [0.8, 0.4]
material = "soft"
[[loads]]
kind = "body_force"
body = 1
value = [0.0, 30.0]
[contact]
friction = 0.2
[time]
steps = 40
cfl = 0.3
[checkpoint]
every_steps = 20
[output]
snapshots = false
figure = false
[output.history]
every_steps = 1
probes = [{name = "box", body = 1, fields = ["v.x", "v.y"], stats = ["mean"]}]
"""


def blob(path, n_ring: int = 12, rings: int = 4, centre=(0.3, 0.3), radius=0.1):
    """A disk of particles in rings (x, y, volume), written as a particle CSV."""
    rows = []
    dr = radius / rings
    for j in range(rings):
        r = (j + 0.5) * dr
        m = max(1, round(2 * np.pi * r / dr))
        for k in range(m):
            a = 2 * np.pi * (k + 0.5) / m
            rows.append((centre[0] + r * np.cos(a), centre[1] + r * np.sin(a),
                         np.pi * ((r + dr / 2) ** 2 - (r - dr / 2) ** 2) / m))
    with open(path, "w") as f:
        f.write("x,y,volume\n")
        for x, y, v in rows:
            f.write(f"{float(x)!r},{float(y)!r},{float(v)!r}\n")
    return len(rows)


def _particles(path):
    with h5py.File(path, "r") as f:
        o = np.argsort(f["particles/gid"][:])
        return {k: f["particles"][k][:][o] for k in f["particles"]}


def _history(folder, from_step: int):
    text = (folder / "history.csv").read_text().splitlines()
    head = text[0].split(",")
    rows = [r.split(",") for r in text[1:]]
    i = head.index("step")
    return head, [r for r in rows if int(r[i]) > from_step]


@pytest.fixture(scope="module")
def straight(tmp_path_factory):
    """The scene run straight through on one rank: checkpoints at steps 20 and 40."""
    root = tmp_path_factory.mktemp("owned")
    blob(root / "blob.csv")
    (root / "scene.toml").write_text(SCENE)
    proc = parmpm_cli("run", "scene.toml", "-o", "straight", "--quiet", cwd=root)
    assert proc.returncode == 0, proc.stderr
    return root


def _restart_after(straight, tmp_path, how: str, ranks: int):
    """Copy the run's checkpoint of step 20 and the blob; do ``how`` to the blob; restart."""
    run = tmp_path / "run"
    shutil.copytree(straight, run, ignore=shutil.ignore_patterns("checkpoint_00000040.h5"))
    # the checkpoint records the blob's absolute path in the straight run's folder: act there
    src = straight / "blob.csv"
    kept = tmp_path / "blob.kept"
    shutil.copy(src, kept)
    try:
        if how == "changed":  # re-meshed: more, other particles
            blob(src, rings=6, radius=0.12)
        elif how == "moved":
            shutil.move(src, tmp_path / "elsewhere.csv")
        elif how == "deleted":
            src.unlink()
        proc = parmpm_cli("restart", str(run / "straight" / "checkpoint_00000020.h5"), "-o",
                          str(tmp_path / "again"), cwd=tmp_path, ranks=ranks)
    finally:
        shutil.copy(kept, src)
    return proc


@pytest.mark.parametrize("how", ["changed", "moved", "deleted"])
def test_restart_without_its_particle_file_is_bit_identical(straight, tmp_path, how, mpirun):
    """1 → 2 ranks: the same particles, the same history (the box's probe, the load's and the
    contact's columns) as the run that never stopped."""
    proc = _restart_after(straight, tmp_path, how, ranks=2)
    assert proc.returncode == 0, proc.stderr
    word = "changed" if how == "changed" else "gone"
    assert f"is {word} since the checkpoint this run continues" in proc.stderr
    a = _particles(straight / "straight" / "checkpoint_00000040.h5")
    b = _particles(tmp_path / "again" / "checkpoint_00000040.h5")
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    head_a, rows_a = _history(straight / "straight", 20)
    head_b, rows_b = _history(tmp_path / "again", 20)
    assert head_a == head_b and len(rows_a) == 20
    keep = [i for i, h in enumerate(head_a) if h not in ("wall_time",)]
    assert [[r[i] for i in keep] for r in rows_a] == [[r[i] for i in keep] for r in rows_b]


def test_unchanged_file_restart_reads_nothing_new(straight, tmp_path):
    """One rank, the file as it was: the same, and no word about the file."""
    proc = _restart_after(straight, tmp_path, "none", ranks=1)
    assert proc.returncode == 0, proc.stderr
    assert "since the checkpoint" not in proc.stderr
    a = _particles(straight / "straight" / "checkpoint_00000040.h5")
    b = _particles(tmp_path / "again" / "checkpoint_00000040.h5")
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_scene_records_the_file_and_a_new_run_says_it_changed(straight, tmp_path):
    """The resolved scene holds the file's size and SHA-256; a new run of that scene after the
    file changed says so in one line and reads the file as it is now."""
    import hashlib

    text = (straight / "straight" / "scene.toml").read_text()
    data = (straight / "blob.csv").read_bytes()
    assert f'file_sha256 = "{hashlib.sha256(data).hexdigest()}"' in text
    assert f"file_size = {len(data)}" in text
    csv = tmp_path / "blob.csv"
    n = blob(csv, rings=5)
    recorded = text.replace(str(straight / "blob.csv"), str(csv))
    with pytest.raises(SceneError, match="file_sha256: expected 64 lower-case hex"):
        scene_from_toml(recorded.replace('file_sha256 = "', 'file_sha256 = "x'))
    (tmp_path / "again.toml").write_text(recorded)
    proc = parmpm_cli("run", "again.toml", "-o", "again", "--set", "time.steps=1", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if "changed since this scene was recorded" in ln]
    assert len(lines) == 1 and "bodies.0.file" in lines[0], proc.stderr
    assert _count(tmp_path / "again") - n == _count(straight / "straight") - blob(tmp_path / "x.csv")


def _count(folder) -> int:
    import json

    return int(json.loads((folder / "summary.json").read_text())["particles"])


def test_detached_body_answers_from_the_record_and_refuses_its_contents(tmp_path):
    """A body whose file is gone: bounds and count as recorded; its points or inside: one line."""
    csv = tmp_path / "gone.csv"
    n = blob(csv)
    sha = recorded_files.digest(str(csv))[1]
    csv.unlink()
    records = [{"ids": [0, n], "file": str(csv), "file_sha256": sha, "shape": "particles",
                "groups": None, "split": None, "step": None, "lo": [0.2, 0.2], "hi": [0.4, 0.4]},
               {"ids": [n, n + 7]}]
    assert recorded_files.remember(records) == [(0, n), (n, n + 7)]
    body = body_file_keys._view("particles", {"file": str(csv), "file_sha256": sha})
    assert recorded_files.detached(body)
    assert body_files.bounds(body, 2) == ([0.2, 0.2], [0.4, 0.4])
    assert body_files.count(body, 2) == n
    with pytest.raises(SceneError, match="is gone or changed since the checkpoint"):
        body_files.listed(body, 2)
    other = body_file_keys._view("particles", {"file": str(csv), "file_sha256": "0" * 64})
    assert not recorded_files.detached(other)  # no record for that content
