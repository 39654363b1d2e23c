"""After G2P, every particle goes to the patch (and rank) that holds its new position.

Three moves: :meth:`Migration.locate_and_send` finds each particle's new patch (or takes what
G2P found) and exchanges the rows that change rank; :meth:`Migration.regroup` sorts the rank's
rows into (patch, id) order again; :meth:`Migration.rebalance` sends whole patches to new owners
after a re-balance. Problems (a particle off the grid, one that crossed more than one patch) go
to the step's :class:`~parmpm.step.faults.StepFaults`.
"""
from __future__ import annotations

import math

import numpy as np

from decomposition import exchange, is_parallel, migrate
from parmpm.core.records import Locate
from parmpm.particles.locate import locate_patches
from parmpm.transfer.reach import fmt_vec, grid_extent


class Migration:
    """``migrated``: particles sent to another rank so far; ``located``: (first particle off the
    grid, particles that changed patch) when G2P found the new patches, else None;
    ``occupancy_changed``: whether the last regroup emptied or filled a patch."""

    def __init__(self, disc, particles, patches, faults):
        self.disc, self.P, self.patches, self.faults = disc, particles, patches, faults
        self.comm = patches.comm
        self.migrated = 0
        self.new_patch = np.zeros(0, np.int64)
        self.located = None
        self.moved = -1                     # particles that changed patch (-1: not counted)
        self.occupancy_changed = False
        self._loc, self._inv_psize = disc.layout.locator()

    def locate_record(self, inside: np.ndarray) -> Locate:
        """What G2P needs to find each particle's next patch (the new-patch buffer sized)."""
        if self.new_patch.size != self.P.n:
            self.new_patch = np.zeros(self.P.n, np.int64)
        return Locate(self._loc, self._inv_psize, self.patches.local_ids, self.new_patch, inside)

    def locate_rest(self, located, rows: np.ndarray) -> None:
        """G2P's specialised kernels found the next patches of every particle but ``rows`` (their
        ``located``: first off the grid, particles that changed patch): find those rows' here,
        so that the migration need not look at every particle again. Left to that full search
        (:attr:`located` None) when a particle left the grid: its message names the first in
        canonical order, which neither part knows alone."""
        self.located = None
        first, moved = located
        if first >= 0:
            return
        D, R, lay = self.disc, self.P.rows, self.disc.layout
        bad, more = locate_patches(D.dim, R.x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                                   lay.patches_per_axis, R.patch, self.new_patch, rows)
        if bad < 0:
            self.located = (-1, moved + more)

    def _fail(self, i: int, message: str) -> None:
        self.faults.fail(self.P.rows, i, message)

    def locate_and_send(self):
        """Find every particle's new patch and exchange the particles that change rank; returns
        what :meth:`regroup` needs (None when no particle changed patch on a single rank)."""
        D, P, ps = self.disc, self.P, self.patches
        R = P.rows  # indices here are physical rows
        lay = D.layout
        if self.new_patch.size != P.n:
            self.new_patch = np.zeros(P.n, np.int64)
        new = self.new_patch
        if self.located is not None:  # G2P did it
            bad, moved = self.located
            self.located = None
        else:
            bad, moved = locate_patches(D.dim, R.x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                                        lay.patches_per_axis, R.patch, new, P.order())
        self.moved = int(moved)
        parallel = is_parallel(self.comm)
        if bad >= 0:  # before any early return: the same on any rank count
            self._fail(bad, f"particle {R.gid[bad]} at {fmt_vec(R.x[bad])} left the grid at "
                       f"{math.hypot(*R.v[bad]):.4g} m/s ({grid_extent(D)}); enlarge grid.cells "
                       "or move grid.origin, or check what drives it (gravity, velocities)")
        if moved == 0 and not parallel:  # nothing to regroup, nothing to send
            return None, None, None
        if moved == 0:  # every particle stays in its patch, so on this rank
            keep, received = (exchange(P.raw_fields(), None, self.comm, ps.peers) if parallel
                              else (None, None))
            return new, keep, received
        return self._send(new, parallel)

    def _send(self, new: np.ndarray, parallel: bool):
        """Some particles changed patch: send those whose patch is another rank's."""
        P, ps, R = self.P, self.patches, self.P.rows
        dest = ps.rank_of[new]
        lost = dest < 0
        if np.any(lost):  # moved past a neighbour patch in one step (CFL > 1): stay, and stop
            order = P.order()
            i = int(order[np.flatnonzero(lost[order])[0]])  # the first in (patch, id) order
            self._fail(i, f"particle {R.gid[i]} at {fmt_vec(R.x[i])} moved more than one patch "
                       "in one step; reduce time.cfl")
            new[lost] = R.patch[lost]
            dest[lost] = ps.rank
        keep, received = None, None
        if parallel:
            self.migrated += int(np.count_nonzero(dest != ps.rank))
            fields = P.raw_fields()
            fields["patch"] = new
            keep, received = exchange(fields, dest, self.comm, ps.peers)
        return new, keep, received

    def regroup(self, new, keep, received) -> None:
        """Sort the particles into (patch, id) order after :meth:`locate_and_send` (merging the
        kept and received rows after an exchange); notes whether a patch became (un)occupied."""
        P, ps = self.P, self.patches
        if new is None:
            self.occupancy_changed = False
            return
        occupied_before = np.diff(P.start) > 0
        if keep is not None or received is not None:  # some left or came
            P.group_by_patch(new, ps.slot_of, ps.n_local, keep=keep, received=received)
            self.new_patch = np.zeros(0, np.int64)  # P's patch rows may lie in it now
        else:
            old = P.rows.patch
            if P.group_by_patch(new, ps.slot_of, ps.n_local, moved=self.moved):
                self.new_patch = old  # the next step's buffer (P.patch is ``new`` now)
        self.occupancy_changed = bool(np.any((np.diff(P.start) > 0) != occupied_before))

    def rebalance(self) -> None:
        """Whole patches changed owner: send their particles to the new owners."""
        P, ps = self.P, self.patches
        dest = ps.rank_of[P.patch]
        self.migrated += int(np.sum(dest != ps.rank))
        P.replace(migrate(P.fields(), dest, self.comm, None))
