"""The velocity field a body starts with, at its seeds: uniform + affine + spin + vibration
mode (:func:`_initial_velocity`), and APIC's ``C_p`` of it (:func:`_initial_affine`).
Elementwise, so any subset of the points gets the same bits."""
from __future__ import annotations

import math

import numpy as np


def body_centre(body) -> np.ndarray:
    """What a body spins about and its affine field is measured from: a box's middle, a disk's
    or sphere's centre, any other shape's bounding box's middle (an annulus: its centre; a plate
    with a hole: the plate's; a cylinder: its mid-point)."""
    if body.shape == "box":
        return 0.5 * (np.asarray(body.min, float) + np.asarray(body.max, float))
    if body.shape in ("disk", "sphere"):
        return np.asarray(body.center, float)
    lo, hi = body.bounds()
    return 0.5 * (np.asarray(lo, float) + np.asarray(hi, float))


def _initial_velocity(d: int, body, pts: np.ndarray) -> np.ndarray:
    """A body's initial velocity at ``pts``: uniform + affine + spin + vibration mode."""
    vel = np.tile(np.asarray(body.velocity, float), (len(pts), 1))
    centre = body_centre(body)
    if body.velocity_gradient is not None:  # affine: v += L·(x − c)
        L = np.asarray(body.velocity_gradient, float)
        for i in range(d):  # elementwise, not BLAS: the same bits for any subset of the points
            for j in range(d):
                vel[:, i] += L[i, j] * (pts[:, j] - centre[j])
    omega = body.angular_velocity
    if omega is not None:  # rigid spin about the body's centre: v += ω × (x − c)
        r = pts - centre
        if d == 2:
            vel += float(omega) * np.stack([-r[:, 1], r[:, 0]], axis=1)
        else:
            vel += np.cross(np.asarray(omega, float), r)
    vib = body.vibration
    if vib:
        ax = vib.axis
        length = body.max[ax] - body.min[ax]
        beta = (2 * vib.mode - 1) * math.pi / (2 * length)
        vel[:, ax] += vib.amplitude * np.sin(beta * (pts[:, ax] - body.min[ax]))
    return vel


def _initial_affine(d: int, body, pts: np.ndarray) -> np.ndarray:
    """APIC's ``C_p`` at the start: the gradient of :func:`_initial_velocity` at ``pts``, so the
    particles carry the whole initial field (a spinning body its spin: ``C = ω×``)."""
    C = np.zeros((len(pts), d, d))
    if body.velocity_gradient is not None:
        C += np.asarray(body.velocity_gradient, float)
    omega = body.angular_velocity
    if omega is not None and d == 2:
        C[:, 0, 1] -= float(omega)
        C[:, 1, 0] += float(omega)
    elif omega is not None:
        w = np.asarray(omega, float)
        C += np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    vib = body.vibration
    if vib:
        ax = vib.axis
        length = body.max[ax] - body.min[ax]
        beta = (2 * vib.mode - 1) * math.pi / (2 * length)
        C[:, ax, ax] += vib.amplitude * beta * np.cos(beta * (pts[:, ax] - body.min[ax]))
    return C
