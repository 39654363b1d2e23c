"""Output folders whose run is still going, a restart's own input, and --out values that are not
folders (issue 28, items 2, 3 and 11): faults around a run's claim of its folder.

* ``--overwrite`` of a folder whose run is still going is refused in one line naming the folder,
  host and pid (a real run, signalled by nothing: it is simply alive); once that run is killed
  (``kill -9``: no clean-up at all) its stale claim can be overwritten;
* the claim's lock (flock, held by rank 0 for the run's life) and, where a filesystem offers no
  locks, the marker's host/pid/``ended`` record decide whether a run is alive;
* ``restart CKPT --out <its own folder> --overwrite`` is refused before anything is deleted;
* ``--overwrite`` leaves nothing of the old run behind (its snapshot and checkpoint ``.parts``);
* ``--out`` on a dangling symbolic link, and an empty ``--out``, are one line each.
"""
from __future__ import annotations

import errno
import json
import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from run_waits import wait_for_steps
from test_cli import assert_one_line_error
from test_cli import parmpm as cli

from parmpm.core.errors import ParmpmError
from parmpm.io.run_folder import MARKER, claim
from parmpm.scene.load import load_scene

REPO = Path(__file__).resolve().parents[2]
QUIET = ["--quiet"]
#: a CLI run that is refused still sets up (compiles, with a cold numba cache) before it claims
CLI_S = 900
LOCK = "parmpm-run.lock"  # (parmpm.io.run_lock.LOCK: not imported, so that HEAD runs each test)
OFF = ["--set", "output.snapshots=false", "--set", "output.figure=false"]


def _tree(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (parts folders included), by relative path."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != LOCK}


def _start_long_run(out: Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.Popen([sys.executable, "-m", "parmpm", "run", "hanging_bar_1d", "-o",
                             str(out), *QUIET, "--set", "time.end=1e6", "--set",
                             "output.history.every_steps=1", "--set", "output.figure=false"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


# --- item 2: a live run's folder -------------------------------------------------------------------
def test_overwrite_of_a_live_run_is_refused_and_of_a_killed_one_allowed(tmp_path):
    """Before: --overwrite deleted the live run's open files and both runs exited 0, the folder
    mixing them. Now the second run is refused in one line naming the folder, host and pid, and
    the live run's files are untouched; after a kill -9 (a stale claim) --overwrite works."""
    out = tmp_path / "live"
    proc = _start_long_run(out)
    try:
        wait_for_steps(proc, out / "history.csv")
        for extra in (["--overwrite"], []):
            other = cli("run", "hanging_bar_1d", "-o", str(out), *QUIET, *OFF, *extra,
                        "--set", "time.steps=2", cwd=tmp_path, timeout=CLI_S)
            assert_one_line_error(other, f"output folder '{out}'", "still going",
                                  f"host {socket.gethostname()}", f"pid {proc.pid}")
            assert (out / "hanging_bar_1d.xdmf").is_file() and (out / "scene.toml").is_file()
        assert proc.poll() is None  # still running, never disturbed
        marker = json.loads((out / MARKER).read_text())
        assert marker["pid"] == proc.pid and marker["host"] == socket.gethostname()
    finally:
        proc.kill()  # SIGKILL: no handler runs, the marker is never told the run ended
        proc.communicate()
    assert "ended" not in json.loads((out / MARKER).read_text())
    again = cli("run", "hanging_bar_1d", "-o", str(out), *QUIET, *OFF, "--overwrite",
                "--set", "time.steps=2", cwd=tmp_path, timeout=CLI_S)
    assert again.returncode == 0, again.stderr
    marker = json.loads((out / MARKER).read_text())
    assert marker["pid"] != proc.pid and marker["ended"]
    assert not (out / "hanging_bar_1d.xdmf").exists()  # the killed run's files are gone


def test_a_claim_is_held_until_released_also_within_one_process(tmp_path):
    """flock belongs to the open file: a second claim from this very process sees the first."""
    folder = tmp_path / "o"
    held = claim(folder, {"files": []}, explicit=True)
    with pytest.raises(ParmpmError, match=f"still going \\(host .*, pid {os.getpid()}\\)"):
        claim(folder, {"files": []}, explicit=True, overwrite=True)
    with pytest.raises(ParmpmError, match="still going"):  # and no default folder is taken
        claim(folder, {"files": []}, explicit=True)
    assert claim(folder, {"files": []}, explicit=False).folder.name == "o_2"
    held.release()
    assert json.loads((folder / MARKER).read_text())["ended"]
    claim(folder, {"files": []}, explicit=True, overwrite=True).release()


def _no_locks(monkeypatch):
    from parmpm.io import run_lock

    def flock(fd, op):
        raise OSError(errno.ENOLCK, "No locks available")

    monkeypatch.setattr(run_lock.fcntl, "flock", flock)


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


@pytest.mark.parametrize("record, verdict", [
    ({}, "live"),                                        # this process: alive
    ({"ended": "2026-01-01T00:00:00"}, "free"),          # said it ended
    ({"pid": "dead"}, "free"),                           # crashed: no such process
    ({"pid_start": "another boot:1"}, "free"),           # the pid was reused
    ({"host": "elsewhere.example"}, "unknown"),          # another node: cannot tell
])
def test_without_locks_the_marker_record_decides(tmp_path, monkeypatch, record, verdict):
    """A filesystem without locks (NFSv3 without lockd: flock fails with ENOLCK): the marker's
    host, pid (and the pid's start) and ``ended`` say whether the run is alive."""
    from parmpm.io import run_lock

    folder = tmp_path / "o"
    claim(folder, {"files": []}, explicit=True).release()
    marker = json.loads((folder / MARKER).read_text())
    marker.pop("ended")
    marker.update(run_lock.me(), **record)
    if marker["pid"] == "dead":
        marker["pid"] = _dead_pid()
    (folder / MARKER).write_text(json.dumps(marker))
    _no_locks(monkeypatch)
    if verdict == "free":
        held = claim(folder, {"files": []}, explicit=True, overwrite=True)
        assert held.lock is None and "ended" not in json.loads((folder / MARKER).read_text())
        held.release()  # without locks, the record is what tells the next run
        assert json.loads((folder / MARKER).read_text())["ended"]
        return
    with pytest.raises(ParmpmError) as info:
        claim(folder, {"files": []}, explicit=True, overwrite=True)
    message = str(info.value)
    assert f"host {marker['host']}, pid {marker['pid']}" in message and "\n" not in message
    assert ("still going" if verdict == "live" else "offers no file locks") in message
    assert (folder / MARKER).exists()  # nothing deleted


# --- item 3: a restart's own input ----------------------------------------------------------------
def test_a_restart_into_its_own_folder_never_deletes_its_checkpoint(tmp_path):
    """Before: 'restart CKPT --out <its folder> --overwrite' deleted the checkpoint it restarts
    from (and the rest of the run). Now it is refused before anything is deleted."""
    d = tmp_path / "run"
    proc = cli("run", "hanging_bar_1d", "-o", str(d), *QUIET, *OFF, "--set", "time.steps=20",
               "--set", "checkpoint.every_steps=10", cwd=tmp_path, timeout=CLI_S)
    assert proc.returncode == 0, proc.stderr
    before = _tree(d)
    ckpt = d / "checkpoint_00000010.h5"
    for out in (d, tmp_path / "run" / ".." / "run"):
        proc = cli("restart", str(ckpt), "-o", str(out), "--overwrite", *QUIET, cwd=tmp_path, timeout=CLI_S)
        assert_one_line_error(proc, f"output folder '{out}' holds the checkpoint this restart "
                              f"continues from ('{ckpt}')", "--overwrite would delete it")
        assert _tree(d) == before
    # its default folder (beside the checkpoint) is its own, and the input stays whole
    proc = cli("restart", str(ckpt), *QUIET, "--set", "time.steps=12", cwd=tmp_path, timeout=CLI_S)
    assert proc.returncode == 0, proc.stderr
    assert _tree(d) == {**before, **{k: v for k, v in _tree(d).items()
                                     if k.startswith("restart_")}}


def test_overwrite_leaves_nothing_of_the_old_run_behind(tmp_path):
    """Before: the old run's snapshot parts (``<series>.parts``) survived an --overwrite by a run
    of another series: half a run in the new run's folder. Now every file of the old run goes,
    its parts folders too, and only files parmpm did not write stay."""
    d = tmp_path / "o"
    series = "bar_from_00000010"
    for rel in (f"{series}.xdmf", f"{series}.h5", f"{series}.parts/part_00000.h5",
                f"{series}.parts/part_00001.h5", "checkpoint_00000020.h5",
                "checkpoint_00000020.parts/part_00000.h5", "summary.json", "notes.txt",
                "mine/keep.txt"):
        (d / rel).parent.mkdir(parents=True, exist_ok=True)
        (d / rel).write_text(rel)
    (d / MARKER).write_text(json.dumps({"run_id": "old", "files": [
        f"{series}.xdmf", f"{series}.h5", "summary.json"]}))
    proc = cli("run", "hanging_bar_1d", "-o", str(d), *QUIET, *OFF, "--overwrite",
               "--set", "time.steps=2", "--set", "output.history=false", cwd=tmp_path, timeout=CLI_S)
    assert proc.returncode == 0, proc.stderr
    assert sorted(str(p.relative_to(d)) for p in d.rglob("*")) == [
        "mine", "mine/keep.txt", "notes.txt", MARKER, LOCK, "scene.toml",
        "summary.json"]


# --- item 11: --out values that are no folder --------------------------------------------------------
def test_out_on_a_dangling_link_says_so(tmp_path):
    """Before: 'cannot create output folder ...: File exists'."""
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "nowhere")
    for out in (link, link / "sub"):
        proc = cli("run", "hanging_bar_1d", "-o", str(out), *QUIET, cwd=tmp_path, timeout=CLI_S)
        assert_one_line_error(proc, f"'{link}' is a symbolic link to '{tmp_path / 'nowhere'}', "
                              "which does not exist")
        assert "File exists" not in proc.stderr
    assert not (tmp_path / "nowhere").exists()


@pytest.mark.parametrize("command", ["run", "restart"])
def test_an_empty_out_is_refused(tmp_path, command):
    """Before: ``--out ''`` was the current folder, written into without a word."""
    what = ["hanging_bar_1d"] if command == "run" else [str(tmp_path / "checkpoint_00000001.h5")]
    proc = cli(command, *what, "--out", "", *QUIET, "--set", "time.steps=1", cwd=tmp_path, timeout=CLI_S)
    assert_one_line_error(proc, "--out is empty")
    assert list(tmp_path.iterdir()) == []


def test_the_lock_file_names_its_holder(tmp_path):
    """A claim this instant (lock taken, no marker yet) is also a live run's, named from the lock
    file."""
    from parmpm.io import run_lock

    folder = tmp_path / "o"
    folder.mkdir()
    lock = run_lock.take(folder)
    try:
        busy = run_lock.take(folder)
        assert isinstance(busy, run_lock.Busy) and busy.record["pid"] == os.getpid()
        with pytest.raises(ParmpmError, match=f"still going .*pid {os.getpid()}"):
            claim(folder, {"files": []}, explicit=True)
    finally:
        lock.release()
    assert isinstance(run_lock.take(folder, create=False), run_lock.RunLock)


# --- issue 41: folders of files parmpm did not write, and files the run reads ----------------------
STEPS = ["--set", "time.steps=2"]
NOTE = "# my scene: keep this comment\n"


def _old_run(d: Path, cwd: Path) -> None:
    """A finished run with its snapshot series in ``d``: the particle file of the runs below."""
    proc = cli("run", "hanging_bar_1d", "-o", str(d), *QUIET, "--set", "output.figure=false",
               "--set", "time.steps=4", cwd=cwd, timeout=CLI_S)
    assert proc.returncode == 0, proc.stderr


def _scene_file(path: Path, name: str, particles: str | None = None) -> None:
    """A user's scene file (with a comment of theirs); its one body read from ``particles``."""
    text = load_scene("hanging_bar_1d", [f'name="{name}"']).to_toml()
    if particles is not None:
        box = text[text.index("[[bodies]]"):text.index("[method]")]
        text = text.replace(box, f'[[bodies]]\nshape = "particles"\nfile = "{particles}"\n'
                                 'material = "bar"\n\n')
    path.write_text(NOTE + text)


@pytest.mark.parametrize("scene_file", ["scene.toml", "pile.toml"])
def test_out_on_the_scene_folder_never_replaces_the_files_the_run_reads(tmp_path, scene_file):
    """Before: 'run scene.toml --out .' exited 0 having replaced the user's scene.toml with the
    resolved scene (its comments gone) and its particle file pile.h5 (the scene's name .h5) with
    the run's snapshots. Now it is refused in one line naming the file, with or without
    --overwrite, and the folder is untouched."""
    _old_run(tmp_path / "old", tmp_path)
    case = tmp_path / "case"
    case.mkdir()
    shutil.copy(tmp_path / "old" / "hanging_bar_1d.h5", case / "pile.h5")
    _scene_file(case / scene_file, "pile", "pile.h5")
    hit = ("the scene file this run reads ('scene.toml')" if scene_file == "scene.toml" else
           f"the particles file of bodies.0 ('{case.resolve() / 'pile.h5'}')")
    before = _tree(case)
    for extra in ([], ["--overwrite"]):
        proc = cli("run", scene_file, "--out", ".", *QUIET, *STEPS, *extra, cwd=case, timeout=CLI_S)
        assert_one_line_error(proc, f"output folder '.' holds {hit}", "the run would replace it",
                              "choose another --out")
        assert _tree(case) == before


def test_overwrite_never_deletes_the_particle_file_the_run_reads(tmp_path):
    """Before: a body read from an old run's snapshots, run with '--out <that run> --overwrite',
    deleted its own input, ran to the end (exit 0) and left checkpoints naming the deleted file.
    Now it is refused in one line naming the file (also given as the series' .xdmf, whose .h5 is
    what is read), before anything is deleted."""
    old = tmp_path / "old"
    _old_run(old, tmp_path)
    before = _tree(old)
    scene = tmp_path / "pile.toml"
    for given in ("hanging_bar_1d.h5", "hanging_bar_1d.xdmf"):
        _scene_file(scene, "pile", str(old / given))
        proc = cli("run", str(scene), "-o", str(old), "--overwrite", *QUIET, *STEPS, "--set",
                   "checkpoint.at_end=true", cwd=tmp_path, timeout=CLI_S)
        assert_one_line_error(proc, f"output folder '{old}' holds the particles file of bodies.0 "
                              f"('{old.resolve() / given}'", "--overwrite would delete it",
                              "choose another --out")
        assert _tree(old) == before


def test_overwrite_of_an_ordinary_old_run_still_works(tmp_path):
    """What --overwrite is for stays as it was: the old run's files go, the new run's come."""
    old = tmp_path / "old"
    _old_run(old, tmp_path)
    first = json.loads((old / MARKER).read_text())["run_id"]
    proc = cli("run", "hanging_bar_1d", "-o", str(old), "--overwrite", *QUIET, *OFF, *STEPS,
               cwd=tmp_path, timeout=CLI_S)
    assert proc.returncode == 0, proc.stderr
    marker = json.loads((old / MARKER).read_text())
    assert marker["run_id"] != first and "ended" in marker
    assert not (old / "hanging_bar_1d.h5").exists()  # the old series (this run writes none)
    assert json.loads((old / "summary.json").read_text())["steps"] == 2


def test_a_folder_of_files_parmpm_did_not_write_needs_overwrite(tmp_path):
    """Before: a folder without a marker counted as free, and a run wrote among the user's files
    (over any of them with one of its names) without a word. Now an --out folder holding files
    parmpm did not write is refused in one line naming them, unless --overwrite, which keeps them
    (those of the run's names replaced); the default folder moves on to the next free one."""
    d = tmp_path / "o"
    d.mkdir()
    (d / "notes.txt").write_text("mine")
    (d / "hanging_bar_1d.png").write_text("my figure")
    proc = cli("run", "hanging_bar_1d", "-o", str(d), *QUIET, *OFF, *STEPS, cwd=tmp_path,
               timeout=CLI_S)
    assert_one_line_error(proc, f"output folder '{d}' holds files parmpm did not write "
                          "('hanging_bar_1d.png', 'notes.txt')", "choose another --out",
                          "pass --overwrite", "replacing 'hanging_bar_1d.png'")
    assert sorted(p.name for p in d.iterdir()) == ["hanging_bar_1d.png", "notes.txt"]
    proc = cli("run", "hanging_bar_1d", "-o", str(d), "--overwrite", *QUIET, *OFF, *STEPS,
               cwd=tmp_path, timeout=CLI_S)
    assert proc.returncode == 0, proc.stderr
    assert (d / "notes.txt").read_text() == "mine" and (d / MARKER).is_file()
    default = tmp_path / "parmpm-out" / "hanging_bar_1d"
    default.mkdir(parents=True)
    (default / "mine.txt").write_text("mine")
    proc = cli("run", "hanging_bar_1d", *QUIET, *OFF, *STEPS, cwd=tmp_path, timeout=CLI_S)
    assert proc.returncode == 0, proc.stderr
    assert [p.name for p in default.iterdir()] == ["mine.txt"]
    assert (tmp_path / "parmpm-out" / "hanging_bar_1d_2" / "summary.json").is_file()


def test_a_link_to_the_scene_folder_and_a_parent_of_the_scene(tmp_path):
    """Before: '--out <a link to the scene's folder> --overwrite' replaced the user's scene.toml,
    and a parent folder of the inputs was written into without a word. Now the link is refused
    naming the scene file; the parent needs --overwrite, and then keeps every input whole."""
    case = tmp_path / "inputs" / "case"
    case.mkdir(parents=True)
    _scene_file(case / "scene.toml", "bar")
    link = tmp_path / "link"
    link.symlink_to(case)
    before = _tree(tmp_path / "inputs")
    proc = cli("run", str(case / "scene.toml"), "-o", str(link), "--overwrite", *QUIET, *OFF,
               *STEPS, cwd=tmp_path, timeout=CLI_S)
    assert_one_line_error(proc, f"output folder '{link}' holds the scene file this run reads "
                          f"('{case / 'scene.toml'}')", "the run would replace it")
    parent = tmp_path / "inputs"
    proc = cli("run", str(case / "scene.toml"), "-o", str(parent), *QUIET, *OFF, *STEPS,
               cwd=tmp_path, timeout=CLI_S)
    assert_one_line_error(proc, f"output folder '{parent}' holds files parmpm did not write "
                          "('case/')", "pass --overwrite")
    assert _tree(parent) == before
    proc = cli("run", str(case / "scene.toml"), "-o", str(parent), "--overwrite", *QUIET, *OFF,
               *STEPS, cwd=tmp_path, timeout=CLI_S)
    assert proc.returncode == 0, proc.stderr
    assert (case / "scene.toml").read_text().startswith(NOTE)
    assert {k: v for k, v in _tree(parent).items() if k.startswith("case")} == before
