"""``summary.json``: the machine-readable record of a run, and its short human form.

``write_summary`` converts numpy scalars and arrays, paths, tuples and sets to plain JSON
(non-finite floats become ``null``, so the file is strict JSON) and writes atomically: a temporary
file in the same folder, flushed and fsynced, then ``os.replace`` — a crash never leaves a torn
summary.
"""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

__all__ = ["to_jsonable", "write_summary", "format_summary", "run_info", "parmpm_version"]

SUMMARY_NAME = "summary.json"

# metrics kept in summary.json but left out of the short human summary
_DETAIL_METRICS = frozenset(
    {"samples", "max_components", "exact_static_tip_displacement", "com_velocity_max_abs_error",
     "wave_modulus", "length"}
)


def to_jsonable(obj):
    """Recursively convert ``obj`` to plain JSON types (dict keys become strings)."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, (set, frozenset)):
        return [to_jsonable(v) for v in sorted(obj, key=repr)]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        value = float(obj)
        return value if math.isfinite(value) else None
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    if obj is None or isinstance(obj, str):
        return obj
    if hasattr(obj, "item"):  # other numpy scalars
        return to_jsonable(obj.item())
    return str(obj)


def parmpm_version() -> str:
    """The installed parmpm's version (the package's own when it runs from a source tree)."""
    try:
        from importlib.metadata import PackageNotFoundError, version
        return version("parmpm")
    except (ImportError, PackageNotFoundError):
        from parmpm.core.version import __version__
        return f"{__version__} (not installed)"


def run_info(ranks: int) -> dict:
    """What produced a summary, so a results folder says how to make it again: the version,
    the command line as this process saw it (``sys.argv``; under ``mpirun`` the launcher's own
    arguments are not in it, hence ``ranks``) and the interpreter."""
    return {"parmpm_version": parmpm_version(),
            "command": {"argv": list(sys.argv), "ranks": int(ranks),
                        "python": sys.executable}}


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_summary(out_dir, summary: dict) -> Path:
    """Write ``<out_dir>/summary.json`` (indent 2) atomically and return its path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / SUMMARY_NAME
    text = json.dumps(to_jsonable(summary), indent=2, allow_nan=False) + "\n"
    fd, tmp = tempfile.mkstemp(prefix=".summary.", suffix=".tmp", dir=out_dir)
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp's 0600 would hide it from the group
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _get(d: dict, *keys, default=None):
    """First present, non-None value among ``keys``; a dotted key looks into nested dicts."""
    for key in keys:
        cur = d
        for part in key.split("."):
            if not isinstance(cur, dict) or part not in cur:
                cur = None
                break
            cur = cur[part]
        if cur is not None:
            return cur
    return default


def _fmt(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return f"{int(value):,}"
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.4g}"
    return str(value)


def format_summary(summary: dict) -> str:
    """A 5–8 line human summary of ``summary``.

    Recognised keys (first found wins): scene name ``scene_name`` | ``scene`` (str) |
    ``scene.name``; ``dim``/``scene.dim``; method ``method`` | ``interpolator`` |
    ``scene.method.interpolator``; ``scheme`` (USL/MUSL); ``lcr`` | ``l_cr``; ``ranks``;
    ``particles`` | ``n_particles``; ``steps`` | ``n_steps``; ``time`` | ``t_end`` |
    ``simulated_time``; ``wall_time`` | ``wall_time_s`` | ``wall_s``; ``compile_seconds`` (numba
    compiling during the run, left out of the wall time and the rate); ``particle_steps_per_s``
    (else particles·steps/wall); ``decomposition`` (patches allocated of the dense box, patch size,
    ghost width; on several ranks the load imbalance and halo bytes per step); ``energy.balance``
    (the history's last energy balance: the residual, its estimate, the energy given); ``metrics``
    (a dict: its scalar entries are listed).
    """
    lines = _run_lines(summary)
    for line in (_patches_line(summary), _energy_line(summary)):
        if line is not None:
            lines.append(line)
    return "\n".join(lines + _metrics_lines(summary.get("metrics")))


def _run_lines(summary: dict) -> list[str]:
    """The four lines every summary has: the scene, the method, the size, the time taken."""
    scene = summary.get("scene")
    name = _get(summary, "scene_name", "scene.name", "name")
    if name is None and isinstance(scene, str):
        name = scene
    dim = _get(summary, "dim", "scene.dim")
    particles = _get(summary, "particles", "n_particles")
    steps = _get(summary, "steps", "n_steps", "step")
    t_sim = _get(summary, "time", "t_end", "simulated_time", "t")
    wall = _get(summary, "wall_seconds", "wall_time", "wall_time_s", "wall_s")
    rate = _get(summary, "particle_steps_per_second", "particle_steps_per_s")
    if rate is None and particles and steps and wall:
        rate = float(particles) * float(steps) / float(wall)
    compiled = summary.get("compile_seconds")
    return [
        f"scene       {_fmt(name)}" + (f" ({dim}D)" if dim is not None else ""),
        _method_line(summary),
        f"particles   {_fmt(particles)}    steps {_fmt(steps)}    simulated time {_fmt(t_sim)} s",
        f"wall time   {_fmt(wall)} s"
        # numba compiling during the run: apart from the steps (cached for the next run)
        + (f" + {float(compiled):.3g} s compiling kernels" if compiled and compiled >= 0.05 else "")
        + "    " + (f"{float(rate):,.0f}" if rate is not None else "-")
        + " particle-steps/s",
    ]


def _method_line(summary: dict) -> str:
    method = _get(summary, "method", "interpolator", "scene.method.interpolator", "scene.method.name")
    if isinstance(method, dict):
        method = method.get("interpolator") or method.get("name")
    scheme = _get(summary, "update", "scheme", "scene.method.update")
    lcr = _get(summary, "lcr", "l_cr", "scene.method.lcr", "scene.method.l_cr")
    ranks = _get(summary, "ranks", "n_ranks", "size")
    meth = f"method      {_fmt(method)}"
    if scheme is not None:
        meth += f" / {scheme}"
    if summary.get("transfer") in ("apic", "mls"):
        meth += f" / {summary['transfer']}"
    if lcr is not None:
        meth += f", l_cr = {_fmt(lcr)}"
    if ranks is not None:
        meth += f", {_fmt(ranks)} rank(s)"
    return meth


def _patches_line(summary: dict) -> str | None:
    """The decomposition: patches allocated, their size; on several ranks the balance."""
    dec = summary.get("decomposition")
    if not (isinstance(dec, dict) and dec.get("patches") is not None):
        return None
    line = (f"patches     {_fmt(dec['patches'])} of {_fmt(dec.get('patches_dense'))} allocated"
            f" ({'x'.join(map(str, dec.get('patch_size', [])))} cells, ghost {_fmt(dec.get('ghost'))})")
    if (dec.get("ranks") or 1) > 1:
        line += (f", imbalance {100 * float(dec.get('imbalance', 0.0)):.1f} %,"
                 f" halo {float(dec.get('halo_bytes_per_step', 0)) / 1024:.1f} KiB/step")
    return line


def _energy_line(summary: dict) -> str | None:
    """The history's last energy balance: the residual, its estimate, the energy given."""
    balance = (summary.get("energy") or {}).get("balance") if isinstance(summary.get("energy"), dict) else None
    if not (isinstance(balance, dict) and balance.get("energy_residual") is not None):
        return None
    scale = float(balance.get("scale") or 0.0)
    line = (f"energy      balance residual {float(balance['energy_residual']):.4g} J"
            f" (estimate {float(balance.get('residual_estimate', float('nan'))):.4g} J)")
    if scale > 0:
        line += (f", {100 * abs(float(balance['energy_residual'])) / scale:.2g} % of the"
                 f" {scale:.4g} J given")
    return line


def _metrics_lines(metrics) -> list[str]:
    """The metrics' scalar entries (not the details kept for the file), three a line, six at
    most."""
    if not (isinstance(metrics, dict) and metrics):
        return []
    items = [
        f"{k} = {_fmt(v)}"
        for k, v in metrics.items()
        if k not in _DETAIL_METRICS
        and v is not None
        and isinstance(v, (bool, int, float, str, np.generic))
    ]
    return [("metrics     " if i == 0 else "            ") + ", ".join(items[i : i + 3])
            for i in range(0, min(len(items), 6), 3)]
