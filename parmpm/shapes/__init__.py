"""Interpolator registry: each interpolator's name, kernel code, documentation and ghost width.

Nothing here compiles: reading or checking a scene needs the names, not the kernels. The kernels
dispatch on the integer code (:func:`parmpm.shapes.support.particle_support`, the one switch;
numba cannot cache kernels that take functions as arguments), and the scene schema, the CLI and
the interpolator tables of the README and of ``docs/concepts/methods.md`` read the names and
documentation from :data:`INTERPOLATORS`.

Ghost width (cells) is derived from the support. A particle owned by a patch has its centre in a
patch cell, so a support reaching ``r`` grid units from the centre touches nodes at most
``⌈r⌉`` cells outside the patch:

* ``mpm``: the particle's own cell, whose far node the local box already holds → 0;
* ``ugimp``: half-width ``Δx/(2·ppc) ≤ Δx/2`` → 1;
* ``bspline``: support half-width 3/2 cells, so the nodes ``c ± 1`` around the nearest node ``c``
  of a centre in a patch cell lie at most one cell outside the patch → 1;
* ``cpdi`` and ``cpdi2`` with domain scaling: corners within ``l_cr`` → ``⌈l_cr / min Δx⌉`` (2 for
  the default ``l_cr = 2·min Δx``: the seed's point);
* ``cpgimp`` and unscaled ``cpdi``/``cpdi2``: unbounded (domains follow F), so 2 by default, a larger
  ``grid.ghost`` on request, and a reach check every step that stops the run cleanly.

To add an interpolator: its per-axis or per-particle weights in a module beside
:mod:`parmpm.shapes.gimp`, a code and an :class:`Interpolator` entry below, and its branch in
:func:`parmpm.shapes.support.particle_support`.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

#: the kernels' interpolator codes (:func:`parmpm.shapes.support.particle_support` switches on them)
MPM, UGIMP, CPGIMP, CPDI, BSPLINE, CPDI2 = 0, 1, 2, 3, 4, 5
#: each code as the kernels' switch takes it: a tuple whose *length* is the code. numba rewrites
#: ``len`` of a tuple argument to a constant and prunes the branches for the other interpolators
#: before typing them, so a loop is compiled with one interpolator's support, not all six (the
#: generic separation count of a cpdi run: 7.6 s to compile with all, 4.2 s with cpdi alone)
KINDS = {code: (0,) * code for code in (MPM, UGIMP, CPGIMP, CPDI, BSPLINE, CPDI2)}

UNBOUNDED_DEFAULT_GHOST = 2


def _no_ghost(lcr: float | None, min_dx: float) -> int:
    return 0


def _one_cell(lcr: float | None, min_dx: float) -> int:
    return 1


def _unbounded(lcr: float | None, min_dx: float) -> int:
    return UNBOUNDED_DEFAULT_GHOST


def _capped_at_lcr(lcr: float | None, min_dx: float) -> int:
    if lcr is None:
        return UNBOUNDED_DEFAULT_GHOST
    return max(1, math.ceil(lcr / min_dx - 1e-9))


@dataclass(frozen=True)
class Interpolator:
    """One interpolator: ``summary`` (one line, the CLI's), ``weight``, ``nodes`` and ``ghost``
    (the tables' columns), ``bounded`` (support bounded a priori, by the method or by
    l_cr) and ``ghost_rule(lcr, min_dx)`` (see the module doc)."""

    name: str
    code: int
    summary: str
    weight: str
    nodes: str
    ghost: str
    bounded: bool
    ghost_rule: Callable[[float | None, float], int]

    def ghost_width(self, lcr: float | None, min_dx: float) -> int:
        """Ghost cells that provably hold every node a patch's particles touch (see module doc);
        for unbounded supports, the default that the per-step reach check guards."""
        return self.ghost_rule(lcr, min_dx)


INTERPOLATORS = {i.name: i for i in (
    Interpolator("mpm", MPM, "standard MPM: linear hat at the particle centre",
                 "linear hat at the particle centre", "2^d", "0", True, _no_ghost),
    Interpolator("ugimp", UGIMP, "uGIMP: fixed top-hat domains (Bardenhagen & Kober 2004)",
                 "hat averaged over a fixed top-hat domain, half-width `Δx/(2·ppc)`", "3^d", "1",
                 True, _one_cell),
    Interpolator("cpgimp", CPGIMP, "cpGIMP: top-hat half-widths follow F_kk",
                 "as ugimp, half-widths `l0_k·|F_kk|` (follow the diagonal of F)", "grows with F",
                 "2 (checked)", False, _unbounded),
    Interpolator("cpdi", CPDI, "CPDI1 (Sadeghirad et al. 2011), optional l_cr domain scaling",
                 "CPDI1: `φ = 2^-d Σ_α S_i(x_α)` over the 2^d corners of `R = F·R0`",
                 "up to 4^d", "`⌈l_cr/min Δx⌉`", True, _capped_at_lcr),
    Interpolator("bspline", BSPLINE,
                 "quadratic B-spline at the particle centre (Steffen, Kirby & Berzins 2008, "
                 "IJNME 76:922-948)",
                 "quadratic B-spline at the particle centre, C¹ (no cell-crossing jump)", "3^d", "1",
                 True, _one_cell),
    Interpolator("cpdi2", CPDI2,
                 "CPDI2 (Sadeghirad, Brannon & Guilkey 2013): tracked corners, optional l_cr cap",
                 "CPDI2: `φ = Σ_α wf_α S_i(x_α)` over the 2^d tracked corners (docs/cpdi2.md)",
                 "up to 4^d", "`⌈l_cr/min Δx⌉`", True, _capped_at_lcr),
)}

#: the interpolators whose domains are capped at ``l_cr`` (``method.lcr``; default ``"2dx"``)
CAPPED = (CPDI, CPDI2)


def interpolator_names() -> str:
    """``"mpm, ugimp, cpgimp, cpdi, bspline, cpdi2"``: the registered names, for help texts."""
    return ", ".join(INTERPOLATORS)


def interpolator_table() -> str:
    """The interpolator table of the README and the methods page (Markdown), one row per
    registered interpolator."""
    rows = ["| name | weight `φ_ip` | nodes per particle | ghost cells |", "|---|---|---|---|"]
    rows += [f"| `{i.name}` | {i.weight} | {i.nodes} | {i.ghost} |" for i in INTERPOLATORS.values()]
    return "\n".join(rows)


__all__ = ["INTERPOLATORS", "Interpolator", "MPM", "UGIMP", "CPGIMP", "CPDI", "BSPLINE", "CPDI2", "CAPPED",
           "UNBOUNDED_DEFAULT_GHOST", "interpolator_names", "interpolator_table"]
