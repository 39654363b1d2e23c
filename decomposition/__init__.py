"""Patch decomposition of a Cartesian node grid: layout, ghost layers, halo exchange.

Physics-free: this package knows "fields on a node grid cut into patches" and nothing of MPM.
The index arithmetic (:mod:`decomposition.layout`) needs no communicator; the halo operations
(:mod:`decomposition.halo`) sum ghost contributions into owners and copy owners back to ghosts.
"""
from decomposition.layout import PatchLayout
from decomposition.halo import HaloPlan, accumulate, fill

__all__ = ["PatchLayout", "HaloPlan", "accumulate", "fill"]
