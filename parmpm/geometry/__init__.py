"""Geometry of bodies: primitives, their placement and inside tests (pure numpy)."""
