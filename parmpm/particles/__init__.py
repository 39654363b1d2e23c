"""Particles: the structure-of-arrays store, its canonical order, and seeding bodies into it."""
