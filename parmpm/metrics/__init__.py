"""Scene metrics computed from particle arrays: numerical separation and error norms.

* :func:`count_components` — numerical fracture detection: particles are connected when they
  share a grid node with nonzero weight (they exchange momentum through it); the number of
  connected components of that graph is the number of separated pieces (Sadeghirad, Brannon &
  Burghardt 2011 describe separation as particles no longer sharing any node).
* one registered class per metrics kind (``metrics.kind`` in the scene), each in its own module:
  :mod:`.bars` (hanging and vibrating bar), :mod:`.tension` (a bar pulled apart between grips:
  where and when it breaks, against the damage model's prediction), :mod:`.manufactured` (the manufactured solution's
  error norm), :mod:`.rotation` (a spinning body: domain size, stress, energy) — per-scene
  histories and the numbers the run's ``summary.json`` reports, against :mod:`parmpm.exact`.

A metrics object is built once with the reference positions ``x0`` and masses, then sampled by the
run loop every ``metrics.every_steps`` steps. Under MPI each rank computes
``terms(gid, x, v, F, t=, particles=, method=, lcr=)`` for its own particles (per-particle addends
and local maxima; the keyword context serves metrics that need time or particle domains); the run driver sums the addends patch by
patch and the patches in id order (the same rounding on any number of ranks), takes the maxima
over ranks, and passes the totals to :meth:`record`. :meth:`sample` does both for arrays of all
particles in global-id order (the same order as ``x0``).
"""

from __future__ import annotations

import logging
import math

import numpy as np

from parmpm.errors import SceneError
from parmpm.connectivity import compact_nodes, local_components
from parmpm.jit import kernel

logger = logging.getLogger(__name__)

__all__ = [
    "patch_sums",
    "count_components",
    "HangingBarMetrics",
    "VibratingBarMetrics",
    "ManufacturedMetrics",
    "RotationMetrics",
    "TensionBarMetrics",
    "METRICS",
    "register_metrics",
    "make_metrics",
]


# --------------------------------------------------------------------------------------------
# Numerical separation: connected components of the particle–node graph
# --------------------------------------------------------------------------------------------
@kernel
def patch_sums(start, values):
    """(patches, k) sums of ``values`` rows over each patch's particles, strictly in order."""
    out = np.zeros((start.size - 1, values.shape[1]))
    for p in range(start.size - 1):
        for i in range(start[p], start[p + 1]):
            for c in range(values.shape[1]):
                out[p, c] += values[i, c]
    return out


def count_components(particle_nodes, particle_nnodes, n_nodes) -> int:
    """Number of connected pieces of material (1 = intact, > 1 = numerically separated).

    ``particle_nodes`` is an int array (N, K) of global flat node ids each particle touches with
    nonzero weight, of which the first ``particle_nnodes[p]`` are valid; ``n_nodes`` bounds the
    ids. When ``n_nodes`` is much larger than the number of entries (a big 3D grid), the ids are
    first compressed with ``np.unique`` so memory follows the particles, not the grid.
    """
    particle_nodes = np.ascontiguousarray(particle_nodes, dtype=np.int64)
    particle_nnodes = np.ascontiguousarray(particle_nnodes, dtype=np.int64)
    if particle_nodes.ndim != 2 or particle_nnodes.shape != (particle_nodes.shape[0],):
        raise ValueError("particle_nodes must be (N, K) and particle_nnodes (N,)")
    n = particle_nodes.shape[0]
    if n == 0:
        return 0
    if np.any(particle_nnodes > particle_nodes.shape[1]) or np.any(particle_nnodes < 0):
        raise ValueError("particle_nnodes out of range [0, K]")
    n_nodes = int(n_nodes)
    if n_nodes > 4 * particle_nodes.size + 1024:
        particle_nodes, n_nodes = compact_nodes(particle_nodes, particle_nnodes)
    return int(local_components(particle_nodes, particle_nnodes, max(n_nodes, 1))[0])


# --------------------------------------------------------------------------------------------
# Reading the resolved scene
# --------------------------------------------------------------------------------------------
_AXES = {"x": 0, "y": 1, "z": 2}


def _axis_index(axis, dim: int, default: int) -> int:
    """Axis as an index: an int, or ``"x"``, ``"y"``, ``"z"``; ``None`` gives ``default``."""
    if axis is None:
        return default
    if isinstance(axis, str):
        if axis.lower() not in _AXES:
            raise SceneError(f"unknown axis {axis!r} (use x, y, z or 0, 1, 2)")
        axis = _AXES[axis.lower()]
    axis = int(axis)
    if not 0 <= axis < dim:
        raise SceneError(f"axis {axis} out of range for a {dim}D scene")
    return axis


def _first(d: dict, keys, default=None):
    for k in keys:
        if k in d and d[k] is not None:
            return d[k]
    return default


def _bar_body(scene_data: dict) -> dict:
    bodies = scene_data.get("bodies") or []
    if not bodies:
        raise SceneError("metrics need at least one body (body 0 is the bar)")
    return bodies[0]


def _bar_material(scene_data: dict, body: dict) -> dict:
    """Material of ``body``: ``materials`` may be a list (body refers by index or name) or a
    dict keyed by name; a body without a reference uses the first material."""
    materials = scene_data.get("materials") or []
    ref = body.get("material", 0)
    if isinstance(materials, dict):
        if isinstance(ref, str) and ref in materials:
            return materials[ref]
        values = list(materials.values())
        if isinstance(ref, int) and 0 <= ref < len(values):
            return values[ref]
    else:
        if isinstance(ref, int) and 0 <= ref < len(materials):
            return materials[ref]
        for m in materials:
            if isinstance(m, dict) and m.get("name") == ref:
                return m
    raise SceneError(f"body 0 refers to an unknown material {ref!r}")


def _material_constants(mat: dict) -> tuple[str, float, float, float]:
    """``(model, E, nu, density)`` of a material table."""
    model = str(_first(mat, ("model", "type", "kind"), ""))
    E = _first(mat, ("E", "youngs_modulus", "young"))
    nu = _first(mat, ("nu", "poisson", "poisson_ratio"), 0.0)
    rho = _first(mat, ("density", "rho", "rho0"))
    if E is None or rho is None:
        raise SceneError("the bar's material needs E and density")
    return model, float(E), float(nu), float(rho)


def _body_box(body: dict):
    """``(lo, hi)`` arrays of a box-shaped body, or None if its geometry is not a box."""
    box = body.get("box")
    lo = hi = None
    if isinstance(box, dict):
        lo, hi = _first(box, ("lo", "min", "lower")), _first(box, ("hi", "max", "upper"))
    elif isinstance(box, (list, tuple)) and len(box) == 2:
        lo, hi = box
    if lo is None:
        lo, hi = _first(body, ("lo", "min", "lower")), _first(body, ("hi", "max", "upper"))
    if lo is None and "origin" in body and "size" in body:
        lo = np.asarray(body["origin"], dtype=float)
        hi = lo + np.asarray(body["size"], dtype=float)
    if lo is None or hi is None:
        return None
    return np.atleast_1d(np.asarray(lo, dtype=float)), np.atleast_1d(np.asarray(hi, dtype=float))


def _lattice_span(coord: np.ndarray) -> tuple[float, float]:
    """Span of a uniform particle lattice along one axis: the particles' range widened by half
    a particle spacing at each end (particles sit at the centres of their sub-cells)."""
    u = np.unique(coord)
    if u.size < 2:
        return (float(u[0]), float(u[0])) if u.size else (0.0, 0.0)
    gaps = np.diff(u)
    spacing = gaps[gaps > 1e-9 * (u[-1] - u[0])].min()
    return float(u[0] - 0.5 * spacing), float(u[-1] + 0.5 * spacing)


def _bar_span(body: dict, x0: np.ndarray, axis: int) -> tuple[float, float]:
    """``(lo, hi)`` of body 0 along ``axis``: its box, else the particle lattice."""
    box = _body_box(body)
    if box is not None and box[0].size > axis:
        return float(box[0][axis]), float(box[1][axis])
    span = _lattice_span(x0[:, axis])
    logger.info("body 0 has no box geometry; bar span %s taken from the particle lattice", span)
    return span


def _bar_mask(scene_data: dict, body: dict, x0: np.ndarray) -> np.ndarray:
    """Particles of body 0: all of them in a one-body scene, else those inside body 0's box."""
    n = x0.shape[0]
    if len(scene_data.get("bodies") or []) <= 1:
        return np.ones(n, dtype=bool)
    box = _body_box(body)
    if box is None or box[0].size < x0.shape[1]:
        logger.warning("several bodies and body 0 is not a box: metrics use all particles")
        return np.ones(n, dtype=bool)
    lo, hi = box[0][: x0.shape[1]], box[1][: x0.shape[1]]
    tol = 1e-9 * max(float(np.max(hi - lo)), 1.0)
    return np.all((x0 >= lo - tol) & (x0 <= hi + tol), axis=1)


def _gravity(scene_data: dict, dim: int) -> np.ndarray:
    """Gravity vector: ``gravity = {g = [...], ramp_time}`` (the resolved scene) or a bare list."""
    g = scene_data.get("gravity")
    if isinstance(g, dict):
        g = g.get("g")
    if g is None:
        return np.zeros(dim)
    g = np.atleast_1d(np.asarray(g, dtype=float))
    out = np.zeros(dim)
    out[: min(dim, g.size)] = g[:dim]
    return out


def _as_points(a, n: int, dim: int) -> np.ndarray:
    return np.asarray(a, dtype=float).reshape(n, dim)


def _to_plain(value):
    """Python float/None for JSON (non-finite numbers become None)."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


class _History:
    """Base of the metrics classes: checkpointing of a metric's history (the attributes named in
    ``_STATE``) and :meth:`sample`. A metric that records separation sets ``needs_components``
    (the run then counts connected pieces)."""

    _STATE: tuple[str, ...] = ()
    needs_components = False

    def sample(self, t, x, v, F, components, v_time=None) -> None:
        """Record one sample from arrays of *all* particles in global-id order (for metrics
        whose :meth:`terms` need no particle context beyond x, v, F and t)."""
        n = self.x0.shape[0]
        sums, maxes = self.terms(np.arange(n), x, v, F, t=t)
        self.record(t, sums.sum(axis=0), maxes, components, v_time)

    def state(self) -> dict:
        """The history so far (JSON-ready), for checkpoints."""
        return {k: v for k, v in vars(self).items() if k in self._STATE}

    def restore(self, state: dict) -> None:
        """Continue the history saved by :meth:`state` (a restarted run)."""
        for k in self._STATE:
            if k in state:
                setattr(self, k, state[k])


# --------------------------------------------------------------------------------------------
# Metrics registry
# --------------------------------------------------------------------------------------------
METRICS: dict[str, type] = {}


def register_metrics(kind: str):
    """Class decorator: make a metrics class available to ``make_metrics`` as ``kind``."""

    def deco(cls):
        METRICS[kind] = cls
        cls.kind = kind
        return cls

    return deco


def make_metrics(scene_data: dict, x0: np.ndarray, mass: np.ndarray):
    """The metrics object for ``scene_data['metrics']['kind']``, or None for ``"none"``/absent."""
    cfg = scene_data.get("metrics") or {}
    kind = cfg.get("kind", "none")
    if kind in (None, "none", ""):
        return None
    if kind not in METRICS:
        raise SceneError(f"unknown metrics kind {kind!r} (known: none, {', '.join(sorted(METRICS))})")
    return METRICS[kind](scene_data, x0, mass)


# the registered families (import for their @register_metrics side effect)
from parmpm.metrics import bars, manufactured, rotation, tension  # noqa: E402,F401
from parmpm.metrics.bars import HangingBarMetrics, VibratingBarMetrics  # noqa: E402
from parmpm.metrics.manufactured import ManufacturedMetrics  # noqa: E402
from parmpm.metrics.rotation import RotationMetrics  # noqa: E402
from parmpm.metrics.tension import TensionBarMetrics  # noqa: E402
