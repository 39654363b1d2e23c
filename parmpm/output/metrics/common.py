"""What the metrics classes share: reading the bar (body 0) from the scene's records
(``scene.spec``, :mod:`parmpm.scene.records`: every field present, materials keyed by name,
per-axis values as tuples of ``dim`` numbers), the collective reductions a metric is built with (what one
rank holds reduced over all: bounds, distinct values, a few rows gathered) and the history base
class :class:`History`.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from decomposition import allreduce_max, is_parallel
from parmpm.output.metrics.trace import Trace

logger = logging.getLogger(__name__)


def bar_material(spec, body):
    """The material record of ``body`` (bodies name their material)."""
    return spec.materials[body.material]


def material_constants(mat) -> tuple[str, float, float, float]:
    """``(model, E, nu, density)`` of a material record."""
    return (mat.model, float(mat.youngs_modulus), float(mat.poisson_ratio), float(mat.density))


def body_box(body):
    """``(min, max)`` arrays of a box body, or None for a disk or sphere (a turned box gives its
    unturned bounds)."""
    if body.shape != "box":
        return None
    return np.asarray(body.min, dtype=float), np.asarray(body.max, dtype=float)


def lattice_span(coord: np.ndarray, comm=None) -> tuple[float, float]:
    """Span of a uniform particle lattice along one axis: the particles' range widened by half
    a particle spacing at each end (particles sit at the centres of their sub-cells).
    ``coord``: this rank's particles' coordinates; the distinct values of every rank's are
    gathered (one lattice line, not the particles)."""
    u = glb_unique(comm, coord)
    if u.size < 2:
        return (float(u[0]), float(u[0])) if u.size else (0.0, 0.0)
    gaps = np.diff(u)
    spacing = gaps[gaps > 1e-9 * (u[-1] - u[0])].min()
    return float(u[0] - 0.5 * spacing), float(u[-1] + 0.5 * spacing)


def bar_span(body, x0: np.ndarray, axis: int, comm=None) -> tuple[float, float]:
    """``(lo, hi)`` of body 0 along ``axis``: its box, else the particle lattice (``x0``: this
    rank's particles; collective when ``comm`` is)."""
    box = body_box(body)
    if box is not None:
        return float(box[0][axis]), float(box[1][axis])
    span = lattice_span(x0[:, axis], comm)
    logger.info("body 0 has no box geometry; bar span %s taken from the particle lattice", span)
    return span


def bar_box(spec, body):
    """What :func:`in_bar` tests: None (every particle is the bar's: a one-body scene, or
    body 0 is not a box) or ``(min, max, tol)`` of body 0's box."""
    if len(spec.bodies) <= 1:
        return None
    box = body_box(body)
    if box is None:
        logger.warning("several bodies and body 0 is not a box: metrics use all particles")
        return None
    lo, hi = box
    return lo, hi, 1e-9 * max(float(np.max(hi - lo)), 1.0)


def in_bar(box, x0: np.ndarray) -> np.ndarray:
    """Particles of body 0 among reference positions ``x0`` (``box``: :func:`bar_box`);
    elementwise, so the same for any subset of the particles."""
    if box is None:
        return np.ones(x0.shape[0], dtype=bool)
    lo, hi, tol = box
    return np.all((x0 >= lo - tol) & (x0 <= hi + tol), axis=1)


def bar_mask(spec, body, x0: np.ndarray) -> np.ndarray:
    """Particles of body 0: all of them in a one-body scene, else those inside body 0's box."""
    return in_bar(bar_box(spec, body), x0)


# --- collective reductions of what one rank holds (comm None or one rank: local) -------------
def glb_bounds(comm, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per column, the smallest and largest value over every rank's rows ``x`` (n, k), exact
    (``±inf`` where no rank has a row)."""
    k = x.shape[1]
    local = np.concatenate([-x.min(axis=0, initial=np.inf), x.max(axis=0, initial=-np.inf)])
    both = allreduce_max(comm, local) if is_parallel(comm) else local
    return -both[:k], both[k:]


def glb_max(comm, value: float) -> float:
    """The largest of every rank's ``value`` (exact)."""
    v = np.array([value], float)
    return float((allreduce_max(comm, v) if is_parallel(comm) else v)[0])


def glb_unique(comm, values: np.ndarray) -> np.ndarray:
    """The distinct values over every rank's ``values``, sorted."""
    u = np.unique(values)
    return np.unique(np.concatenate(comm.allgather(u))) if is_parallel(comm) else u


def gather_rows(comm, gid: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every rank's ``(gid, rows)`` (a few particles: a bar's tip) on every rank, in global-id
    order."""
    gid, rows = np.asarray(gid, np.int64), np.asarray(rows)
    if is_parallel(comm):
        parts = comm.allgather((gid, rows))
        gid = np.concatenate([p[0] for p in parts])
        rows = np.concatenate([p[1] for p in parts])
    order = np.argsort(gid, kind="stable")
    return gid[order], rows[order]


def gravity(spec) -> np.ndarray:
    """The gravity vector ``gravity.g``."""
    return np.asarray(spec.gravity.g, dtype=float)


def as_points(a, n: int, dim: int) -> np.ndarray:
    return np.asarray(a, dtype=float).reshape(n, dim)


def to_plain(value):
    """Python float/None for JSON (non-finite numbers become None)."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


class History:
    """Base of the metrics classes: the particles a metric is built from (:meth:`_own`), their
    reference fields at sampling time (:meth:`reference`), the record of the samples, its
    checkpointing and :meth:`sample`. ``needs_components`` (the run then counts connected
    pieces) is set from the kind's registry entry (:data:`parmpm.output.metrics.METRIC_KINDS`).

    The record does not grow with the run (:mod:`parmpm.output.metrics.trace`): a class's ``record``
    reduces a sample to a row of ``_TRACE`` (``times`` first) and hands it to ``_add``, which
    updates the summary's streaming figures (the attributes named in ``_STATE``) and the bounded
    :class:`~parmpm.output.metrics.trace.Trace` (``self.trace``); each trace column reads as an
    attribute of its name (``m.times``, ``m.tip_history``: arrays of the kept samples and the
    latest). A checkpoint keeps ``_STATE`` and the trace (:meth:`state`); one written before the
    trace, with whole lists, is replayed row by row (:meth:`restore`).

    A metric is built from the particles one rank holds (``x0``, ``mass``, global ids ``gid``)
    and a communicator ``comm``: what it needs of the others comes from collective reductions,
    and it keeps only those (scalars, a bar's tip), never a particle field. Built without a
    communicator, the arrays are every particle's (one process) and are kept for
    :meth:`sample`."""

    _STATE: tuple[str, ...] = ()
    _TRACE: tuple[str, ...] = ("times",)
    needs_components = False

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        for name in cls._TRACE:  # a trace column reads as an attribute
            if name not in vars(cls):
                setattr(cls, name, property(lambda self, c=name: self.trace.column(c),
                                            doc=f"the trace's {name!r} (kept samples, latest)"))

    def _begin(self) -> None:
        """Start an empty record (a class sets its ``_STATE`` attributes' starting values)."""
        self.trace = Trace(self._TRACE)

    def _add(self, *row) -> None:
        """One sample, reduced to a row of ``_TRACE``: update ``_STATE`` and the trace."""
        self.trace.add(*row)

    @property
    def samples(self) -> int:
        """Samples recorded so far."""
        return self.trace.count

    def _own(self, x0, mass, comm, gid):
        """``(x0 (n, dim), mass, gid)`` of the particles the metric is built from (``gid``
        default: 0..n−1); kept as ``self.x0``, ``self.mass`` only without ``comm``."""
        mass = np.asarray(mass, dtype=float)
        x0 = as_points(x0, mass.shape[0], self.dim)
        gid = np.arange(mass.shape[0]) if gid is None else np.asarray(gid, np.int64)
        self.x0, self.mass = (x0, mass) if comm is None else (None, None)
        return x0, mass, gid

    def reference(self, gid, particles=None) -> tuple[np.ndarray, np.ndarray]:
        """``(x0, mass)`` of the particles ``gid``: the particle store's rows (``particles``,
        in the order of ``gid``), else those kept at construction."""
        if particles is not None:
            return particles.x0, particles.mass
        if self.x0 is None:  # built collectively: it keeps no particle field (issue: O(N/P))
            raise TypeError(f"{type(self).__name__}.terms() needs particles= (the rank's particle "
                            "store): a metric built with a communicator keeps no positions")
        return self.x0[gid], self.mass[gid]

    def sample(self, t, x, v, F, components, v_time=None) -> None:
        """Record one sample from arrays of *all* particles in global-id order (a metric built
        without a communicator, whose :meth:`terms` need no particle context beyond x, v, F
        and t)."""
        n = self.x0.shape[0]
        sums, maxes = self.terms(np.arange(n), x, v, F, t=t)
        self.record(t, sums.sum(axis=0), maxes, components, v_time)

    def state(self) -> dict:
        """The record so far (JSON-ready, bounded), for checkpoints."""
        return {**{k: getattr(self, k) for k in self._STATE}, "trace": self.trace.state()}

    def restore(self, state: dict) -> None:
        """Continue the record saved by :meth:`state` (a restarted run). A state saved before
        the trace (whole lists, named as the trace's columns) is replayed sample by sample; a
        column it lacks is NaN."""
        if "trace" in state:
            self.trace.restore(state["trace"])
        else:
            n = len(state.get("times") or ())
            cols = [state.get(c) or [math.nan] * n for c in self._TRACE]
            for row in zip(*cols):
                self._add(*row)
        for k in self._STATE:
            if k in state:
                setattr(self, k, state[k])
