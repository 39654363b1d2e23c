"""Metrics of the tension bar: a bar between two grips pulled apart, and where and when it breaks.

The grips are the two box bodies of material ``metrics.grip`` (default "grip"); every other body
is the bar, its segments in series along the grips' axis ``e`` (from one grip's centre to the
other's). Grip particles are those whose reference position lies in a grip's (turned) box.

* **stretch** of the bar: ``λ = (|C_B − C_A| − h_A − h_B) / L0`` with ``C`` the grips' current
  centroids, ``h`` their half-lengths along ``e`` and ``L0`` the bar's initial length between them
  (grips far stiffer than the bar keep their length, so this is the bar's mean stretch);
* **failure**: the first sample at which a bar particle is fully damaged (``D = 1``);
* **separation**: the first sample with more than one connected piece of material
  (:func:`parmpm.output.metrics.count_components`), with the stretch then and the crack's position
  ``s = (X − mid)·e`` (reference coordinates, from the bar's centre): the mean and range over the
  fully damaged particles;
* **prediction**: :func:`parmpm.exact.tension.tension_failure` from the scene's segments — the
  stretch at which the weakest segment peaks — and the failed segment's position, to compare with.
"""
from __future__ import annotations

import dataclasses
import logging

import numpy as np

from parmpm.core.errors import SceneError
from parmpm.exact.tension import opening_allowance, tension_failure
from parmpm.output.metrics import register_metrics
from parmpm.output.metrics.common import History, as_points, to_plain
from parmpm.output.metrics.trace import first_max
from parmpm.geometry.primitives import turn

logger = logging.getLogger(__name__)

FULL = 1.0 - 1e-9  # damage counted as complete failure


def _box_frame(body, dim: int):
    """(centre, axes as rows, half-lengths) of a (possibly turned) box body (its record)."""
    lo, hi = np.asarray(body.min, float), np.asarray(body.max, float)
    axes = turn(dim, body.angle).T if body.angle else np.eye(dim)  # rows: its edges
    return 0.5 * (lo + hi), axes, 0.5 * (hi - lo)


def _project(x0: np.ndarray, origin: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """``(x0 − origin)·axesᵀ`` summed elementwise in a fixed order (not BLAS, whose rounding
    depends on where a row sits in the array): the same bits for any subset of the particles."""
    r = x0 - origin
    out = np.zeros((x0.shape[0], axes.shape[0]))
    for i in range(axes.shape[0]):
        for k in range(x0.shape[1]):
            out[:, i] += r[:, k] * axes[i, k]
    return out


def _inside(body, dim: int, x0: np.ndarray) -> np.ndarray:
    centre, axes, half = _box_frame(body, dim)
    local = _project(x0, centre, axes)
    return np.all(np.abs(local) <= half * (1 + 1e-9) + 1e-12, axis=1)


def _extent(body, dim: int, e: np.ndarray) -> float:
    """Half-length of a box body along the unit vector ``e``."""
    _, axes, half = _box_frame(body, dim)
    return float(np.sum(np.abs(axes @ e) * half))


def _section(body, dim: int, e: np.ndarray) -> float:
    """Reference cross-section of a box body across ``e``: the product of its other edges
    (per unit thickness in 2D, 1 in 1D)."""
    _, axes, half = _box_frame(body, dim)
    along = int(np.argmax(np.abs(axes @ e)))
    return float(np.prod([2.0 * half[k] for k in range(dim) if k != along]))


def _segment(body, material, dim: int, e: np.ndarray) -> dict:
    """A bar segment as :func:`parmpm.exact.tension.tension_failure` reads it: its length along
    ``e`` and its material's law and damage table."""
    damage = material.damage
    return {"length": 2.0 * _extent(body, dim, e), "model": material.model,
            "E": material.youngs_modulus, "nu": material.poisson_ratio,
            "damage": None if damage is None else dataclasses.asdict(damage)}


@register_metrics("tension_bar")
class TensionBarMetrics(History):
    """Stretch, failure and separation of a bar pulled between two grips (module doc)."""

    _TRACE = ("times", "stretch_history", "max_damage_history", "components_history",
              "stress_history")
    _STATE = ("peak_stress", "stretch_at_peak", "failure_time", "stretch_at_failure",
              "separation_time", "stretch_at_separation", "crack_position", "crack_range",
              "max_stretch", "max_damage", "max_components")

    def __init__(self, spec, x0: np.ndarray, mass: np.ndarray, comm=None, gid=None):
        self.dim = d = int(spec.dim)
        self._own(x0, mass, comm, gid)  # the grips and the bar are told from x0 when sampling
        grip = spec.metrics.grip
        bodies = spec.bodies
        grips = [b for b in bodies if b.material == grip]
        if len(grips) != 2:
            raise SceneError(f"tension_bar metrics need two bodies of material {grip!r}")
        self.grips = grips  # their boxes tell a particle's part from its x0 (_parts)
        (cA, _, _), (cB, _, _) = _box_frame(grips[0], d), _box_frame(grips[1], d)
        axis = cB - cA
        self.e = axis / np.linalg.norm(axis)
        # the bar's reference cross-section (plane strain: per unit thickness; 1D: 1)
        self.area0 = _section(next(b for b in bodies if b.material != grip), d, self.e)
        self.mid = 0.5 * (cA + cB)
        self.h = _extent(grips[0], d, self.e) + _extent(grips[1], d, self.e)
        self.L0 = float(np.linalg.norm(axis)) - self.h

        bar_bodies = [b for b in bodies if b.material != grip]
        segments = [_segment(b, spec.materials[b.material], d, self.e) for b in bar_bodies]
        self.predicted = self.allowance = self.weak_position = self.weak_halfwidth = None
        try:
            pred = tension_failure(segments, d)
        except SceneError as err:
            logger.warning("no predicted failure stretch: %s", err)
            pred = None
        if pred is not None:
            self.predicted = pred
            weak = bar_bodies[pred["weakest"]]
            self.weak_position = float((_box_frame(weak, d)[0] - self.mid) @ self.e)
            self.weak_halfwidth = _extent(weak, d, self.e)
            cell = float(min(spec.grid.cell_size))
            self.allowance = opening_allowance(segments, pred["weakest"], cell)

        self._begin()
        self.max_stretch = self.max_damage = self.max_components = None
        self.peak_stress = self.stretch_at_peak = None
        self.failure_time = self.stretch_at_failure = None
        self.separation_time = self.stretch_at_separation = None
        self.crack_position = self.crack_range = None

    def terms(self, gid, x, v, F, particles=None, **context):
        """Addends: each grip's mass and first moment; the fully damaged bar particles' count and
        Σ s. Maxima: the bar's damage, and ``±s`` of its fully damaged particles."""
        n = np.shape(gid)[0]
        d = self.dim
        x = as_points(x, n, d)
        x0, m = self.reference(gid, particles)
        grip_a, grip_b, bar, s = self._parts(x0)
        sums = np.zeros((n, 2 * d + 5))
        for k, grip in enumerate((grip_a, grip_b)):
            col = k * (d + 1)
            sums[:, col] = np.where(grip, m, 0.0)
            sums[:, col + 1:col + 1 + d] = np.where(grip[:, None], m[:, None] * x, 0.0)
        damage = (np.zeros(n) if particles is None or particles.damage.size != n
                  else particles.damage)
        failed = bar & (damage >= FULL)
        sums[:, -2] = failed
        sums[:, -1] = np.where(failed, s, 0.0)
        if particles is not None and particles.stress.shape[0] == n:  # ∫ σ_ee dV over the bar
            Fp = np.asarray(F, dtype=float).reshape(n, d, d)
            sig = np.einsum("pij,i,j->p", particles.stress.reshape(n, d, d), self.e, self.e)
            sums[:, -3] = np.where(bar, particles.vol0 * np.linalg.det(Fp) * sig, 0.0)
        maxes = np.array([damage[bar].max(initial=0.0),
                          s[failed].max(initial=-np.inf), (-s[failed]).max(initial=-np.inf)])
        return sums, maxes

    def _parts(self, x0: np.ndarray):
        """Of particles at reference positions ``x0``: in grip A, in grip B, in the bar, and
        ``s = (X − mid)·e`` (elementwise: the same for any subset of the particles)."""
        d = self.dim
        grip_a = _inside(self.grips[0], d, x0)
        grip_b = _inside(self.grips[1], d, x0) & ~grip_a
        return grip_a, grip_b, ~(grip_a | grip_b), _project(x0, self.mid, self.e[None, :])[:, 0]

    def record(self, t, sums, maxes, components, v_time=None) -> None:
        d = self.dim
        cA = sums[1:1 + d] / sums[0]
        cB = sums[d + 2:2 * d + 2] / sums[d + 1]
        stretch = (float(np.linalg.norm(cB - cA)) - self.h) / self.L0
        # ∫σ_ee dV = force × current length for a force uniform along the bar: nominal stress
        stress = float(sums[-3]) / (stretch * self.L0) / self.area0
        comps = -1 if components is None else int(components)
        separated = self.separation_time is not None
        self._add(float(t), stretch, float(maxes[0]), comps, stress)
        if self.separation_time is not None and not separated and sums[-2] > 0:
            self.crack_position = float(sums[-1] / sums[-2])
            self.crack_range = [float(-maxes[2]), float(maxes[1])]

    def _add(self, t, stretch, damage, comps, stress) -> None:
        super()._add(t, stretch, damage, comps, stress)
        if self.peak_stress is None or stress > self.peak_stress:
            self.peak_stress, self.stretch_at_peak = stress, stretch
        if self.failure_time is None and damage >= FULL:
            self.failure_time, self.stretch_at_failure = float(t), stretch
        if comps > 1 and self.separation_time is None:
            self.separation_time, self.stretch_at_separation = float(t), stretch
        self.max_stretch = first_max(self.max_stretch, stretch)
        self.max_damage = first_max(self.max_damage, damage)
        self.max_components = first_max(self.max_components, int(comps))

    def result(self) -> dict:
        """JSON-ready dict: the measured and predicted stretches and positions (class doc)."""
        pred = self.predicted or {}
        sep = self.stretch_at_separation
        rel = None
        if sep is not None and pred:
            rel = (sep - pred["stretch"]) / (pred["stretch"] - 1.0)
        return {
            "separated": self.separation_time is not None,
            "separation_time": self.separation_time,
            "stretch_at_separation": to_plain(sep),
            "failure_time": self.failure_time,
            "stretch_at_failure": to_plain(self.stretch_at_failure),
            "predicted_failure_stretch": to_plain(pred.get("stretch")),
            "predicted_peak_stress": to_plain(pred.get("peak_stress")),
            "peak_stress": to_plain(self.peak_stress),
            "stretch_at_peak_stress": to_plain(self.stretch_at_peak),
            "opening_allowance": to_plain(self.allowance),
            "separation_excess": to_plain(rel),
            "crack_position": to_plain(self.crack_position),
            "crack_range": self.crack_range,
            "weak_segment_position": to_plain(self.weak_position),
            "weak_segment_halfwidth": to_plain(self.weak_halfwidth),
            "max_stretch": to_plain(self.max_stretch),
            "max_damage": to_plain(self.max_damage),
            "bar_length": self.L0,
            "max_components": None if self.max_components is None else int(self.max_components),
            "samples": self.samples,
        }
