#!/usr/bin/env bash
# The closed-loop campaigns (README: Closed-loop campaign): planner + flight simulator per scenario on the Dask
# engine, in a mean wind up to 20 kt (drawn per scenario) with 2 kt gusts and 30 m radar noise.
#  1. thesis size: 200 random scenarios of 2-8 aircraft (the open-loop campaigns' traffic, seed 2026);
#  2. thesis size, wind known and no gusts or noise: how often the flown path stays within 0.05 nm of the plan
#     without a replan;
#  3. terminal area: 100 random scenarios of 2-8 aircraft (mal-traffic --profile tma).
# Usage: benchmarks/closed_loop_campaign.sh [OUT_ROOT]   (default /tmp; about 20 + 15 + 30 min on 2 cores)
set -euo pipefail
root="${1:-/tmp}"
bin="$(dirname "$0")/../.venv/bin"
"$bin/mal-traffic" --count 200 --aircraft 2-8 --seed 2026 --layout mixed --landing-times mixed --out "$root/cl-traffic"
"$bin/mal-campaign" "$root/cl-traffic" --out "$root/cl200" --workers 2 --timeout-s 900 --no-progress \
  --closed-loop --wind-kt-max 20 --gust-kt 2 --noise-m 30
"$bin/mal-campaign" "$root/cl-traffic" --out "$root/cl200-calm" --workers 2 --timeout-s 900 --no-progress \
  --closed-loop --wind-kt-max 20 --gust-kt 0 --noise-m 0
"$bin/mal-traffic" --count 100 --aircraft 2-8 --seed 17 --layout mixed --landing-times mixed --profile tma \
  --out "$root/tma100-traffic"
"$bin/mal-campaign" "$root/tma100-traffic" --out "$root/cl-tma100" --workers 2 --timeout-s 1800 --no-progress \
  --closed-loop --wind-kt-max 20 --gust-kt 2 --noise-m 30
