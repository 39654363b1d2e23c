"""PNG figures of the particle state (matplotlib, imported lazily; optional dependency).

The figure is drawn with matplotlib's object API on an Agg canvas (no pyplot, no global backend
switch), so it works headless and from inside other programs.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

logger = logging.getLogger(__name__)

__all__ = ["plot_particles"]


def plot_particles(path, x, stretch, dim: int, corners=None, title: str = ""):
    """Draw the particles coloured by axial stretch and save a PNG at ``path``.

    * 1D: stretch against position (line through the particles sorted by position, plus dots);
    * 2D: the CPDI domains as polygons (``corners`` (N, 4, 2), in order around the domain) when
      given, else a scatter of the particle centres;
    * 3D: a scatter projected on the plane of the two axes with the largest extent (x–y when the
      cloud is equant).

    Returns the path written, or None (with a warning) when matplotlib is not installed.
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        logger.warning("matplotlib is not installed: no figure written to %s", path)
        return None

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    stretch = np.asarray(stretch, dtype=float).ravel()
    n = stretch.size
    x = np.asarray(x, dtype=float).reshape(n, -1)
    clim = _colour_range(stretch)

    fig = Figure(figsize=(6.4, 4.8) if dim != 1 else (6.4, 3.6), dpi=150)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    if dim == 1:
        mappable = _draw_line(ax, x, stretch, clim)
    elif dim == 2 and corners is not None:
        mappable = _draw_domains(ax, corners, stretch, clim)
    else:
        mappable = _draw_points(ax, x, stretch, clim, dim)
    fig.colorbar(mappable, ax=ax, label="axial stretch")
    if title:
        ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, format="png", bbox_inches="tight")
    return path


def _colour_range(stretch: np.ndarray) -> tuple[float, float]:
    """The colour scale: the finite values' range, widened when it is a single value."""
    finite = stretch[np.isfinite(stretch)]
    vmin, vmax = (finite.min(), finite.max()) if finite.size else (0.0, 1.0)
    if vmax <= vmin:
        vmin, vmax = vmin - 0.5e-3 * max(abs(vmin), 1.0), vmax + 0.5e-3 * max(abs(vmax), 1.0)
    return vmin, vmax


def _draw_line(ax, x, stretch, clim):
    """1D: stretch against position, a line through the particles and a dot on each."""
    order = np.argsort(x[:, 0])
    ax.plot(x[order, 0], stretch[order], "-", color="0.6", lw=1)
    mappable = ax.scatter(x[:, 0], stretch, c=stretch, s=12, cmap="viridis", vmin=clim[0],
                          vmax=clim[1])
    ax.set_xlabel("x")
    ax.set_ylabel("axial stretch")
    return mappable


def _draw_domains(ax, corners, stretch, clim):
    """2D with domains: each particle's domain as a polygon."""
    from matplotlib.collections import PolyCollection

    polys = np.asarray(corners, dtype=float).reshape(stretch.size, -1, 2)
    coll = PolyCollection(polys, array=stretch, cmap="viridis", edgecolors="k", linewidths=0.2)
    coll.set_clim(*clim)
    ax.add_collection(coll)
    lo, hi = polys.reshape(-1, 2).min(axis=0), polys.reshape(-1, 2).max(axis=0)
    pad = 0.02 * max(float(np.max(hi - lo)), 1e-12)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    return coll


def _draw_points(ax, x, stretch, clim, dim: int):
    """2D without domains, or 3D: the particle centres (3D: projected on the plane of the two
    axes with the largest extent), dots sized by their number."""
    n = stretch.size
    if dim >= 3:
        extent = np.ptp(x, axis=0) if n else np.zeros(x.shape[1])
        a, b = sorted(np.argsort(-extent, kind="stable")[:2])
    else:
        a, b = 0, 1
    size = max(1.0, min(20.0, 4000.0 / max(n, 1)))
    mappable = ax.scatter(x[:, a], x[:, b], c=stretch, s=size, cmap="viridis", vmin=clim[0],
                          vmax=clim[1])
    ax.set_aspect("equal")
    ax.set_xlabel("xyz"[a])
    ax.set_ylabel("xyz"[b])
    return mappable
