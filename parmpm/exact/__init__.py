"""Exact solutions parmpm is verified against (pure numpy)."""
