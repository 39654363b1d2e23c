"""What a snapshot holds: this rank's particle fields, for the XDMF series.

One function of the run (a :class:`parmpm.driver.simulation.Simulation`), local: every rank computes
the fields of its own particles and hands them to :meth:`parmpm.driver.run_files.RunFiles.write_snapshot`,
which gathers them only within the rank's writer group (:mod:`parmpm.io.xdmf`, "Parts") to the
group's lead, who writes them; the datasets carry the units and descriptions of
:func:`field_info`.

The domains (``output.domains``) are the corners :func:`parmpm.output.domains.domain_corners` gives:
the domains the interpolation uses, i.e. CPDI's ``R = F·r0`` after the ``l_cr`` cap (CPDI2: its
tracked corners after the cap), the
cpGIMP/uGIMP boxes, or MPM's nominal box. A frozen CPDI domain (:mod:`parmpm.shapes.freeze`)
needs nothing more: the freeze resets ``r0`` after every deformation update so that ``F·r0`` is
the frozen domain, which is what every kernel and ``domain_corners`` read.
"""
from __future__ import annotations

import numpy as np

from parmpm.output import domains
from parmpm.driver.measures import axial_stretch
from parmpm.materials.plasticity.state import STATE_EPSP, STATE_WORK, plastic_volume


def field_info(dim: int, plastic: bool = False) -> dict[str, dict[str, str]]:
    """Units and meaning of every field a run's snapshot holds (in 2D, per metre of thickness;
    in 1D, per square metre of cross-section); ``plastic``: a run with a plastic material."""
    vol = {1: "m", 2: "m^2", 3: "m^3"}[dim]
    return {**_elastic_info(vol), **(PLASTIC_INFO if plastic else {})}


#: the fields of a run with a plastic material (0 on its elastic particles)
PLASTIC_INFO = {
    "plastic_strain": {"units": "1", "description": "equivalent plastic strain (von Mises "
                       "equivalent of the accumulated plastic log strain)"},
    "plastic_volume": {"units": "1", "description": "plastic volume change ln J_p = "
                       "-1/2 ln det C_p^-1 (0: none; > 0 dilation)"},
    "plastic_work": {"units": "J/m^3", "description": "plastic work done per unit reference "
                     "volume so far"},
}


def _elastic_info(vol: str) -> dict[str, dict[str, str]]:
    return {
        "x": {"units": "m", "description": "position"},
        "velocity": {"units": "m/s", "description": "velocity"},
        "displacement": {"units": "m", "description": "displacement x - x0 from the initial position"},
        "stress": {"units": "Pa", "description": "Cauchy stress, row-major"},
        "F": {"units": "1", "description": "deformation gradient, row-major"},
        "volume": {"units": vol, "description": "current volume vol0 * det F"},
        "mass": {"units": "kg", "description": "mass"},
        "stretch": {"units": "1", "description": "stretch |F e_a| along the metrics' axis a"},
        "damage": {"units": "1", "description": "damage (0: intact, 1: failed)"},
        "rank": {"units": "1", "description": "the MPI rank that held the particle"},
        "gid": {"units": "1", "description": "global particle id (never changes)"},
        "domains": {"units": "m", "description": "corners of the particle's domain as the "
                    "interpolation sees it (CPDI after the l_cr cap), XDMF/VTK node order"},
    }


def snapshot_fields(sim) -> dict:
    """The fields of this rank's particles for one snapshot (no communication): ``x``, the
    fields of :func:`field_info`, ``domains`` (with ``output.domains``) and ``step`` (the run's
    step, an int)."""
    s, P = sim.state, sim.particles
    d = s.dim
    fields = {"x": P.x, "velocity": P.v, "displacement": P.x - P.x0, "stress": P.stress, "F": P.F,
              "volume": P.vol0 * np.linalg.det(P.F) if P.n else np.zeros(0),
              "mass": P.mass, "stretch": axial_stretch(s), "damage": P.damage,
              "rank": np.full(P.n, s.rank, np.int32), "gid": P.gid.astype(np.int64)}
    if "plastic" in P.optional:
        S = P.plastic
        fields["plastic_strain"] = S[:, STATE_EPSP].copy()
        fields["plastic_volume"] = plastic_volume(S)
        fields["plastic_work"] = S[:, STATE_WORK].copy()
    if sim.spec.output.domains:
        fields["domains"] = domains.domain_corners(d, s.disc.method, s.disc.lcr, P.x, P.F,
                                                   P.r0, P.lh0, P.corners)
    fields["step"] = int(sim.nstep)
    return fields
