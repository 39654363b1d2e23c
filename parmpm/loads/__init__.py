"""Loads and forcings applied to bodies (body forces, the manufactured solution)."""
