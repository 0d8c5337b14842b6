#!/usr/bin/env bash
# The "Dependable planning" campaign (README: Campaigns): 200 random arrival scenarios of 2-8 aircraft, both
# layouts, fixed and free landing times, default plan options, a 240 s planning limit per scenario.
# Usage: benchmarks/dependable_campaign.sh [OUT_ROOT]   (default /tmp; about 27 min on 2 cores)
set -euo pipefail
root="${1:-/tmp}"
bin="$(dirname "$0")/../.venv/bin"
"$bin/mal-traffic" --count 200 --aircraft 2-8 --seed 2026 --layout mixed --landing-times mixed --out "$root/c10-traffic"
"$bin/mal-campaign" "$root/c10-traffic" --out "$root/c10" --workers 2 --timeout-s 300 --plan-time-limit-s 240
