"""A body spinning rigidly (``metrics.kind = "rotation"``): do the particle domains and the stress
survive large rotation?

Body 0 spins about its centre with the angular velocity ω of its ``angular_velocity`` key
(2D, no gravity, free boundaries). Exactly, it keeps its angular momentum and turns through about
``θ = ω t``; started unstressed, it "breathes" (expands radially and oscillates about the
centrifugally stretched state), so its kinetic energy dips periodically by a little, and its
stress stays of the order of the centrifugal scale ``ρ0 ω² R²`` (R: the largest distance of a
particle from the centre); its domains keep their size. Each sample records:

* ``area_ratio``: total domain size over its initial value (:func:`parmpm.output.domains.domain_sizes`:
  cpGIMP's ``l0·|F_kk|`` boxes shrink as ``cos² θ`` towards 90°; CPDI's ``R = F·R0`` keeps its
  size), and ``min_area_ratio``, the smallest single-particle ratio;
* ``stress_ratio``: the largest Frobenius norm of the Cauchy stress over ``ρ0 ω² R²``;
* ``energy_ratio`` and ``momentum_ratio``: kinetic energy and angular momentum (about the
  centre) over their initial values.
"""
from __future__ import annotations

import math

import numpy as np

from parmpm.output.domains import domain_sizes
from parmpm.core.errors import SceneError
from parmpm.output.metrics import register_metrics
from parmpm.output.metrics.common import History, as_points, glb_max, to_plain
from parmpm.output.metrics.trace import first_max, first_min
from parmpm.particles.seeding.velocity import body_centre


@register_metrics("rotation")
class RotationMetrics(History):
    """Domain size, stress, energy and angular momentum of a spinning body (2D)."""

    _TRACE = ("times", "area_ratio", "min_area_ratio", "stress_ratio", "energy", "momentum")
    _STATE = ("area_ratio_min", "min_area_ratio_min", "stress_ratio_max", "first", "last")

    def __init__(self, spec, x0: np.ndarray, mass: np.ndarray, comm=None, gid=None):
        self.dim = int(spec.dim)
        if self.dim != 2:
            raise SceneError('metrics.kind = "rotation" is for 2D scenes')
        body = spec.bodies[0]
        if not body.angular_velocity:  # none, or 0: nothing spins to measure against
            raise SceneError('metrics.kind = "rotation" needs a nonzero bodies.0.angular_velocity'
                             f' (got {body.angular_velocity!r}; or set metrics.kind = "none")')
        self.omega = float(body.angular_velocity)
        self.centre = body_centre(body)  # what the body spins about
        x0, _, _ = self._own(x0, mass, comm, gid)
        rho = spec.materials[body.material].density
        # the largest distance of a particle from the centre, over every rank (exact)
        radius = float(np.sqrt(glb_max(comm, np.max(np.sum((x0 - self.centre) ** 2, axis=1),
                                                     initial=-np.inf))))
        self.stress_scale = rho * self.omega**2 * radius**2
        self._begin()
        self.area_ratio_min = self.min_area_ratio_min = self.stress_ratio_max = None
        self.first = self.last = None  # (t, energy, momentum) of the first and latest samples

    def terms(self, gid, x, v, F, particles=None, method=0, lcr=None, inertia=None, **context):
        """Per particle: domain size now and at rest, kinetic energy, angular momentum (with
        APIC's affine part, ``inertia = diag D_p``: :mod:`parmpm.transfer.affine`); local maxima of the
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
        self._add(float(t), float(sums[0] / sums[1]), -float(maxes[1]),
                  float(maxes[0]) / self.stress_scale, float(sums[2]), float(sums[3]))

    def _add(self, t, area, min_area, stress, energy, momentum) -> None:
        super()._add(t, area, min_area, stress, energy, momentum)
        self.area_ratio_min = first_min(self.area_ratio_min, area)
        self.min_area_ratio_min = first_min(self.min_area_ratio_min, min_area)
        self.stress_ratio_max = first_max(self.stress_ratio_max, stress)
        self.last = [t, energy, momentum]
        if self.first is None:
            self.first = self.last

    def result(self) -> dict:
        """JSON-ready dict: the extrema and final ratios over every sample, and ``history``:
        the trace's samples (all of them up to :data:`parmpm.output.metrics.trace.CAPACITY`)."""
        def rel(q, q0):
            return q / q0 if q0 else math.nan

        n = self.samples
        e0, L0 = (self.first[1], self.first[2]) if n else (0.0, 0.0)
        energy, momentum = self.trace.column("energy"), self.trace.column("momentum")
        return {
            "angular_velocity": self.omega,
            "turns": self.omega * self.last[0] / (2 * math.pi) if n else 0.0,
            "stress_scale": self.stress_scale,
            "area_ratio_min": to_plain(self.area_ratio_min) if n else None,
            "min_area_ratio": to_plain(self.min_area_ratio_min) if n else None,
            "stress_ratio_max": to_plain(self.stress_ratio_max) if n else None,
            "energy_ratio_final": to_plain(rel(self.last[1], e0)) if n else None,
            "momentum_ratio_final": to_plain(rel(self.last[2], L0)) if n else None,
            "history": {"t": self.times.tolist(), "area_ratio": self.area_ratio.tolist(),
                        "min_area_ratio": self.min_area_ratio.tolist(),
                        "stress_ratio": self.stress_ratio.tolist(),
                        "energy_ratio": [rel(q, e0) for q in energy.tolist()],
                        "momentum_ratio": [rel(q, L0) for q in momentum.tolist()]},
            "samples": n,
        }
