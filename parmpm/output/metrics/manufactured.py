"""Error norms of the manufactured solution (``metrics.kind = "manufactured"``).

Position error of particle p: ``e_p = |x_p − φ(X_p, t)|`` with ``φ = X + U`` of
:func:`parmpm.exact.bars.manufactured_motion`. Each sample records the RMS over particles,
``sqrt(Σ e_p² / N)`` (Wallstedt & Guilkey 2008; Kamojjala et al. 2015), and the largest ``e_p``.
The summary reports both at the last sample and their maxima over time.
"""
from __future__ import annotations

import math

import numpy as np

from parmpm.core.errors import SceneError
from parmpm.exact.bars import manufactured_motion
from parmpm.output.metrics import register_metrics
from parmpm.output.metrics.common import History, as_points, to_plain
from parmpm.output.metrics.trace import nanmax


@register_metrics("manufactured")
class ManufacturedMetrics(History):
    """RMS and maximum position error against the manufactured motion."""

    _TRACE = ("times", "rms", "linf")
    _STATE = ("rms_max", "linf_max")

    def __init__(self, spec, x0: np.ndarray, mass: np.ndarray, comm=None, gid=None):
        self.dim = int(spec.dim)
        self._own(x0, mass, comm, gid)  # nothing of the particles is needed beyond sampling
        man = spec.manufactured
        if not man:
            raise SceneError('metrics.kind = "manufactured" needs a [manufactured] table')
        mat = next(iter(spec.materials.values()))
        self.A = float(man.amplitude)
        self.c = math.sqrt(mat.youngs_modulus / mat.density)
        self.period = 2.0 / self.c
        self._begin()
        self.rms_max = self.linf_max = math.nan  # nanmax over the samples

    def terms(self, gid, x, v, F, t=0.0, **context):
        """Per-particle squared error and count; the local maximum error."""
        n = np.shape(gid)[0]
        X, _ = self.reference(gid, context.get("particles"))
        u, _, _ = manufactured_motion(X, t, self.A, self.c)
        e2 = np.sum((as_points(x, n, self.dim) - X - u) ** 2, axis=1)
        sums = np.stack([e2, np.ones(n)], axis=1)
        return sums, np.array([math.sqrt(float(e2.max())) if n else -np.inf])

    def record(self, t, sums, maxes, components, v_time=None) -> None:
        rms = math.sqrt(float(sums[0]) / float(sums[1])) if sums[1] > 0 else math.nan
        self._add(float(t), rms, float(maxes[0]))

    def _add(self, t, rms, linf) -> None:
        super()._add(t, rms, linf)
        self.rms_max = nanmax(self.rms_max, rms)
        self.linf_max = nanmax(self.linf_max, linf)

    def result(self) -> dict:
        n = self.samples
        rms, linf = self.rms, self.linf
        return {
            "rms_error": to_plain(rms[-1]) if n else None,
            "rms_error_max": to_plain(self.rms_max) if n else None,
            "max_error": to_plain(linf[-1]) if n else None,
            "max_error_max": to_plain(self.linf_max) if n else None,
            "amplitude": self.A,
            "period": self.period,
            "samples": n,
        }
