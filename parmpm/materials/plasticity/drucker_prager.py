"""Drucker–Prager plasticity in principal Hencky space: the granular workhorse (Drucker & Prager
1952; de Souza Neto, Perić & Owen 2008, §8.3 and ch. 14).

Sign convention everywhere: **tension positive**. ``p = tr τ / 3`` (negative in compression),
``s = τ − p I``, ``√J2 = |s| / √2``. Perfectly plastic, cohesion ``c`` constant:

* yield function ``f = √J2 + η p − ξ c`` (a cone opening towards compression, apex at
  ``p_apex = ξ c / η``), flow potential ``g = √J2 + η̄ p`` (non-associated: ``η̄`` from the
  dilatancy angle ψ ≤ φ; ``η̄ = η`` associated);
* a tension cut-off ``p ≤ p_t`` with ``0 ≤ p_t ≤ p_apex`` (associated: purely volumetric
  flow). It is what makes the return to the apex exact for ``η̄ < η``: a non-associated cone
  alone has no volumetric flow to carry a hydrostatically stretched state back to the apex, and
  the apex is the corner of the cone and the cut-off (Koiter's rule, two multipliers).

:func:`drucker_prager_constants` turns (φ, ψ, c) and a Mohr–Coulomb matching into the
kernel's scalars (and refuses bad values); :func:`dp_return` maps the principal trial elastic
log strains to the updated ones; :func:`dp_dissipation` is the step's plastic work
``τ_{n+1} : Δε_p`` for the energy ledger; :func:`free_volume` is the optional volume
correction's shift of the trial (``volume_correction = true``). docs/concepts/drucker-prager.md derives it.
"""
import math

from parmpm.core.errors import SceneError
from parmpm.core.jit import helper_kernel
from parmpm.materials.plasticity.hencky import kirchhoff_principal
from parmpm.materials.plasticity.inertial import inertial_cone
from parmpm.materials.plasticity.spectral import from_principal, trial_log_strains

#: :func:`dp_return`'s region codes (the apex is the cone/cut-off corner when p_t = p_apex)
ELASTIC, CONE, CUTOFF, APEX = 0, 1, 2, 3
MATCHINGS = ("plane_strain", "outer", "inner")


def _eta_xi(angle, matching):
    """``(η, ξ)`` of an angle (radians) under a Mohr–Coulomb matching."""
    if matching == "plane_strain":  # de Souza Neto et al. (2008) ch. 6; Bui et al. (2008)
        t = math.tan(angle)
        root = math.sqrt(9.0 + 12.0 * t * t)
        return 3.0 * t / root, 3.0 / root
    s = math.sin(angle)
    den = math.sqrt(3.0) * (3.0 - s if matching == "outer" else 3.0 + s)
    return 6.0 * s / den, 6.0 * math.cos(angle) / den


def drucker_prager_constants(phi, psi, c, matching="plane_strain", tension_cutoff=None,
                             where="drucker_prager"):
    """``(η, ξ, η̄, p_t)`` of friction angle ``phi`` and dilatancy ``psi`` (degrees), cohesion
    ``c`` and a Mohr–Coulomb ``matching``:

    * ``"plane_strain"``: ``η = 3 tan φ / √(9 + 12 tan²φ)``, ``ξ = 3 / √(9 + 12 tan²φ)`` —
      the cone inscribed in Mohr–Coulomb's hexagon, whose plane-strain limit state with
      associated flow (ψ = φ) is Mohr–Coulomb's (de Souza Neto et al. 2008, ch. 6; the
      constants of Bui et al. 2008; with ψ < φ the plane-strain limit is weaker, see the docs);
    * ``"outer"``: ``η = 6 sin φ / (√3 (3 − sin φ))``, ``ξ = 6 cos φ / (√3 (3 − sin φ))`` —
      touches Mohr–Coulomb on its compressive meridian (triaxial compression), circumscribes it;
    * ``"inner"``: the same with ``3 + sin φ`` — touches on the tensile meridian (outside
      Mohr–Coulomb between the meridians, inside on the compressive one: not the inscribed cone).

    ``η̄`` is ``η``'s formula at ψ. ``p_t`` (same units as ``c``) defaults to the apex
    ``ξ c / η`` (``inf`` for φ = 0: the von Mises-like cylinder has no apex); a given value must
    lie in ``[0, ξ c / η]``. Bad values raise :class:`SceneError` naming ``where``.
    """
    if matching not in MATCHINGS:
        raise SceneError(f"{where}: matching {matching!r} is not one of {', '.join(MATCHINGS)}")
    if not 0.0 <= phi < 90.0:
        raise SceneError(f"{where}: friction angle {phi} deg is outside [0, 90)")
    if not 0.0 <= psi <= phi:
        raise SceneError(f"{where}: dilatancy angle {psi} deg is outside [0, phi = {phi}]")
    if not c >= 0.0 or math.isinf(c):
        raise SceneError(f"{where}: cohesion {c} must be finite and >= 0")
    if phi == 0.0 and c == 0.0:
        raise SceneError(f"{where}: phi = 0 and c = 0 leave no strength at all")
    eta, xi = _eta_xi(math.radians(phi), matching)
    eta_bar = _eta_xi(math.radians(psi), matching)[0]
    apex = xi * c / eta if eta > 0.0 else math.inf
    if tension_cutoff is None:
        return eta, xi, eta_bar, apex
    if not 0.0 <= tension_cutoff <= apex:
        raise SceneError(f"{where}: tension cut-off {tension_cutoff} is outside [0, apex "
                         f"xi c / eta = {apex:.6g}]")
    return eta, xi, eta_bar, float(tension_cutoff)


#: a plastic volume ``ln J_p`` at or below this is taken as none: the round-off between ``ln det F``
#: and the trial's trace on a particle that never dilated (:func:`free_volume`)
FREE_VOLUME_MIN = 1e-12


@helper_kernel
def free_volume(ln_J, ev):
    """The volume correction's shift of the trial's trace ``ev = tr ε*`` (Tampubolon et al.
    2017): the particle's plastic volume ``ln J_p = ln J − ev`` when it is positive, else 0.
    Added to every principal trial strain as a third of it, it measures the trial's volume from
    the initial one, ``ln J``: a particle dilated at the cut-off (or by dilatancy) is loose grains
    that compact back free of stress, and press only once denser than they started (the
    disconnected state of Dunatunga & Kamrin 2015). docs/concepts/drucker-prager.md."""
    v = ln_J - ev
    return v if v > FREE_VOLUME_MIN else 0.0


@helper_kernel
def dp_yield(tau, eta, xi, c):
    """``f = √J2 + η p − ξ c`` of principal Kirchhoff stresses ``tau`` (3,), tension positive."""
    p = (tau[0] + tau[1] + tau[2]) / 3.0
    ss = 0.0
    for a in range(3):
        ss += (tau[a] - p) * (tau[a] - p)
    return math.sqrt(0.5 * ss) + eta * p - xi * c


@helper_kernel
def _set_state(eps_tr, K, G, p, scale, eps_out, tau_out):
    """The state with mean stress ``p`` and the trial deviator scaled by ``scale`` (``eps_out``
    may be ``eps_tr``: each entry is read before it is written)."""
    ev = eps_tr[0] + eps_tr[1] + eps_tr[2]
    for a in range(3):
        e = scale * (eps_tr[a] - ev / 3.0)
        eps_out[a] = e + p / (3.0 * K)
        tau_out[a] = p + 2.0 * G * e


@helper_kernel
def dp_return_invariants(ev, ee, K, G, eta, xi, eta_bar, c, p_t, eta2, i0, a):
    """:func:`dp_return` on the trial's invariants: ``ev = tr ε*`` and ``ee = |dev ε*|²`` of the
    trial elastic log strain. ``i0 > 0`` turns on the μ(I) rheology (:mod:`.inertial`: the cone's
    slope rises from ``eta`` to ``eta2``; ``a = d √ρ_s / Δt``) for a compressed trial; ``i0 = 0``
    is the rate-independent cone. Returns ``(p, scale, Δγ, Δγ_t, region)``: the updated mean stress
    and the factor the trial deviator is scaled by (``ε = scale dev ε* + p/(3K) I``), the
    multipliers and the region. Isotropy makes every return one of these two numbers, so the
    principal axes are not needed (the series path of :mod:`.update` uses this directly)."""
    p_tr = K * ev
    q_tr = G * math.sqrt(2.0 * ee)  # √J2 of s* = 2G dev ε*
    f_tr = q_tr + eta * p_tr - xi * c
    if f_tr <= 0.0 and p_tr <= p_t:
        return p_tr, 1.0, 0.0, 0.0, ELASTIC
    if f_tr > 0.0:
        dg = f_tr / (G + K * eta * eta_bar)
        if i0 > 0.0 and a > 0.0 and p_tr < 0.0:  # p < 0 all along: the static cone's return is accepted
            dg = inertial_cone(q_tr, p_tr, K, G, eta, xi, eta_bar, c, eta2, i0, a, dg)
        p = p_tr - K * eta_bar * dg
        q = q_tr - G * dg
        if p <= p_t and q >= 0.0:
            return p, q / q_tr, dg, 0.0, CONE
    q_t = max(xi * c - eta * p_t, 0.0)  # the cone's √J2 at the cut-off (0: the apex)
    if q_tr < q_t:
        return p_t, 1.0, 0.0, (p_tr - p_t) / K, CUTOFF
    dg = (q_tr - q_t) / G
    return p_t, q_t / q_tr if q_tr > 0.0 else 0.0, dg, (p_tr - p_t) / K - eta_bar * dg, APEX


@helper_kernel
def dp_return(eps_tr, K, G, eta, xi, eta_bar, c, p_t, eta2, i0, a, eps_out, tau_out):
    """Return map of the principal trial elastic log strains ``eps_tr`` (3,): writes the updated
    ones ``eps_out`` and the principal Kirchhoff stresses ``tau_out``; returns
    ``(Δγ, Δγ_t, region)``, the multipliers of the cone's potential and of the cut-off, so that
    ``Δε_p = eps_tr − eps_out = Δγ (s / (2√J2) + η̄/3 I) + Δγ_t I/3``.

    Closed forms (perfect plasticity; ``q = √J2``, trial values ``q*``, ``p*``;
    :func:`dp_return_invariants`):

    * cone: ``Δγ = f* / (G + K η η̄)``, ``q = q* − G Δγ``, ``p = p* − K η̄ Δγ``, accepted when
      ``p ≤ p_t``;
    * cut-off: ``p = p_t``, ``s = s*``, ``Δγ_t = (p* − p_t) / K``, accepted when
      ``q* + η p_t − ξ c ≤ 0``;
    * corner (the apex when ``p_t = ξ c / η``): ``p = p_t``, ``q = ξ c − η p_t``,
      ``Δγ = (q* − q) / G``, ``Δγ_t = (p* − p_t) / K − η̄ Δγ`` (both ≥ 0 whenever the cone
      return overshoots ``p_t`` and the cut-off return leaves the cone: no third case).

    With μ(I) (``i0 > 0``) the cone's ``Δγ`` is :func:`.inertial.inertial_cone`'s instead.
    """
    ev = eps_tr[0] + eps_tr[1] + eps_tr[2]
    ee = 0.0
    for k in range(3):
        e = eps_tr[k] - ev / 3.0
        ee += e * e
    p, scale, dg, dgt, region = dp_return_invariants(ev, ee, K, G, eta, xi, eta_bar, c, p_t,
                                                     eta2, i0, a)
    if region == ELASTIC:
        for k in range(3):
            eps_out[k] = eps_tr[k]
        kirchhoff_principal(eps_out, K, G, tau_out)
    else:
        _set_state(eps_tr, K, G, p, scale, eps_out, tau_out)
    return dg, dgt, region


@helper_kernel
def dp_dissipation(eps_tr, eps, tau):
    """The step's plastic work per unit reference volume, ``τ_{n+1} : Δε_p`` with
    ``Δε_p = eps_tr − eps`` (coaxial principal values): ≥ 0 for ``0 ≤ p_t`` and ``η̄ ≤ η``."""
    w = 0.0
    for a in range(3):
        w += tau[a] * (eps_tr[a] - eps[a])
    return w


@helper_kernel
def dp_update(dF, be, K, G, eta, xi, eta_bar, c, p_t, eta2, i0, a, tau, M, V, w, e, t):
    """One particle's step, as :func:`parmpm.materials.plasticity.j2.j2_update`: ``b_e`` (3, 3)
    updated in place by the increment ``dF`` (3, 3), the Kirchhoff stress ``tau`` (3, 3)
    written. Scratch: ``M``, ``V`` (3, 3), ``w``, ``e``, ``t`` (3,). Returns ``(Δε̄p, plastic
    work per unit reference volume)``, ``Δε̄p = √(2/3) |dev Δε_p|`` the von Mises equivalent of
    the step's plastic log strain (what J2's ε̄p is, so one snapshot field serves both)."""
    trial_log_strains(dF, be, M, V, w)  # b_e^tr = ΔF b_e ΔFᵀ: axes, ½ ln λ
    dp_return(w, K, G, eta, xi, eta_bar, c, p_t, eta2, i0, a, e, t)
    work = dp_dissipation(w, e, t)
    dl = dp_equivalent(w, e)
    from_principal(t, V, tau)
    for A in range(3):
        w[A] = math.exp(2.0 * e[A])
    from_principal(w, V, be)
    return dl, work


@helper_kernel
def dp_equivalent(eps_tr, eps):
    """``√(2/3) |dev Δε_p|`` of the step's plastic log strain ``Δε_p = eps_tr − eps``
    (principal values): the increment of the equivalent plastic strain."""
    dv = (eps_tr[0] - eps[0] + eps_tr[1] - eps[1] + eps_tr[2] - eps[2]) / 3.0
    dd = 0.0
    for A in range(3):
        x = eps_tr[A] - eps[A] - dv
        dd += x * x
    return math.sqrt(2.0 / 3.0 * dd)
