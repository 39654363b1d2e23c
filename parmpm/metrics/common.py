"""What the metrics classes share: reading the bar (body 0) from the *resolved* scene
(:func:`parmpm.scene_schema.resolve`: every key present, materials keyed by name, per-axis
values as lists of ``dim`` numbers) and the history base class :class:`History`.
"""

from __future__ import annotations

import logging
import math

import numpy as np

logger = logging.getLogger(__name__)


def bar_material(scene_data: dict, body: dict) -> dict:
    """The material table of ``body`` (bodies name their material)."""
    return scene_data["materials"][body["material"]]


def material_constants(mat: dict) -> tuple[str, float, float, float]:
    """``(model, E, nu, density)`` of a material table."""
    return (mat["model"], float(mat["youngs_modulus"]), float(mat["poisson_ratio"]),
            float(mat["density"]))


def body_box(body: dict):
    """``(min, max)`` arrays of a box body, or None for a disk or sphere (a turned box gives its
    unturned bounds)."""
    if body["shape"] != "box":
        return None
    return np.asarray(body["min"], dtype=float), np.asarray(body["max"], dtype=float)


def lattice_span(coord: np.ndarray) -> tuple[float, float]:
    """Span of a uniform particle lattice along one axis: the particles' range widened by half
    a particle spacing at each end (particles sit at the centres of their sub-cells)."""
    u = np.unique(coord)
    if u.size < 2:
        return (float(u[0]), float(u[0])) if u.size else (0.0, 0.0)
    gaps = np.diff(u)
    spacing = gaps[gaps > 1e-9 * (u[-1] - u[0])].min()
    return float(u[0] - 0.5 * spacing), float(u[-1] + 0.5 * spacing)


def bar_span(body: dict, x0: np.ndarray, axis: int) -> tuple[float, float]:
    """``(lo, hi)`` of body 0 along ``axis``: its box, else the particle lattice."""
    box = body_box(body)
    if box is not None:
        return float(box[0][axis]), float(box[1][axis])
    span = lattice_span(x0[:, axis])
    logger.info("body 0 has no box geometry; bar span %s taken from the particle lattice", span)
    return span


def bar_mask(scene_data: dict, body: dict, x0: np.ndarray) -> np.ndarray:
    """Particles of body 0: all of them in a one-body scene, else those inside body 0's box."""
    n = x0.shape[0]
    if len(scene_data["bodies"]) <= 1:
        return np.ones(n, dtype=bool)
    box = body_box(body)
    if box is None:
        logger.warning("several bodies and body 0 is not a box: metrics use all particles")
        return np.ones(n, dtype=bool)
    lo, hi = box
    tol = 1e-9 * max(float(np.max(hi - lo)), 1.0)
    return np.all((x0 >= lo - tol) & (x0 <= hi + tol), axis=1)


def gravity(scene_data: dict) -> np.ndarray:
    """The gravity vector ``gravity.g``."""
    return np.asarray(scene_data["gravity"]["g"], dtype=float)


def as_points(a, n: int, dim: int) -> np.ndarray:
    return np.asarray(a, dtype=float).reshape(n, dim)


def to_plain(value):
    """Python float/None for JSON (non-finite numbers become None)."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


class History:
    """Base of the metrics classes: checkpointing of a metric's history (the attributes named in
    ``_STATE``) and :meth:`sample`. ``needs_components`` (the run then counts connected pieces)
    is set from the kind's registry entry (:data:`parmpm.metrics.METRIC_KINDS`)."""

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
