"""What ``parmpm restart --set`` may change, applied in full, and recorded.

A restart continues the run stored in a checkpoint: its particles (positions, velocities,
deformation, masses, volumes, damage), its clock and the state of its metrics, energy watch and
output schedule all come from the file. A ``--set`` used to change the stored scene wholesale,
so that a key the particles already embody was half applied and misrecorded:
``materials.NAME.density=5000`` kept the checkpoint's masses but set Δt from the new wave speed
and ``scene.toml`` said 5000; a changed body size was recorded though the whole body ran; a
``time.end`` before the checkpoint's time ran 0 steps without a word.

The keys a restart may change are those the continued run applies in full from its first step,
without contradicting what the checkpoint holds (:data:`RESTART_KEYS`):

* ``time.*``: how long (``end``, ``steps``: both count from the run's start, and must lie past
  the checkpoint), the step (``cfl``, ``dt_max``, ``dt``) and the blow-up watch
  (``max_energy_growth``);
* ``output.*`` (a changed ``every`` / ``every_steps`` starts a new snapshot series from the
  checkpoint's time instead of the stored schedule), ``checkpoint.*``;
* ``method.*``: the interpolator, ``lcr``, update order, FLIP blend and transfer are how each
  step is computed; the particles carry every field any method needs (APIC's ``C_p`` starts at
  zero, CPDI2's corners from ``F``);
* ``decomposition.*``, ``grid.patch_size``: how the grid is dealt out over the ranks, not what
  it computes (another patch grid reads every position once);
* ``metrics.stop_on_separation`` (a stop criterion), ``name``, ``description``.

Every other key defines the problem the particles already embody: ``dim``, the grid's geometry
(``origin``, ``cell_size``, ``cells``, ``exterior``, and ``ghost``, on which the "auto"
exterior layer depends), ``materials``, ``bodies``, ``gravity``,
``damping``, ``boundary``, ``manufactured``, and the metrics whose history the checkpoint
carries (``kind``, ``every_steps``, ``axis``, ``grip``). A ``--set`` that changes one of them is
refused in one line naming the key; run the changed scene from the start instead. A ``--set``
that leaves the value as it was is no change. What changed is compared on the resolved scenes,
so a key changed through its table (``--set 'materials={…}'``) is found all the same.

:func:`check_restart` records the changes in ``Scene.restart``: ``scene.toml`` lists them in its
header, and the run folder's marker in the run it ``continues``.
"""
from __future__ import annotations

from parmpm.core.errors import SceneError
from parmpm.scene.check import show, short_text
from parmpm.driver.schedule import REL_TOL

#: the keys (or tables: every key below them) a restart may change; see the module doc
RESTART_KEYS = ("name", "description", "time", "output", "checkpoint", "method",
                "decomposition", "grid.patch_size", "metrics.stop_on_separation")

#: why a key outside :data:`RESTART_KEYS` cannot change, by its first part
_WHY = {
    "dim": "the particles have the checkpoint's dimension",
    "grid": "the particles' domains and the nodes they were built on are the checkpoint's",
    "materials": "the particles' masses and volumes were set from the checkpoint's materials",
    "bodies": "the particles are the checkpoint's, seeded from its bodies",
    "metrics": "the checkpoint carries the history of its metrics",
    "manufactured": "the particles follow the checkpoint's manufactured solution",
}


def allowed(key: str) -> bool:
    """Whether a restart may change the dotted ``key``."""
    return any(key == k or key.startswith(k + ".") for k in RESTART_KEYS)


def changes(stored, new, key: str = "") -> dict[str, list]:
    """{dotted key: [stored value, new value]} of every leaf where two resolved scenes differ
    (a list of another length, or a table against a value, is one change of its key)."""
    if isinstance(stored, dict) and isinstance(new, dict):
        out: dict[str, list] = {}
        for k in list(stored) + [k for k in new if k not in stored]:
            out.update(changes(stored.get(k), new.get(k), f"{key}.{k}" if key else str(k)))
        return out
    if isinstance(stored, list) and isinstance(new, list) and len(stored) == len(new):
        out = {}
        for i, (a, b) in enumerate(zip(stored, new)):
            out.update(changes(a, b, f"{key}.{i}"))
        return out
    same = stored == new and type(stored) is type(new)
    return {} if same else {key: [stored, new]}


def _origin(key: str, overrides) -> str:
    """The ``--set`` that changed ``key`` (the latest that names it, a table above it or a key
    below it), as the message quotes it."""
    for text in reversed([str(o) for o in overrides]):
        k = text.partition("=")[0].strip()
        if key == k or key.startswith(k + ".") or k.startswith(key + "."):
            return f"--set {short_text(text)}: "
    return ""


def check_restart(path, stored, scene, overrides, step: int, t: float) -> None:
    """Refuse, in one line, a restart of the checkpoint ``path`` (at ``step``, time ``t``) whose
    scene ``scene`` (the stored one, ``stored``, with ``overrides``) changes a key a restart
    cannot change, or has nothing left to run; else record the changes in ``scene.restart``."""
    where = f"checkpoint '{path}'"
    changed = changes(stored.data, scene.data)
    for key, (was, now) in changed.items():
        if not allowed(key):
            why = _WHY.get(key.split(".")[0], "it defines the problem the checkpoint's particles "
                                              "were run on")
            raise SceneError(
                f"{where}: {_origin(key, overrides)}a restart cannot change {key} ({show(was)} "
                f"-> {show(now)}): {why}; a restart may change "
                + ", ".join(k if "." in k or k in ("name", "description") else f"{k}.*"
                            for k in RESTART_KEYS)
                + " (run the changed scene from the start instead)")
    tm = scene.spec.time
    if tm.end is not None and t >= tm.end * (1.0 - REL_TOL):
        raise SceneError(f"{where}: {_origin('time.end', overrides)}the checkpoint is at "
                         f"t = {t!r} s (step {step}), so time.end = {tm.end!r} s leaves "
                         "nothing to run: --set time.end to a later time")
    if tm.steps is not None and step >= tm.steps:
        raise SceneError(f"{where}: {_origin('time.steps', overrides)}the checkpoint is at step "
                         f"{step}, so time.steps = {tm.steps} (counted from the run's start) "
                         f"leaves nothing to run: --set time.steps to more than {step}")
    scene.restart = {"checkpoint": str(path), "step": int(step), "time": float(t),
                     "changed": changed}
