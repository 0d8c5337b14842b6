#!/usr/bin/env bash
# Issue 32: real-size traffic flown in closed loop with the fallback (holds) and the safety net
# (docs/closed-loop.md, "Safe when planning is late or fails"). Terminal-area traffic (mal-traffic --profile tma:
# 45 nm, 3 nm separation, restricted areas) of 10, 15 and 20 aircraft, a mean wind up to 20 kt drawn per scenario,
# 2 kt gusts, 30 m radar noise; then the 10-aircraft set with a slow planner (every replan 30 s late) and a failing
# one (every other replan fails).
# Usage: benchmarks/safety_net_campaign.sh [OUT_ROOT] [COUNT]   (default /tmp, 6 per size; on 2 cores about
# 2-5 min per 10-15-aircraft scenario and 2-40 min per 20-aircraft one: replans of 20 aircraft that run out of
# time are retried with up to 224 s while the aircraft hold)
set -euo pipefail
root="${1:-/tmp}"
count="${2:-6}"
bin="$(dirname "$0")/../.venv/bin"
campaign() { "$bin/mal-campaign" "$@" --workers 2 --no-progress --closed-loop --wind-kt-max 20 --gust-kt 2 \
  --noise-m 30 --timeout-s 2400; }
for n in 10 15 20; do
  "$bin/mal-traffic" --count "$count" --aircraft "$n" --seed "32$n" --profile tma --out "$root/sn-traffic-$n"
  campaign "$root/sn-traffic-$n" --out "$root/sn-$n"
done
campaign "$root/sn-traffic-10" --out "$root/sn-10-slow" --extra-plan-delay-s 30
campaign "$root/sn-traffic-10" --out "$root/sn-10-fail" --fail-every 2
