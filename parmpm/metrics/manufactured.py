"""Error norms of the manufactured solution (``metrics.kind = "manufactured"``).

Position error of particle p: ``e_p = |x_p − φ(X_p, t)|`` with ``φ = X + U`` of
:func:`parmpm.exact.manufactured_motion`. Each sample records the RMS over particles,
``sqrt(Σ e_p² / N)`` (Wallstedt & Guilkey 2008; Kamojjala et al. 2015), and the largest ``e_p``.
The summary reports both at the last sample and their maxima over time.
"""
from __future__ import annotations

import math

import numpy as np

from parmpm.errors import SceneError
from parmpm.exact import manufactured_motion
from parmpm.metrics import register_metrics
from parmpm.metrics.common import History, as_points, to_plain


@register_metrics("manufactured")
class ManufacturedMetrics(History):
    """RMS and maximum position error against the manufactured motion."""

    def __init__(self, scene_data: dict, x0: np.ndarray, mass: np.ndarray, comm=None, gid=None):
        self.dim = int(scene_data["dim"])
        self._own(x0, mass, comm, gid)  # nothing of the particles is needed beyond sampling
        man = scene_data.get("manufactured")
        if not man:
            raise SceneError('metrics.kind = "manufactured" needs a [manufactured] table')
        mat = next(iter(scene_data["materials"].values()))
        self.A = float(man["amplitude"])
        self.c = math.sqrt(mat["youngs_modulus"] / mat["density"])
        self.period = 2.0 / self.c
        self.times: list[float] = []
        self.rms: list[float] = []
        self.linf: list[float] = []

    def terms(self, gid, x, v, F, t=0.0, **context):
        """Per-particle squared error and count; the local maximum error."""
        n = np.shape(gid)[0]
        X, _ = self.reference(gid, context.get("particles"))
        u, _, _ = manufactured_motion(X, t, self.A, self.c)
        e2 = np.sum((as_points(x, n, self.dim) - X - u) ** 2, axis=1)
        sums = np.stack([e2, np.ones(n)], axis=1)
        return sums, np.array([math.sqrt(float(e2.max())) if n else -np.inf])

    def record(self, t, sums, maxes, components, v_time=None) -> None:
        self.times.append(float(t))
        self.rms.append(math.sqrt(float(sums[0]) / float(sums[1])) if sums[1] > 0 else math.nan)
        self.linf.append(float(maxes[0]))

    def result(self) -> dict:
        rms, linf = np.asarray(self.rms), np.asarray(self.linf)
        return {
            "rms_error": to_plain(rms[-1]) if rms.size else None,
            "rms_error_max": to_plain(np.nanmax(rms)) if rms.size else None,
            "max_error": to_plain(linf[-1]) if linf.size else None,
            "max_error_max": to_plain(np.nanmax(linf)) if linf.size else None,
            "amplitude": self.A,
            "period": self.period,
            "samples": len(self.times),
        }


ManufacturedMetrics._STATE = ("times", "rms", "linf")
