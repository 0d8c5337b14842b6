#!/usr/bin/env bash
# The closed-loop campaigns (README: Closed-loop campaign): planner + flight simulator per scenario on the Dask
# engine, in a mean wind up to 20 kt drawn per scenario (known to the planner).
#  1. thesis size: 200 random scenarios of 2-8 aircraft (the open-loop campaigns' traffic, seed 2026), 2 kt gusts,
#     30 m radar noise;
#  2. terminal area: 200 random scenarios of 2-8 aircraft (mal-traffic --profile tma), the same disturbances;
#  3. thesis size, the first 100 scenarios flown by BlueSky (optional extra 'bluesky'; steady wind only), 30 m noise;
#  4. thesis size, the first 100 scenarios with no gusts and no noise: flown as planned without replanning?
#  5. ten aircraft, thesis size: 24 random scenarios, 2 kt gusts, 30 m noise (the replan latency at 10 aircraft).
# Usage: benchmarks/closed_loop_campaign.sh [OUT_ROOT]   (default /tmp; about 10 + 15 + 15 + 5 + 3 min on 2 cores)
set -euo pipefail
root="${1:-/tmp}"
bin="$(dirname "$0")/../.venv/bin"
campaign() { "$bin/mal-campaign" "$@" --workers 2 --no-progress --closed-loop --wind-kt-max 20; }
"$bin/mal-traffic" --count 200 --aircraft 2-8 --seed 2026 --layout mixed --landing-times mixed --out "$root/cl-traffic"
"$bin/mal-traffic" --count 100 --aircraft 2-8 --seed 2026 --layout mixed --landing-times mixed --out "$root/cl100"
"$bin/mal-traffic" --count 200 --aircraft 2-8 --seed 17 --layout mixed --landing-times mixed --profile tma \
  --out "$root/tma200-traffic"
"$bin/mal-traffic" --count 24 --aircraft 10 --seed 2026 --layout mixed --landing-times mixed --out "$root/cl10-traffic"
campaign "$root/cl-traffic" --out "$root/cl200" --timeout-s 900 --gust-kt 2 --noise-m 30
campaign "$root/tma200-traffic" --out "$root/cl-tma200" --timeout-s 1800 --gust-kt 2 --noise-m 30
campaign "$root/cl100" --out "$root/cl100-bluesky" --timeout-s 900 --gust-kt 0 --noise-m 30 --simulator bluesky
campaign "$root/cl100" --out "$root/cl100-calm" --timeout-s 900 --gust-kt 0 --noise-m 0
campaign "$root/cl10-traffic" --out "$root/cl10" --timeout-s 1500 --gust-kt 2 --noise-m 30
