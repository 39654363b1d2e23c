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
        from matplotlib.collections import PolyCollection
        from matplotlib.figure import Figure
    except ImportError:
        logger.warning("matplotlib is not installed: no figure written to %s", path)
        return None

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    stretch = np.asarray(stretch, dtype=float).ravel()
    n = stretch.size
    x = np.asarray(x, dtype=float).reshape(n, -1)
    finite = stretch[np.isfinite(stretch)]
    vmin, vmax = (finite.min(), finite.max()) if finite.size else (0.0, 1.0)
    if vmax <= vmin:
        vmin, vmax = vmin - 0.5e-3 * max(abs(vmin), 1.0), vmax + 0.5e-3 * max(abs(vmax), 1.0)

    fig = Figure(figsize=(6.4, 4.8) if dim != 1 else (6.4, 3.6), dpi=150)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    labels = "xyz"
    if dim == 1:
        order = np.argsort(x[:, 0])
        ax.plot(x[order, 0], stretch[order], "-", color="0.6", lw=1)
        mappable = ax.scatter(x[:, 0], stretch, c=stretch, s=12, cmap="viridis", vmin=vmin, vmax=vmax)
        ax.set_xlabel("x")
        ax.set_ylabel("axial stretch")
    elif dim == 2 and corners is not None:
        polys = np.asarray(corners, dtype=float).reshape(n, -1, 2)
        coll = PolyCollection(polys, array=stretch, cmap="viridis", edgecolors="k", linewidths=0.2)
        coll.set_clim(vmin, vmax)
        ax.add_collection(coll)
        lo, hi = polys.reshape(-1, 2).min(axis=0), polys.reshape(-1, 2).max(axis=0)
        pad = 0.02 * max(float(np.max(hi - lo)), 1e-12)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.set_xlabel("x")
        ax.set_ylabel("y")
        mappable = coll
    else:
        if dim >= 3:
            extent = np.ptp(x, axis=0) if n else np.zeros(x.shape[1])
            a, b = sorted(np.argsort(-extent, kind="stable")[:2])
        else:
            a, b = 0, 1
        size = max(1.0, min(20.0, 4000.0 / max(n, 1)))
        mappable = ax.scatter(x[:, a], x[:, b], c=stretch, s=size, cmap="viridis", vmin=vmin, vmax=vmax)
        ax.set_aspect("equal")
        ax.set_xlabel(labels[a])
        ax.set_ylabel(labels[b])
    fig.colorbar(mappable, ax=ax, label="axial stretch")
    if title:
        ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, format="png", bbox_inches="tight")
    return path
