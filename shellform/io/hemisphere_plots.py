"""Pictures of the hemispherical gridshell: 3D views, side views and force-displacement curves."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..gridshell.configurations import central_profiles
from ..gridshell.hemisphere import HemisphereModel
from .table import save_figure


def _figure(*args, **kw):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.figure(*args, **kw), plt


def _save(fig, plt, path, dpi: int) -> None:
    """Lay the figure out, write it and close it (also when writing fails)."""
    fig.tight_layout()
    try:
        save_figure(fig, path, dpi=dpi)
    finally:
        plt.close(fig)


def draw_gridshell(ax, model: HemisphereModel, q: np.ndarray, highlight: bool = True) -> None:
    """All rods of state ``q`` on a 3D axis; the two central rods in colour."""
    R = model.radius
    for k, (rod, line) in enumerate(zip(model.net.rods, model.rod_polylines(q))):
        central = highlight and rod.index == 0
        colour = ("tab:red" if rod.family == "u" else "tab:blue") if central else "0.35"
        ax.plot(line[:, 0] / R, line[:, 1] / R, line[:, 2] / R, color=colour, lw=1.6 if central else 0.8)
    ax.set_xlim(-1.3, 1.3)
    ax.set_ylim(-1.3, 1.3)
    ax.set_zlim(-1.3, 1.3)
    try:
        ax.set_box_aspect((1, 1, 0.75), zoom=1.5)
    except TypeError:  # matplotlib < 3.6 has no zoom
        ax.set_box_aspect((1, 1, 0.75))
    ax.set_zlim(-1.1, 1.1)
    ax.set_axis_off()


def draw_profiles(ax, model: HemisphereModel, q: np.ndarray) -> None:
    """Side views of the two central rods: ``(x, z)`` of the u rod, ``(y, z)`` of the v rod."""
    R = model.radius
    for prof, colour, name in zip(central_profiles(model, q), ("tab:red", "tab:blue"), ("u0 (x, z)", "v0 (y, z)")):
        ax.plot(prof[:, 0] / R, prof[:, 1] / R, color=colour, lw=1.4, label=name)
    ax.axhline(0.0, color="0.7", lw=0.6)
    ax.set_aspect("equal")
    ax.set_xlim(-1.5, 1.5)
    ax.set_ylim(-1.3, 1.3)


def render_states(path, model: HemisphereModel, states: Sequence[tuple[str, np.ndarray]], dpi: int = 110) -> None:
    """One column per state: 3D view above, central-rod side views below, titled."""
    k = len(states)
    fig, plt = _figure(figsize=(2.8 * k, 5.6))
    grid = fig.add_gridspec(2, k, height_ratios=(1.5, 1.0))
    for i, (title, q) in enumerate(states):
        ax = fig.add_subplot(grid[0, i], projection="3d")
        ax.view_init(elev=22, azim=-60)
        draw_gridshell(ax, model, q)
        ax.set_title(title, fontsize=9)
        ax2 = fig.add_subplot(grid[1, i])
        draw_profiles(ax2, model, q)
        if i == 0:
            ax2.legend(fontsize=7, loc="lower left")
        ax2.tick_params(labelsize=7)
    _save(fig, plt, path, dpi)


def plot_curves(path, curves: Sequence[dict], title: str = "", published: Sequence[float] = (),
                tolerance: float = 0.1, dpi: int = 110) -> None:
    """Force-displacement curves ``-sum(Fz) R^2/EI`` against ``dD/R``.

    ``curves``: dicts with ``x``, ``y``, ``segment`` (stable segments drawn
    separately, a snap as a dotted vertical jump), ``label`` and the computed
    ``thresholds``. Published thresholds are shaded with their tolerance.
    """
    fig, plt = _figure(figsize=(6.0, 4.0))
    ax = fig.gca()
    for t in published:
        ax.axvspan(t - tolerance, t + tolerance, color="0.9", zorder=0)
        ax.axvline(t, color="0.6", lw=0.8, ls="--", zorder=0)
    for c in curves:
        x, y, seg = np.asarray(c["x"]), np.asarray(c["y"]), np.asarray(c["segment"])
        colour = None
        for s in np.unique(seg):
            m = seg == s
            line = ax.plot(x[m], y[m], color=colour, lw=1.3, label=c.get("label") if s == seg[0] else None)
            colour = line[0].get_color()
        # snaps: vertical jumps between the segments
        for s in np.unique(seg)[1:]:
            i = int(np.flatnonzero(seg == s)[0])
            ax.plot([x[i - 1], x[i]], [y[i - 1], y[i]], color=colour, lw=0.8, ls=":")
        for t in c.get("thresholds", ()):
            ax.axvline(t, color=colour, lw=0.5, alpha=0.5)
    ax.axhline(0.0, color="0.5", lw=0.5)
    ax.set_xlabel(r"$\Delta D / R$")
    ax.set_ylabel(r"$-\sum F_z\, R^2 / EI$")
    ax.set_xlim(0, 2.0)
    if title:
        ax.set_title(title)
    ax.legend(fontsize=8)
    _save(fig, plt, path, dpi)
