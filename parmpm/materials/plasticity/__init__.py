"""Finite-strain plasticity in the Hencky (logarithmic) framework: the multiplicative split
``F = F_e F_p``, the elastic left Cauchy–Green tensor ``b_e = F_e F_eᵀ`` carried by each particle
(3×3 in every dimension: plane strain and 1D have an out-of-plane elastic stretch of their own),
its principal logarithmic strains ``ε_A = ½ ln(eig b_e)``, the Kirchhoff stress
``τ_A = K tr ε + 2G dev ε_A`` (:mod:`.hencky`), and a return map in principal space per yield
criterion: von Mises (J2) with isotropic hardening, Drucker–Prager. Simo (1992), *Algorithms for
static and dynamic multiplicative plasticity that preserve the classical return mapping schemes
of the infinitesimal theory*, CMAME 99; de Souza Neto, Perić & Owen (2008), *Computational
Methods for Plasticity*, ch. 14. docs/concepts/plasticity.md derives what the code relies on.
"""
