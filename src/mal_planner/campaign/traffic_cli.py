"""``mal-traffic``: write K random arrival-traffic scenario files (see :mod:`mal_planner.campaign.traffic`)."""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from mal_planner.campaign.traffic import (
    WAKE_MODES,
    WAKE_SHARES,
    WAKE_STRATEGY,
    WAKE_TABLE,
    TrafficError,
    TrafficSpec,
    generate_one,
)
from mal_planner.profiles import PROFILES

PROG = "mal-traffic"
MAX_AIRCRAFT = 50


def aircraft_range(text: str) -> tuple[int, int]:
    match = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", text)
    if not match:
        raise argparse.ArgumentTypeError(f"expected N or N1-N2, got {text!r}")
    low = int(match.group(1))
    high = int(match.group(2) or low)
    if not 1 <= low <= high <= MAX_AIRCRAFT:
        raise argparse.ArgumentTypeError(f"need 1 <= N1 <= N2 <= {MAX_AIRCRAFT}, got {text!r}")
    return low, high


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG, description="Generate random arrival-traffic scenario files (arrival streams towards one runway, "
                               "through a wall with a hole or around no-fly zones). The same seed gives the same "
                               "files.")
    parser.add_argument("--count", type=int, required=True, help="number of scenario files K")
    parser.add_argument("--aircraft", type=aircraft_range, required=True, help="aircraft per scenario: N or N1-N2")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--layout", choices=["wall", "no-fly-zones", "mixed"], default="mixed",
                        help="obstacles: a wall with a hole, random no-fly zones, or either at random "
                             "(default: %(default)s)")
    parser.add_argument("--landing-times", choices=["free", "fixed", "mixed"], default="free",
                        help="free: no landing times in the files; fixed: a feasible-looking schedule; mixed: either "
                             "at random (default: %(default)s)")
    parser.add_argument("--airspace-nm", type=float, nargs=2, metavar=("X", "Y"), default=None,
                        help="fixed airspace extents: x in [-X/2, X/2], y from the profile's lower edge to Y "
                             "(default: grows with N)")
    parser.add_argument("--profile", choices=sorted(PROFILES), default="thesis",
                        help="the numbers of the traffic: thesis (the thesis's 6-nm box, 0.25 nm separation, 45 deg "
                             "bank) or tma (a real terminal area: 45 nm across, 3 nm separation, 90 s landing "
                             "spacing, 30 deg bank, glide paths) (default: %(default)s)")
    shares = ", ".join(f"{c} {100 * share:g} %%" for c, share in WAKE_SHARES.items())  # %% : argparse formats help
    parser.add_argument("--flyable", action="store_true",
                        help="airliners: every aircraft flies the airspeed model (point_mass_airspeed) under the "
                             "default arrival procedures (procedures: {aircraft_type: A320}); the same draws")
    parser.add_argument("--wake", choices=WAKE_MODES, default="none",
                        help=f"none: no wake categories (the files as before); mixed: each aircraft draws an ICAO "
                             f"category ({shares}) and the file asks for the {WAKE_TABLE} wake minima and the "
                             f"{WAKE_STRATEGY} sequence (default: %(default)s)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.count < 1:
            raise TrafficError(f"--count: must be >= 1, got {args.count}")
        if args.seed < 0:
            raise TrafficError(f"--seed: must be >= 0, got {args.seed}")
        if args.airspace_nm is not None and (args.airspace_nm[0] < 3.0 or args.airspace_nm[1] < 4.0):
            raise TrafficError(f"--airspace-nm: need X >= 3 and Y >= 4 nm, got {args.airspace_nm}")
        if args.out.exists() and not args.out.is_dir():
            raise TrafficError(f"--out: {args.out} is not a folder")
        if args.landing_times != "free":
            try:
                from mal_planner.sequencing.timing import earliest_landing_times  # noqa: F401
            except ImportError:
                raise TrafficError("--landing-times: fixed schedules need mal_planner.sequencing.timing."
                                   "earliest_landing_times, which this installation lacks") from None
        spec = TrafficSpec(aircraft=args.aircraft, seed=args.seed, layout=args.layout,
                           landing_times=args.landing_times,
                           airspace_nm=tuple(args.airspace_nm) if args.airspace_nm else None, profile=args.profile,
                           wake=args.wake, flyable=args.flyable)
        args.out.mkdir(parents=True, exist_ok=True)
        for index in range(args.count):
            generated = generate_one(spec, index)
            (args.out / generated.file_name).write_text(generated.text, encoding="utf-8")
    except TrafficError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    print(f"{PROG}: wrote {args.count} scenario files to {args.out}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
