#!/usr/bin/env bash
# Issue 32: real-size traffic flown in closed loop with the fallback (holds) and the safety net
# (docs/closed-loop.md, "Safe when planning is late or fails"). Terminal-area traffic (mal-traffic --profile tma:
# 45 nm, 3 nm separation, restricted areas) of 10, 15 and 20 aircraft, a mean wind up to 20 kt drawn per scenario,
# 2 kt gusts, 30 m radar noise; each also with a slow planner (every replan 30 s late) and a failing one (every
# other replan fails).
# Usage: benchmarks/safety_net_campaign.sh [OUT_ROOT] [COUNT]   (default /tmp, 50 per size, the issue's count; on
# 2 cores 50 scenarios of 10 aircraft take about 20 minutes per campaign, 15 aircraft about 6 min per scenario and
# 20 aircraft 2-40 min: replans of 20 aircraft that run out of time are retried with up to 224 s while the aircraft
# hold; a campaign interrupted resumes where it stopped)
set -euo pipefail
root="${1:-/tmp}"
count="${2:-50}"
bin="$(dirname "$0")/../.venv/bin"
campaign() { "$bin/mal-campaign" "$@" --workers 2 --no-progress --closed-loop --wind-kt-max 20 --gust-kt 2 \
  --noise-m 30 --timeout-s 2400; }
traffic() { "$bin/mal-traffic" --count "$count" --aircraft "$1" --seed "32$1" --profile tma --out "$root/sn-traffic-$1"; }
# the 10-aircraft set first, with a normal, a slow and a failing planner (about an hour); then 15 and 20 (hours),
# replanning what changed (--replan-what-changed, as their published numbers were run)
traffic 10
campaign "$root/sn-traffic-10" --out "$root/sn-10"
campaign "$root/sn-traffic-10" --out "$root/sn-10-slow" --extra-plan-delay-s 30
campaign "$root/sn-traffic-10" --out "$root/sn-10-fail" --fail-every 2
for n in 15 20; do
  traffic "$n"
  campaign "$root/sn-traffic-$n" --out "$root/sn-$n" --replan-what-changed
  campaign "$root/sn-traffic-$n" --out "$root/sn-$n-slow" --replan-what-changed --extra-plan-delay-s 30
  campaign "$root/sn-traffic-$n" --out "$root/sn-$n-fail" --replan-what-changed --fail-every 2
done
