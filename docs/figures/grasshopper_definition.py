"""A schematic of the Grasshopper definition the Hops server serves: docs/figures/grasshopper_definition.png.

Every component, input and output drawn is taken from the server's own
descriptions (what ``GET /`` answers, :meth:`shellform.hops.HopsApp.listing`),
so the picture follows the code. Each Hops component is drawn with its path,
its inputs wired from the Grasshopper source that typically feeds that type
(a number slider showing the default, a panel, a curve or mesh parameter...)
and its outputs wired to a preview or a panel. Inputs without a default are
drawn dashed: connect them when used.

    python docs/figures/grasshopper_definition.py [--out PATH]

Every text drawn that names a component, an input or an output carries a
``gid`` (``component:<name>``, ``input:<component>:<name>``,
``output:<component>:<name>``) so that a test can check the picture against
the server.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import FancyBboxPatch  # noqa: E402

OUT = Path(__file__).with_suffix(".png")
URL = "http://127.0.0.1:5000"
#: height of one input or output row [in]
ROW = 0.27
#: x positions [in]: sources, component, sinks
SOURCE_X, SOURCE_W = 0.0, 2.6
COMPONENT_X, COMPONENT_W = 3.4, 3.2
SINK_X, SINK_W = 7.4, 1.9
WIDTH = SINK_X + SINK_W + 0.1
#: the Grasshopper source that typically feeds an input of each type
SOURCES = {"Number": "Number Slider", "Integer": "Integer Slider", "Boolean": "Boolean Toggle", "Text": "Panel",
           "Curve": "Curve", "Mesh": "Mesh", "Point": "Point", "Vector": "Vector XYZ", "Line": "Line"}
#: where an output of each type typically goes
SINKS = {"Line": "Custom Preview", "Mesh": "Custom Preview", "Curve": "Custom Preview", "Point": "Point Preview",
         "Vector": "Vector Display", "Number": "Panel", "Integer": "Panel", "Boolean": "Panel", "Text": "Panel"}
COLOURS = {"component": "#c9c9c9", "source": "#e8eef6", "sink": "#eef6e8", "wire": "#555555"}


def server_listing() -> list[dict]:
    """The components as the server describes them (``GET /``)."""
    from shellform.hops import HopsApp

    app = HopsApp()
    try:
        return app.listing()
    finally:
        app.close()


def _source_label(p: dict) -> str:
    label = SOURCES.get(p["ParamType"], p["ParamType"])
    if p["AtMost"] > 1:
        label += " (list)"
    if "Default" in p:
        default = p["Default"]
        shown = ", ".join(map(_shown, default)) if isinstance(default, list) else _shown(default)
        label += f"  \"{shown}\"" if p["ParamType"] == "Text" else f"  {shown}"
    return label


def _shown(value) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _box(ax, x, y, w, h, colour, dashed=False, round_=0.04):
    ax.add_patch(FancyBboxPatch((x, y - h / 2), w, h, boxstyle=f"round,pad=0,rounding_size={round_}",
                                facecolor=colour, edgecolor="#333333", linewidth=0.7,
                                linestyle=(0, (3, 2)) if dashed else "-"))


def _wire(ax, x0, y0, x1, y1, dashed=False):
    # a Grasshopper wire: a horizontal S-curve
    import numpy as np

    t = np.linspace(0.0, 1.0, 30)
    s = 3 * t**2 - 2 * t**3
    ax.plot(x0 + (x1 - x0) * t, y0 + (y1 - y0) * s, color=COLOURS["wire"], linewidth=0.8,
            linestyle=(0, (3, 2)) if dashed else "-")


def draw_component(ax, c: dict, top: float) -> float:
    """One Hops component with its sources and sinks, from ``top`` down; returns the height used [in]."""
    inputs, outputs = c["Inputs"], c["Outputs"]
    rows = max(len(inputs), len(outputs))
    head = 0.55
    height = head + rows * ROW + 0.15
    cx, cy = COMPONENT_X, top - height / 2
    _box(ax, cx, cy, COMPONENT_W, height, COLOURS["component"], round_=0.1)
    ax.text(cx + COMPONENT_W / 2, top - 0.17, c["Name"], ha="center", va="center", fontsize=10, weight="bold",
            gid=f"component:{c['Name']}")
    ax.text(cx + COMPONENT_W / 2, top - 0.4, f"Hops  {URL}{c['Uri']}", ha="center", va="center", fontsize=6.5,
            family="monospace")
    first = top - head - ROW / 2
    for k, p in enumerate(inputs):
        y = first - k * ROW
        optional = p["AtLeast"] == 0 and "Default" not in p
        ax.text(cx + 0.08, y, p["Name"], ha="left", va="center", fontsize=7, gid=f"input:{c['Name']}:{p['Name']}")
        _box(ax, SOURCE_X, y, SOURCE_W, ROW * 0.8, COLOURS["source"], dashed=optional)
        ax.text(SOURCE_X + 0.08, y, _source_label(p), ha="left", va="center", fontsize=6.5,
                color="#666666" if optional else "black")
        _wire(ax, SOURCE_X + SOURCE_W, y, cx, y, dashed=optional)
    for k, p in enumerate(outputs):
        y = first - k * ROW
        ax.text(cx + COMPONENT_W - 0.08, y, p["Name"], ha="right", va="center", fontsize=7,
                gid=f"output:{c['Name']}:{p['Name']}")
        _box(ax, SINK_X, y, SINK_W, ROW * 0.8, COLOURS["sink"])
        ax.text(SINK_X + 0.08, y, SINKS.get(p["ParamType"], "Panel"), ha="left", va="center", fontsize=6.5)
        _wire(ax, cx + COMPONENT_W, y, SINK_X, y)
    return height


def draw(listing: list[dict]):
    """The figure of all components, one below the other."""
    gap = 0.35
    heights = [0.55 + max(len(c["Inputs"]), len(c["Outputs"])) * ROW + 0.15 for c in listing]
    total = sum(heights) + gap * (len(listing) + 1) + 0.3
    fig = plt.figure(figsize=(WIDTH, total))
    ax = fig.add_axes([0, 0, 1, 1])
    ax.set_xlim(-0.05, WIDTH - 0.05)
    ax.set_ylim(0, total)
    ax.axis("off")
    ax.text(WIDTH / 2, total - 0.2, "shellform serve: the Hops components (schematic of the definition; dashed: "
            "connect when used)", ha="center", va="center", fontsize=8, style="italic")
    top = total - 0.3 - gap
    for c, h in zip(listing, heights):
        draw_component(ax, c, top)
        top -= h + gap
    return fig


def drawn_names(fig) -> set[str]:
    """The ``gid`` of every text that names a component, an input or an output."""
    return {t.get_gid() for t in fig.findobj(matplotlib.text.Text) if t.get_gid()}


def main(argv=None):
    """Draw the definition and write it; returns the figure (closed) and the path written."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    fig = draw(server_listing())
    fig.savefig(args.out, dpi=110)
    plt.close(fig)
    return fig, args.out


if __name__ == "__main__":
    print(main()[1])
