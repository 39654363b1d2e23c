"""Metrics registry: each ``metrics.kind`` of a scene, its documentation and its class.

A metrics kind records the per-scene history and the numbers a run's ``summary.json`` reports,
against :mod:`parmpm.exact.bars`. Nothing here compiles or imports the implementations: reading or
checking a scene needs the names (:data:`METRIC_KINDS`), and :func:`make_metrics` imports the
kind's module when a run builds its metrics. The kinds, one module each:

* :mod:`.bars`: the self-weighted (hanging) bar and the axially vibrating bar;
* :mod:`.tension`: a bar pulled apart between grips (where and when it breaks, against the
  damage model's prediction);
* :mod:`.manufactured`: the manufactured solution's error norm;
* :mod:`.rotation`: a spinning body (domain size, stress, energy).

Beside them: :mod:`.separation` (numerical fracture: connected pieces of material),
:mod:`.sums` (ordered per-patch sums), :mod:`.common` (reading the bar from the scene's records,
the history base class).

A metrics object is built once, from the scene's records (``scene.spec``) and, collectively,
each rank's own particles (reference positions ``x0``, masses, global ids): what it needs of the
whole body (a bar's extent, its tip particles, its mass) comes from reductions over the ranks, so
no rank holds another's particles. The run loop samples it every ``metrics.every_steps``
steps: each rank computes ``terms(gid, x, v, F, t=, particles=, method=, lcr=)`` for its own
particles (per-particle addends and local maxima, from the particle store's reference fields;
the keyword context serves metrics that need time or particle domains); the run driver sums the
addends patch by patch and the patches in id order (the same rounding on any number of ranks),
takes the maxima over ranks, and passes the totals to ``record``. Built without a communicator
from arrays of all particles (one process), ``sample`` does both for arrays in global-id order
(the same order as ``x0``).

To add a kind: a module beside :mod:`.rotation` with a class decorated
``@register_metrics("kind")``, and a :class:`MetricKind` entry below.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

from parmpm.core.errors import SceneError

#: ``metrics.kind`` of a scene without metrics
NO_METRICS = "none"


@dataclass(frozen=True)
class MetricKind:
    """One ``metrics.kind``: its ``summary`` (one line), the module and class that implement it,
    and whether it ``counts_pieces`` (the run then counts connected pieces of material, and
    ``metrics.stop_on_separation`` may stop on them)."""

    name: str
    summary: str
    module: str
    cls: str
    counts_pieces: bool

    def load(self) -> type:
        """The implementing class (its module is imported on first use)."""
        return getattr(importlib.import_module(f"parmpm.output.metrics.{self.module}"), self.cls)


METRIC_KINDS = {k.name: k for k in (
    MetricKind("hanging_bar", "self-weighted bar: stretch, tip and corner history, separation "
               "(1D: against the exact static state)", "bars", "HangingBarMetrics", True),
    MetricKind("vibrating_bar", "axially vibrating bar: centre-of-mass velocity against the "
               "exact mode", "bars", "VibratingBarMetrics", False),
    MetricKind("tension_bar", "bar pulled apart between grips: where and when it breaks, "
               "against the damage model's prediction", "tension", "TensionBarMetrics", True),
    MetricKind("manufactured", "RMS and largest position error against the manufactured motion",
               "manufactured", "ManufacturedMetrics", False),
    MetricKind("rotation", "spinning body: domain size, stress, energy and angular momentum",
               "rotation", "RotationMetrics", False),
)}


def metric_names() -> tuple[str, ...]:
    """Every value ``metrics.kind`` may take: the registered kinds, then ``"none"``."""
    return (*METRIC_KINDS, NO_METRICS)


def separation_kinds() -> tuple[str, ...]:
    """The kinds that count separated pieces (registry order)."""
    return tuple(name for name, k in METRIC_KINDS.items() if k.counts_pieces)


def register_metrics(kind: str):
    """Class decorator of a kind's implementation: checks that the kind is registered here and
    that the entry names this class, and sets ``kind`` and ``needs_components`` from the entry."""

    def deco(cls):
        entry = METRIC_KINDS.get(kind)
        home = None if entry is None else (f"parmpm.output.metrics.{entry.module}", entry.cls)
        if home != (cls.__module__, cls.__name__):
            raise TypeError(f"metrics class {cls.__module__}.{cls.__name__} registers kind "
                            f"{kind!r}, which parmpm.output.metrics.METRIC_KINDS does not name for it")
        cls.kind = kind
        cls.needs_components = entry.counts_pieces
        return cls

    return deco


def make_metrics(spec, x0, mass, comm=None, gid=None):
    """The metrics object of the scene's ``metrics.kind`` (``spec``: the scene's records,
    ``scene.spec``), or None for ``"none"``.
    ``x0``, ``mass``: reference positions and masses of this rank's particles (global ids
    ``gid``) under ``comm`` (collective), or of every particle without it (one process)."""
    kind = spec.metrics.kind
    if kind == NO_METRICS:
        return None
    if kind not in METRIC_KINDS:
        raise SceneError(f"unknown metrics kind {kind!r} "
                         f"(known: none, {', '.join(sorted(METRIC_KINDS))})")
    return METRIC_KINDS[kind].load()(spec, x0, mass, comm, gid)


_LAZY = {"patch_sums": "sums", "count_components": "separation",
         **{k.cls: k.module for k in METRIC_KINDS.values()}}


def __getattr__(name: str):
    """The implementations, loaded on first use (importing the registry compiles nothing):
    ``METRICS`` (kind → class), the classes, :func:`.sums.patch_sums` and
    :func:`.separation.count_components`."""
    if name == "METRICS":
        return {kind: entry.load() for kind, entry in METRIC_KINDS.items()}
    if name in _LAZY:
        return getattr(importlib.import_module(f"parmpm.output.metrics.{_LAZY[name]}"), name)
    raise AttributeError(f"module 'parmpm.output.metrics' has no attribute {name!r}")


__all__ = ["METRIC_KINDS", "MetricKind", "NO_METRICS", "metric_names", "separation_kinds",
           "register_metrics", "make_metrics", "METRICS", "patch_sums", "count_components",
           "HangingBarMetrics", "VibratingBarMetrics", "ManufacturedMetrics", "RotationMetrics",
           "TensionBarMetrics"]
