"""Patch decomposition of a Cartesian node grid: layout, sparse patch set, halo exchange,
record migration and load balance.

Physics-free: this package knows "fields on a node grid cut into patches" and "records that
belong to a patch" and nothing of MPM. :mod:`~decomposition.boxes` is the patch-box
arithmetic (owned box, ghost base, cell or point → patch), written once;
:mod:`~decomposition.layout` holds a layout's parameters and applies it;
:mod:`~decomposition.partition` picks the existing patches and their owners;
:mod:`~decomposition.halo` sums ghost contributions into owners and copies owners back to ghosts
(locally and over MPI); :mod:`~decomposition.migrate` moves records between ranks;
:mod:`~decomposition.patchset` keeps the live picture consistent on every rank.
"""
from decomposition.comm import (SerialComm, allreduce_max, deal_from_root, is_parallel,
                                max_and_patch_sum, ordered_sum, ranks_on_this_node, world)
from decomposition.halo import HaloPlan, accumulate, accumulate_max, fill, halo_pairs
from decomposition.layout import PatchLayout
from decomposition.migrate import exchange, migrate
from decomposition.partition import active_patches, assign, imbalance, morton_order
from decomposition.patchset import PatchSet

__all__ = ["PatchLayout", "PatchSet", "HaloPlan", "accumulate", "accumulate_max", "fill", "halo_pairs",
           "migrate", "exchange",
           "active_patches", "assign", "imbalance", "morton_order", "SerialComm", "world",
           "is_parallel", "allreduce_max", "max_and_patch_sum", "ordered_sum", "ranks_on_this_node",
           "deal_from_root"]
