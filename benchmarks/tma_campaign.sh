#!/usr/bin/env bash
# The terminal-area campaign (README: Real terminal-area scale): 200 random arrival scenarios of 4-20 aircraft at
# real size (mal-traffic --profile tma), wall and no-fly-zone layouts, fixed and free landing times, default plan
# options, 300 s per scenario. Then the tally of the sequential strategy's recoveries.
# Usage: benchmarks/tma_campaign.sh [OUT_ROOT]   (default /tmp; about 75 min on 2 cores)
set -euo pipefail
root="${1:-/tmp}"
here="$(dirname "$0")"
bin="$here/../.venv/bin"
"$bin/mal-traffic" --count 200 --aircraft 4-20 --seed 16 --layout mixed --landing-times mixed --profile tma \
  --out "$root/tma200-traffic"
"$bin/mal-campaign" "$root/tma200-traffic" --out "$root/tma200" --workers 2 --timeout-s 300 --no-progress
"$bin/python" "$here/recoveries.py" "$root/tma200"
