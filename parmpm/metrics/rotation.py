"""A body spinning rigidly (``metrics.kind = "rotation"``): do the particle domains and the stress
survive large rotation?

Body 0 spins about its centre with the angular velocity ω of its ``angular_velocity`` key
(2D, no gravity, free boundaries). Exactly, it keeps its angular momentum and turns through about
``θ = ω t``; started unstressed, it "breathes" (expands radially and oscillates about the
centrifugally stretched state), so its kinetic energy dips periodically by a little, and its
stress stays of the order of the centrifugal scale ``ρ0 ω² R²`` (R: the largest distance of a
particle from the centre); its domains keep their size. Each sample records:

* ``area_ratio``: total domain size over its initial value (:func:`parmpm.domains.domain_sizes`:
  cpGIMP's ``l0·|F_kk|`` boxes shrink as ``cos² θ`` towards 90°; CPDI's ``R = F·R0`` keeps its
  size), and ``min_area_ratio``, the smallest single-particle ratio;
* ``stress_ratio``: the largest Frobenius norm of the Cauchy stress over ``ρ0 ω² R²``;
* ``energy_ratio`` and ``momentum_ratio``: kinetic energy and angular momentum (about the
  centre) over their initial values.
"""
from __future__ import annotations

import math

import numpy as np

from parmpm.domains import domain_sizes
from parmpm.errors import SceneError
from parmpm.metrics import register_metrics
from parmpm.metrics.common import History, as_points, glb_max, to_plain


@register_metrics("rotation")
class RotationMetrics(History):
    """Domain size, stress, energy and angular momentum of a spinning body (2D)."""

    def __init__(self, scene_data: dict, x0: np.ndarray, mass: np.ndarray, comm=None, gid=None):
        self.dim = int(scene_data["dim"])
        if self.dim != 2:
            raise SceneError('metrics.kind = "rotation" is for 2D scenes')
        body = scene_data["bodies"][0]
        if not body.get("angular_velocity"):  # none, or 0: nothing spins to measure against
            raise SceneError('metrics.kind = "rotation" needs a nonzero bodies.0.angular_velocity'
                             f' (got {body.get("angular_velocity")!r}; or set metrics.kind = "none")')
        self.omega = float(body["angular_velocity"])
        self.centre = (np.asarray(body["center"], float) if body["shape"] != "box" else
                       0.5 * (np.asarray(body["min"], float) + np.asarray(body["max"], float)))
        x0, _, _ = self._own(x0, mass, comm, gid)
        rho = scene_data["materials"][body["material"]]["density"]
        # the largest distance of a particle from the centre, over every rank (exact)
        radius = float(np.sqrt(glb_max(comm, np.max(np.sum((x0 - self.centre) ** 2, axis=1),
                                                     initial=-np.inf))))
        self.stress_scale = rho * self.omega**2 * radius**2
        self.times: list[float] = []
        self.area_ratio: list[float] = []
        self.min_area_ratio: list[float] = []
        self.stress_ratio: list[float] = []
        self.energy: list[float] = []
        self.momentum: list[float] = []

    def terms(self, gid, x, v, F, particles=None, method=0, lcr=None, inertia=None, **context):
        """Per particle: domain size now and at rest, kinetic energy, angular momentum (with
        APIC's affine part, ``inertia = diag D_p``: :mod:`parmpm.affine`); local maxima of the
        stress norm and of ``−(size / size at rest)``."""
        n = np.shape(gid)[0]
        x, v = as_points(x, n, 2), as_points(v, n, 2)
        _, m = self.reference(gid, particles)
        size = domain_sizes(2, method, lcr, F, particles.r0, particles.lh0,
                            getattr(particles, "corners", None))
        size0 = np.prod(2.0 * particles.lh0, axis=1)
        r = x - self.centre
        spin = 0.0
        if particles.affine.shape[0] == n and inertia is not None and np.any(inertia):
            C, D = particles.affine, inertia
            spin = m * (C[:, 1, 0] * D[0] - C[:, 0, 1] * D[1])
        sums = np.stack([size, size0, 0.5 * m * np.sum(v * v, axis=1),
                         m * (r[:, 0] * v[:, 1] - r[:, 1] * v[:, 0]) + spin], axis=1)
        stress = np.sqrt(np.sum(particles.stress.reshape(n, 4) ** 2, axis=1))  # n = 0: idle rank
        return sums, np.array([stress.max(initial=-np.inf), (-size / size0).max(initial=-np.inf)])

    def record(self, t, sums, maxes, components, v_time=None) -> None:
        self.times.append(float(t))
        self.area_ratio.append(float(sums[0] / sums[1]))
        self.energy.append(float(sums[2]))
        self.momentum.append(float(sums[3]))
        self.stress_ratio.append(float(maxes[0]) / self.stress_scale)
        self.min_area_ratio.append(-float(maxes[1]))

    def result(self) -> dict:
        def rel(h):
            return [q / h[0] for q in h] if h and h[0] else [math.nan for _ in h]

        e, L = rel(self.energy), rel(self.momentum)
        return {
            "angular_velocity": self.omega,
            "turns": self.omega * self.times[-1] / (2 * math.pi) if self.times else 0.0,
            "stress_scale": self.stress_scale,
            "area_ratio_min": to_plain(min(self.area_ratio)) if self.times else None,
            "min_area_ratio": to_plain(min(self.min_area_ratio)) if self.times else None,
            "stress_ratio_max": to_plain(max(self.stress_ratio)) if self.times else None,
            "energy_ratio_final": to_plain(e[-1]) if e else None,
            "momentum_ratio_final": to_plain(L[-1]) if L else None,
            "history": {"t": self.times, "area_ratio": self.area_ratio,
                        "min_area_ratio": self.min_area_ratio, "stress_ratio": self.stress_ratio,
                        "energy_ratio": e, "momentum_ratio": L},
            "samples": len(self.times),
        }


RotationMetrics._STATE = ("times", "area_ratio", "min_area_ratio", "stress_ratio", "energy",
                          "momentum")
