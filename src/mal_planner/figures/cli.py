"""``mal-figures PLAN_JSON [--out DIR] [--figures all|png|html]``: (re-)render the figures of a saved plan.

Also what the ROS node runs in a background process after each plan (``python -m mal_planner.figures``);
with ``--follow`` it renders again while plan.json changed during rendering, so the figures end up
matching the newest plan without the node ever waiting for them.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

from mal_planner.figures import FIGURE_CHOICES, render, want


def _stamp(path: Path) -> tuple[int, int]:
    st = path.stat()
    return st.st_mtime_ns, st.st_size


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="mal-figures", description="Render the figures of a saved plan.json: "
                                     "PNGs (overview.png, ...) and the interactive plan.html.")
    parser.add_argument("plan", type=Path, help="plan.json written by mal-plan or the planner node")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default: the plan's folder)")
    parser.add_argument("--figures", choices=FIGURE_CHOICES, default="all", help="what to write (default: all)")
    parser.add_argument("--follow", action="store_true",
                        help="render again while the plan file changed during rendering (used by the node)")
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname).1s %(name)s: %(message)s")
    out_dir = args.out or args.plan.parent
    while True:
        try:
            stamp = _stamp(args.plan)
            doc = json.loads(args.plan.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            print(f"mal-figures: error: {args.plan}: cannot read the plan ({exc})", file=sys.stderr)
            return 2
        t0 = time.perf_counter()
        try:
            written = render(doc, out_dir, want(args.figures))
        except (KeyError, TypeError, ValueError) as exc:
            print(f"mal-figures: error: {args.plan}: not a usable plan.json ({type(exc).__name__}: {exc})",
                  file=sys.stderr)
            return 2
        if not args.quiet:
            print(f"wrote {len(written)} figures to {out_dir}/ in {time.perf_counter() - t0:.2f} s")
        try:
            if not args.follow or _stamp(args.plan) == stamp:
                return 0
        except OSError:
            return 0


if __name__ == "__main__":
    sys.exit(main())
