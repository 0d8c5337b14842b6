"""Regenerate the README's figures in docs/figures/ from a real plan (never edit them by hand).

    python scripts/make_docs_figures.py                          # plans scenarios/five_aircraft.yaml (~40 s)
    python scripts/make_docs_figures.py --plan out/five_aircraft/plan.json   # re-renders a saved plan

Writes overview.png, states.png, separation.png and controls.png at 100 dpi, and plan_html.png, a
screenshot of plan.html in headless Chromium when /usr/bin/chromium exists.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
from pathlib import Path

from mal_planner.figures import static, style
from mal_planner.figures.data import plan_view
from mal_planner.figures.interactive import write_html

DOCS_DPI = 100
CHROMIUM = Path("/usr/bin/chromium")


def plan_document(scenario: Path) -> dict:
    from mal_planner.pipeline import plan
    from mal_planner.report import result_to_dict
    from mal_planner.scenario import load_scenario

    return result_to_dict(plan(load_scenario(scenario)))


def screenshot_html(doc: dict, png: Path) -> bool:
    """plan.html as rendered by headless Chromium (WebGL on SwiftShader), 1200 x 760."""
    if not CHROMIUM.exists():
        return False
    with tempfile.TemporaryDirectory() as tmp:
        view = plan_view(doc)
        t = round(0.3 * max(a.trajectory.t[-1] for a in view.aircraft))  # aircraft mid-flight
        jump = (f"var gd = document.getElementById('{{plot_id}}'); Plotly.animate(gd, ['{t:.1f}'], "
                "{mode: 'immediate', frame: {duration: 0, redraw: true}, transition: {duration: 0}});")
        page = write_html(view, Path(tmp) / "plan.html", post_script=jump)
        subprocess.run([str(CHROMIUM), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                        "--no-first-run", "--disable-background-networking", "--disable-component-update",
                        "--disable-sync", f"--user-data-dir={tmp}/profile", "--use-angle=swiftshader",
                        "--enable-unsafe-swiftshader", "--virtual-time-budget=5000", "--hide-scrollbars",
                        "--window-size=1200,760", f"--screenshot={png}", page.as_uri()],
                       check=True, capture_output=True, timeout=120)
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", type=Path, default=Path("scenarios/five_aircraft.yaml"))
    parser.add_argument("--plan", type=Path, default=None, help="render this plan.json instead of planning")
    parser.add_argument("--out", type=Path, default=Path("docs/figures"))
    args = parser.parse_args()
    doc = json.loads(args.plan.read_text(encoding="utf-8")) if args.plan else plan_document(args.scenario)
    args.out.mkdir(parents=True, exist_ok=True)
    view = plan_view(doc)
    colors = style.color_map(view.callsigns)
    seps = view.separations()
    figures = {"overview": static.figure_overview(view, colors, seps), "states": static.figure_states(view, colors),
               "separation": static.figure_separation(view, colors, seps),
               "controls": static.figure_controls(view, colors)}
    for name, fig in figures.items():
        print(style.save(fig, args.out / f"{name}.png", dpi=DOCS_DPI))
    if screenshot_html(doc, args.out / "plan_html.png"):
        print(args.out / "plan_html.png")
    total = sum(p.stat().st_size for p in args.out.glob("*.png"))
    print(f"{total / 1e6:.2f} MB in {args.out}/")


if __name__ == "__main__":
    main()
