"""Planned paths beside the real flown tracks: a map (longitude, latitude) and altitude against time.

    python -m mal_planner.geo.figure out/cdg_1443/plan.json data/cdg_1443_tracks.csv --out docs/figures/cdg_arrivals.png

``plan.json`` of a geodetic scenario carries lat/lon/alt_ft per sample; the tracks CSV is the one
``mal-adsb --tracks`` writes (times from the same moment).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path

import numpy as np

from mal_planner.figures.style import RUNWAY_COLOR, WIDTH_IN, apply_style, color_map, save


def read_tracks(path: str | Path) -> dict[str, dict[str, np.ndarray]]:
    """The tracks CSV by callsign: arrays t_s, lat, lon, alt_ft."""
    rows: dict[str, list[list[float]]] = {}
    with open(path, newline="", encoding="utf-8") as fh:
        for row in csv.DictReader(fh):
            rows.setdefault(row["callsign"], []).append([float(row[k]) for k in ("t_s", "lat", "lon", "alt_ft")])
    return {c: dict(zip(("t_s", "lat", "lon", "alt_ft"), np.array(v).T, strict=True)) for c, v in rows.items()}


def figure(plan: dict, tracks: dict[str, dict[str, np.ndarray]], title: str | None = None):
    """The figure (matplotlib): planned (solid) and flown (dashed) per aircraft, in the plan's landing order."""
    apply_style()
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    frame = plan["scenario"].get("geo_frame")
    if frame is None:
        raise ValueError("the plan has no geodetic frame (plan a geodetic scenario)")
    origin = frame["origin"]
    order = list(plan["landing_order"])
    colors = color_map(order)
    fig, (ax_map, ax_alt) = plt.subplots(1, 2, figsize=(WIDTH_IN * 1.35, WIDTH_IN * 0.62),
                                         gridspec_kw={"width_ratios": [1.15, 1.0]})
    by_callsign = {a["callsign"]: a for a in plan["aircraft"]}
    for callsign in order:
        tr = by_callsign[callsign]["trajectory"]
        c = colors[callsign]
        ax_map.plot(tr["lon_deg"], tr["lat_deg"], color=c, lw=1.4, label=callsign)
        ax_map.plot(tr["lon_deg"][0], tr["lat_deg"][0], "o", color=c, ms=4)
        ax_alt.plot(tr["t"], tr["alt_ft"], color=c, lw=1.4)
        if callsign in tracks:
            real = tracks[callsign]
            ax_map.plot(real["lon"], real["lat"], color=c, lw=1.0, ls=(0, (3, 2)), alpha=0.8)
            ax_alt.plot(real["t_s"], real["alt_ft"], color=c, lw=1.0, ls=(0, (3, 2)), alpha=0.8)
        ax_map.annotate(callsign, (tr["lon_deg"][0], tr["lat_deg"][0]), textcoords="offset points", xytext=(4, 3),
                        fontsize=7, color=c)
    ax_map.plot(origin["lon_deg"], origin["lat_deg"], marker=(3, 0, -frame["course_deg"]), color=RUNWAY_COLOR,
                ms=9, ls="none")
    ax_map.set_aspect(1.0 / math.cos(math.radians(origin["lat_deg"])))
    ax_map.set_xlabel("longitude (deg E)")
    ax_map.set_ylabel("latitude (deg N)")
    ax_map.grid(True, alpha=0.3)
    ax_alt.set_xlabel("time after the moment (s)")
    ax_alt.set_ylabel("altitude (ft)")
    ax_alt.grid(True, alpha=0.3)
    handles = [Line2D([], [], color="0.2", lw=1.4, label="planned"),
               Line2D([], [], color="0.2", lw=1.0, ls=(0, (3, 2)), label="flown (ADS-B)"),
               Line2D([], [], color=RUNWAY_COLOR, marker=(3, 0, -frame["course_deg"]), ls="none", label="threshold")]
    entries = handles + [Line2D([], [], color=colors[c], lw=1.4, label=c) for c in order]
    fig.legend(handles=entries, loc="lower center", ncol=min(len(entries), 6), fontsize=7)
    fig.suptitle(title or plan["scenario"]["name"])
    fig.tight_layout(rect=(0.0, 0.09, 1.0, 1.0))
    return fig


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m mal_planner.geo.figure", description=__doc__.split("\n")[0])
    p.add_argument("plan", type=Path, help="plan.json of a geodetic scenario")
    p.add_argument("tracks", type=Path, help="tracks CSV (mal-adsb --tracks)")
    p.add_argument("--out", type=Path, required=True, help="PNG to write")
    p.add_argument("--title", default=None)
    args = p.parse_args(argv)
    try:
        plan = json.loads(args.plan.read_text(encoding="utf-8"))
        fig = figure(plan, read_tracks(args.tracks), args.title)
    except (OSError, ValueError, KeyError) as exc:
        print(f"{p.prog}: error: {exc}", file=sys.stderr)
        return 2
    save(fig, args.out, dpi=100)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
