"""Interpolator registry: name → kernel code, and the ghost width each one needs.

Ghost width (cells) is derived from the support. A particle owned by a patch has its centre in a
patch cell, so a support reaching ``r`` grid units from the centre touches nodes at most
``⌈r⌉`` cells outside the patch:

* ``mpm``: the particle's own cell, whose far node the local box already holds → 0;
* ``ugimp``: half-width ``Δx/(2·ppc) ≤ Δx/2`` → 1;
* ``cpdi`` with domain scaling: corners within ``l_cr`` → ``⌈l_cr / min Δx⌉`` (2 for the default
  ``l_cr = 2·min Δx``: the seed's point);
* ``cpgimp`` and unscaled ``cpdi``: unbounded (domains follow F), so 2 by default, a larger
  ``grid.ghost`` on request, and a reach check every step that stops the run cleanly.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from parmpm.shapes.support import CPDI, CPGIMP, MPM, UGIMP, domain_matrix, particle_support

UNBOUNDED_DEFAULT_GHOST = 2


@dataclass(frozen=True)
class Interpolator:
    name: str
    code: int
    summary: str
    bounded: bool  # support bounded a priori (by the method, or by l_cr)?

    def ghost_width(self, lcr: float | None, min_dx: float) -> int:
        """Ghost cells that provably hold every node a patch's particles touch (see module doc);
        for unbounded supports, the default that the per-step reach check guards."""
        if self.code == MPM:
            return 0
        if self.code == UGIMP:
            return 1
        if self.code == CPDI and lcr is not None:
            return max(1, math.ceil(lcr / min_dx - 1e-9))
        return UNBOUNDED_DEFAULT_GHOST


INTERPOLATORS = {
    "mpm": Interpolator("mpm", MPM, "standard MPM: linear hat at the particle centre", True),
    "ugimp": Interpolator("ugimp", UGIMP, "uGIMP: fixed top-hat domains (Bardenhagen & Kober 2004)", True),
    "cpgimp": Interpolator("cpgimp", CPGIMP, "cpGIMP: top-hat half-widths follow F_kk", False),
    "cpdi": Interpolator("cpdi", CPDI, "CPDI1 (Sadeghirad et al. 2011), optional l_cr domain scaling", True),
}

__all__ = ["INTERPOLATORS", "Interpolator", "particle_support", "domain_matrix",
           "MPM", "UGIMP", "CPGIMP", "CPDI"]
