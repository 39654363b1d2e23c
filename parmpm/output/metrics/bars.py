"""Metrics of the bar scenes: the self-weighted (hanging) bar and the axially vibrating bar."""

from __future__ import annotations

import logging
import math

import numpy as np

from parmpm.core.errors import SceneError
from parmpm.exact.bars import (hanging_bar_static, hanging_bar_static_displacement, lame_parameters,
                          mode_constants, nominal_stress_1d, vibrating_bar_com_velocity)
from parmpm.output.metrics import register_metrics
from parmpm.output.metrics.common import (History, as_points, bar_box, bar_material, bar_span, gather_rows,
                                   glb_bounds, gravity, in_bar, material_constants, to_plain)
from parmpm.output.metrics.sums import gid_order_sum
from parmpm.output.metrics.trace import first_max, max_or_nan, nanmax

logger = logging.getLogger(__name__)


@register_metrics("hanging_bar")
class HangingBarMetrics(History):
    """Separation, stretch and tip history of the self-weighted bar (body 0).

    * axial stretch of particle p: ``|F_p e_a|`` (length of column ``a`` of F), ``a`` =
      ``metrics.axis`` (default ``dim − 1``, the axis a hanging bar's gravity acts along);
    * tip: the bar's particles with the extreme initial coordinate in the direction of gravity;
      its displacement is the mean displacement of those particles projected on ``−ĝ`` along the
      axis (so negative = downward);
    * bottom corner: of the tip particles, the one with the smallest reference coordinate on
      every other axis (2D: the bottom-left particle; 1D: the tip particle), the point whose
      displacement history Sadeghirad, Brannon & Burghardt (2011) plot for this bar. Its
      displacement along the axis (``corner_displacement``; negative = downward) gives the
      *first peak* (``corner_first_peak`` and ``corner_first_peak_time``: the lowest point of the
      first downswing) and the *rebound* (``corner_rebound``, ``corner_rebound_time``: the
      highest point of the upswing after it), found by :func:`first_peak_and_rebound`; ``None``
      where the run ended before the history turned;
    * separation: ``components > 1`` at some sample (see :func:`count_components`);
    * in 1D, the static elongation ``ΔL`` of :func:`parmpm.exact.bars.hanging_bar_static` with the
      material's 1D law (``exact_static_elongation``, at the very tip), the exact static
      displacement ``u*`` at the tip particles' reference position (half a particle spacing
      above the tip; ``exact_static_tip_displacement``), and
      ``relative_error_static = |(−tip_displacement) − u*| / u*`` at the last sample. Comparing
      with ``u*`` rather than ``ΔL`` removes an O(Δx²) offset that is not a solver error. It is
      meaningful only for damped or slowly ramped runs: an undamped bar oscillates about the
      static state, peaking at twice it in small strain.
    """

    _TRACE = ("times", "tip_history", "corner_history", "max_stretch_history",
              "components_history")
    _STATE = ("separation_time", "stretch_at_separation", "max_stretch", "max_tip",
              "max_components", "turns")

    def __init__(self, spec, x0: np.ndarray, mass: np.ndarray, comm=None, gid=None):
        self.dim = int(spec.dim)
        x0, mass, gid = self._own(x0, mass, comm, gid)
        g = gravity(spec)
        self.axis = int(spec.metrics.axis)
        self.g = math.hypot(*g)  # no overflow warning for an absurd g
        down = g[self.axis]
        self.up_sign = -1.0 if down > 0 else 1.0  # displacement · up_sign < 0 means downward

        body = spec.bodies[0]
        self.bar_box = bar_box(spec, body)
        bar = in_bar(self.bar_box, x0)
        xa = x0[:, self.axis]
        lo3, hi3 = glb_bounds(comm, x0[bar])  # the bar's extent per axis, over every rank

        def tol(k):
            return 1e-9 * max(float(hi3[k] - lo3[k]), 1.0)

        extreme = hi3[self.axis] if down > 0 else lo3[self.axis]
        # the tip particles (a face of the bar: a few) on every rank, in global-id order
        tip = bar & (np.abs(xa - extreme) <= tol(self.axis))
        self.tip, tip_x0 = gather_rows(comm, gid[tip], x0[tip])
        corner, cx = self.tip, tip_x0
        for k in range(self.dim):
            if k != self.axis:
                keep = cx[:, k] - cx[:, k].min() <= tol(k)
                corner, cx = corner[keep], cx[keep]
        self.corner = int(corner[0])
        lo, hi = bar_span(body, x0[bar], self.axis, comm)
        self.L = hi - lo
        # reference distance of the tip particles from the support (the top of the bar)
        xt = tip_x0[:, self.axis]
        self.X_tip = float(np.mean(hi - xt)) if down <= 0 else float(np.mean(xt - lo))

        self.exact_static_elongation = None
        self.exact_static_tip_displacement = None
        if self.dim == 1:
            model, E, nu, rho = material_constants(bar_material(spec, body))
            try:
                law = nominal_stress_1d(model, E, nu)
                exact = hanging_bar_static(self.L, rho, self.g, law)
                self.exact_static_elongation = exact["elongation"]
                self.exact_static_tip_displacement = float(
                    hanging_bar_static_displacement(self.X_tip, self.L, rho, self.g, law)
                )
            except (SceneError, ValueError) as err:
                if comm.Get_rank() == 0:  # every rank builds the metric: one line, not P
                    logger.warning("no exact static elongation: %s", err)

        self._begin()
        self.separation_time = None
        self.stretch_at_separation = None
        self.max_stretch = math.nan       # nanmax over the samples
        self.max_tip = math.nan           # nanmax of |tip displacement|
        self.max_components = None
        self._turns = TurningPoints()     # the corner's first peak and rebound

    def terms(self, gid, x, v, F, **context):
        """Per-particle addends (tip displacement along the axis, tip indicator, the same two for
        the bottom corner) and the local maximum axial stretch of the bar, for particles ``gid``
        (any subset, any order)."""
        n = np.shape(gid)[0]
        x = as_points(x, n, self.dim)
        F = np.asarray(F, dtype=float).reshape(n, self.dim, self.dim)
        x0, _ = self.reference(gid, context.get("particles"))
        tip = np.isin(gid, self.tip)
        corner = np.asarray(gid) == self.corner
        u = x[:, self.axis] - x0[:, self.axis]
        sums = np.zeros((n, 4))
        sums[:, 0] = np.where(tip, u, 0.0)
        sums[:, 1] = tip
        sums[:, 2] = np.where(corner, u, 0.0)
        sums[:, 3] = corner
        bar = in_bar(self.bar_box, x0)
        stretch = np.sqrt(np.sum(F[bar, :, self.axis] ** 2, axis=1))
        return sums, np.array([stretch.max() if stretch.size else -np.inf])

    def record(self, t, sums, maxes, components, v_time=None) -> None:
        """Record one sample from globally reduced :meth:`terms` and the component count."""
        max_stretch = float(maxes[0]) if np.isfinite(maxes[0]) else float("nan")
        tip = float(sums[0] / sums[1]) * self.up_sign if sums[1] > 0 else float("nan")
        corner = float(sums[2] / sums[3]) * self.up_sign if sums[3] > 0 else float("nan")
        comps = -1 if components is None else int(components)
        self._add(float(t), tip, corner, max_stretch, comps)

    def _add(self, t, tip, corner, max_stretch, comps) -> None:
        super()._add(t, tip, corner, max_stretch, comps)
        comps = int(comps)
        if comps > 1 and self.separation_time is None:
            self.separation_time = float(t)
            self.stretch_at_separation = max_stretch
        self.max_stretch = nanmax(self.max_stretch, max_stretch)
        self.max_tip = nanmax(self.max_tip, abs(tip))
        self.max_components = first_max(self.max_components, comps)
        self._turns.add(corner, t)

    @property
    def turns(self) -> dict:
        """The corner's :class:`TurningPoints`, as a checkpoint keeps them."""
        return self._turns.state()

    @turns.setter
    def turns(self, state: dict) -> None:
        self._turns = TurningPoints.of(state)

    def result(self) -> dict:
        """JSON-ready dict (see the class docstring for the definitions)."""
        n = self.samples
        last = self.trace.column("tip_history")[-1:] if n else ()
        tip_final = float(last[0]) if n else None
        exact = self.exact_static_tip_displacement
        rel = None
        if exact is not None and tip_final is not None and exact != 0.0:
            rel = abs(-tip_final - exact) / abs(exact)
        corner = self.trace.column("corner_history")
        peak, rebound = self._turns.peak, self._turns.rebound  # (index, t, u) or None
        return {
            "separated": self.separation_time is not None,
            "separation_time": self.separation_time,
            "max_stretch": to_plain(self.max_stretch) if n else None,
            "stretch_at_separation": to_plain(self.stretch_at_separation),
            "tip_displacement": to_plain(tip_final),
            "max_tip_displacement": to_plain(self.max_tip) if n else None,
            "corner_particle": self.corner,
            "corner_displacement": to_plain(corner[-1]) if n else None,
            "corner_first_peak": None if peak is None else to_plain(peak[2]),
            "corner_first_peak_time": None if peak is None else to_plain(peak[1]),
            "corner_rebound": None if rebound is None else to_plain(rebound[2]),
            "corner_rebound_time": None if rebound is None else to_plain(rebound[1]),
            "exact_static_elongation": to_plain(self.exact_static_elongation),
            "exact_static_tip_displacement": to_plain(exact),
            "relative_error_static": to_plain(rel),
            "max_components": int(self.max_components) if n else None,
            "samples": n,
        }


class TurningPoints:
    """The first peak and the rebound of a displacement history that starts at rest and first
    swings downward (``u < 0``), found one sample at a time (:meth:`add`): no history is kept.

    The first peak is the lowest sample of the first downswing, the rebound the highest sample of
    the upswing that follows it. A turning point counts only once the history has come back from
    it by ``tol·|peak|`` (so round-off wiggles and a run that ends on its way down do not count);
    :attr:`peak`, :attr:`rebound`: ``(index, t, u)`` of the sample, None until then. NaN samples
    are skipped. Of several equal samples, the first counts."""

    def __init__(self, tol: float = 0.01):
        self.tol, self.n = float(tol), 0
        self.high, self.high_at = math.nan, None  # the lowest point so far (as d = −u)
        self.peak = None
        self.low, self.low_at = math.nan, None    # the highest point since the peak
        self.rebound = None

    def add(self, u: float, t: float = math.nan) -> None:
        k, d = self.n, -float(u)
        self.n += 1
        if self.rebound is not None:
            return
        if self.peak is None:
            if d > self.high or (math.isnan(self.high) and not math.isnan(d)):
                self.high, self.high_at = d, (k, float(t), float(u))
            if self.high > 0.0 and self.high - d > self.tol * self.high:  # turned back up
                self.peak = self.high_at
                self.low, self.low_at = d, (k, float(t), float(u))
            return
        if d < self.low:
            self.low, self.low_at = d, (k, float(t), float(u))
        if d - self.low > self.tol * -self.peak[2]:  # turned back down
            self.rebound = self.low_at

    def state(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in vars(self).items()}

    @classmethod
    def of(cls, state: dict) -> TurningPoints:
        """The tracker :meth:`state` saved."""
        out = cls(state["tol"])
        for k, v in state.items():
            setattr(out, k, tuple(v) if isinstance(v, list) else v)
        return out


def first_peak_and_rebound(u, tol: float = 0.01) -> tuple[int | None, int | None]:
    """Sample indices of the first peak and the rebound of the displacement history ``u``
    (:class:`TurningPoints`); either is None when it has not shown by the last sample."""
    turns = TurningPoints(tol)
    for value in np.asarray(u, dtype=float).ravel():
        turns.add(value)
    return (None if turns.peak is None else turns.peak[0],
            None if turns.rebound is None else turns.rebound[0])


@register_metrics("vibrating_bar")
class VibratingBarMetrics(History):
    """Centre-of-mass velocity of the axially vibrating bar (body 0) against the exact mode.

    ``v̄_num = Σ m v_a / Σ m`` over the bar's particles, ``v̄_exact = v0/(β_n L) cos(ω_n t)``
    (:func:`parmpm.exact.bars.vibrating_bar_com_velocity`) with ``v0``, ``n``, ``a`` from body 0's
    ``vibration`` table (amplitude, mode, axis) and ``L`` its extent along ``a``. The error is
    ``sqrt(Σ (v̄_num − v̄_exact)² / Σ v̄_exact²)`` over the samples.

    The wave modulus is that of the material's small-strain law in the bar's setting: ``λ_L + 2μ``
    in 1D (uniaxial strain, the 1D law of :func:`parmpm.exact.bars.nominal_stress_1d`), ``E/(1 − ν²)``
    in 2D (plane strain, laterally free, long waves) and ``E`` in 3D; all equal ``E`` for ν = 0.
    """

    _TRACE = ("times", "com_velocity", "com_velocity_exact")
    _STATE = ("sq_error", "sq_exact", "max_abs_error")

    def __init__(self, spec, x0: np.ndarray, mass: np.ndarray, comm=None, gid=None):
        self.dim = int(spec.dim)
        x0, mass, gid = self._own(x0, mass, comm, gid)
        body = spec.bodies[0]
        vib = body.vibration
        if not vib:
            raise SceneError("vibrating_bar metrics need body 0's 'vibration' table")
        self.v0 = float(vib.amplitude)
        self.mode = int(vib.mode)
        self.axis = int(vib.axis)
        lo, hi = bar_span(body, x0, self.axis, comm)
        self.L = hi - lo
        _, E, nu, self.rho = material_constants(bar_material(spec, body))
        lam, mu = lame_parameters(E, nu)
        self.modulus = {1: lam + 2.0 * mu, 2: E / (1.0 - nu * nu)}.get(self.dim, E)
        _, omega, _ = mode_constants(self.L, self.modulus, self.rho, self.mode)
        self.period = 2.0 * math.pi / omega
        self.bar_box = bar_box(spec, body)
        bar = in_bar(self.bar_box, x0)
        # Σ m over the bar in global-id order, as one process holding every particle sums it
        self.bar_mass = gid_order_sum(comm, gid[bar], mass[bar])
        self._begin()
        self.sq_error = 0.0      # Σ (v̄_num − v̄_exact)²
        self.sq_exact = 0.0      # Σ v̄_exact²
        self.max_abs_error = -math.inf  # max |v̄_num − v̄_exact| (NaN if a sample is)

    def terms(self, gid, x, v, F, **context):
        """Per-particle momentum along the axis of the bar's particles ``gid``; no maxima."""
        n = np.shape(gid)[0]
        v = as_points(v, n, self.dim)
        x0, mass = self.reference(gid, context.get("particles"))
        sums = np.where(in_bar(self.bar_box, x0), mass * v[:, self.axis], 0.0)[:, None]
        return sums, np.zeros(0)

    def record(self, t, sums, maxes, components, v_time=None) -> None:
        """Record ``v̄_num`` and ``v̄_exact``. The explicit step is symplectic Euler: the particle
        velocity after a step approximates the velocity half a step earlier (``v_time``), to second
        order; comparing it with the exact value at ``t`` instead adds an O(Δt) error."""
        vbar = float(sums[0]) / self.bar_mass
        exact = float(
            vibrating_bar_com_velocity(t if v_time is None else v_time, self.v0, self.L, self.modulus, self.rho, self.mode)
        )
        self._add(float(t), vbar, exact)

    def _add(self, t, vbar, exact) -> None:
        super()._add(t, vbar, exact)
        self.sq_error += (vbar - exact) ** 2
        self.sq_exact += exact**2
        self.max_abs_error = max_or_nan(self.max_abs_error, abs(vbar - exact))

    def result(self) -> dict:
        """JSON-ready dict: ``com_velocity_rel_l2_error``, ``samples``, ``period``, ..."""
        den = self.sq_exact
        err = math.sqrt(self.sq_error / den) if den > 0 else None
        return {
            "com_velocity_rel_l2_error": to_plain(err),
            "com_velocity_max_abs_error": to_plain(self.max_abs_error) if self.samples else None,
            "samples": self.samples,
            "period": to_plain(self.period),
            "wave_modulus": to_plain(self.modulus),
            "length": to_plain(self.L),
        }


