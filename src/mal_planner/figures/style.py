"""The one style of every figure (plans and campaign summaries): colours, fonts, sizes, saving.

Only :func:`apply_style` and :func:`save` import matplotlib; colours are plain hex strings that plotly
uses too, so aircraft ``k`` has the same colour in the PNGs and in ``plan.html``.
"""

from __future__ import annotations

import colorsys
from pathlib import Path
from typing import Any

DPI = 110
"""Resolution of saved PNGs (the README's copies use 100)."""
FONT_SIZE = 9.0
WIDTH_IN = 7.5
"""Width of a full-width figure (inches): fits an A4 text block at 100 %."""

# Qualitative palettes: matplotlib's tab10, then the rest of tab20 (the light shades), then tab20b.
_TAB10 = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
          "#17becf"]
_TAB20_LIGHT = ["#aec7e8", "#ffbb78", "#98df8a", "#ff9896", "#c5b0d5", "#c49c94", "#f7b6d2", "#c7c7c7", "#dbdb8d",
                "#9edae5"]
_TAB20B = ["#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#5254a3", "#8ca252", "#bd9e39", "#ad494a",
           "#a55194"]
PALETTE: tuple[str, ...] = tuple(_TAB10 + _TAB20_LIGHT + _TAB20B)

REQUIRED_COLOR = "#d62728"
"""Limits and the required separation."""
OBSTACLE_COLOR = "#4a5a6a"
GATE_COLOR = "#e6a100"
RUNWAY_COLOR = "#000000"
PHASE_BAND_COLOR = "#000000"
PHASE_BAND_ALPHA = 0.045

MARKERS = {"start": "o", "gate": "D", "land": "v"}
"""Event markers shared by every view."""


def aircraft_colors(n: int) -> list[str]:
    """``n`` distinct colours (hex): tab10 up to 10, tab20/tab20b up to 30, then golden-angle hues."""
    if n <= len(PALETTE):
        return list(PALETTE[:n])
    extra = []
    for k in range(n - len(PALETTE)):
        hue = (k * 0.618033988749895) % 1.0
        light, sat = (0.35, 0.75) if k % 2 else (0.55, 0.65)
        r, g, b = colorsys.hls_to_rgb(hue, light, sat)
        extra.append(f"#{int(r * 255):02x}{int(g * 255):02x}{int(b * 255):02x}")
    return list(PALETTE) + extra


def pair_colors(n: int) -> list[str]:
    """``n`` colours for pairs of aircraft, dark (closest pair) to light, unlike any aircraft colour."""
    out = []
    for k in range(n):
        f = k / max(n - 1, 1)
        r, g, b = colorsys.hls_to_rgb(0.83 - 0.55 * f, 0.25 + 0.35 * f, 0.85)
        out.append(f"#{int(r * 255):02x}{int(g * 255):02x}{int(b * 255):02x}")
    return out


def color_map(callsigns: list[str]) -> dict[str, str]:
    """Callsign -> colour, in the given order (use the landing order, so colours are stable per plan)."""
    return dict(zip(callsigns, aircraft_colors(len(callsigns)), strict=True))


def legend_columns(n: int, per_column: int = 12) -> int:
    """Columns of a legend of ``n`` entries so that it stays shorter than ``per_column`` rows."""
    return max(1, -(-n // per_column))


def legend_width(labels: list[str], ncol: int = 1, fontsize: float = FONT_SIZE - 1) -> float:
    """Estimated width (inches) of a frameless legend with these labels in ``ncol`` columns.

    Figures reserve it beside the axes instead of saving with a tight bounding box, which would draw
    every figure twice.
    """
    em = fontsize / 72.0
    column = (max((len(t) for t in labels), default=0) * 0.6 + 2.0 + 0.8 + 1.0) * em
    return ncol * column + 0.6 * em


def apply_style() -> None:
    """Select the Agg backend and set the team's rcParams (idempotent)."""
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.rcParams.update({
        "font.size": FONT_SIZE,
        "axes.titlesize": FONT_SIZE + 1,
        "axes.titleweight": "bold",
        "axes.labelsize": FONT_SIZE,
        "legend.fontsize": FONT_SIZE - 1,
        "legend.frameon": False,
        "xtick.labelsize": FONT_SIZE - 1,
        "ytick.labelsize": FONT_SIZE - 1,
        "axes.grid": True,
        "grid.alpha": 0.3,
        "grid.linewidth": 0.5,
        "axes.spines.top": False,
        "axes.spines.right": False,
        "lines.linewidth": 1.4,
        "figure.dpi": DPI,
        "savefig.dpi": DPI,
        "savefig.bbox": "standard",
        "image.cmap": "viridis",
    })


def save(fig: Any, path: str | Path, dpi: int | None = None) -> Path:
    """Save ``fig`` as PNG (the team's dpi; the figure's own size and layout) and close it; return the path."""
    import matplotlib.pyplot as plt

    path = Path(path)
    fig.savefig(path, dpi=dpi or DPI)
    plt.close(fig)
    return path
