#!/usr/bin/env bash
# The reference traffic campaign (README: Campaigns): 60 random arrival scenarios of 2-8 aircraft, both
# layouts, free and fixed landing times, planned with the default plan options on a local Dask cluster.
# Usage: benchmarks/reference_campaign.sh [OUT_ROOT]   (default /tmp; about 25 min on 2 cores)
set -euo pipefail
root="${1:-/tmp}"
bin="$(dirname "$0")/../.venv/bin"
"$bin/mal-traffic" --count 60 --aircraft 2-8 --seed 1 --layout mixed --landing-times mixed --out "$root/ref-traffic"
"$bin/mal-campaign" "$root"/ref-traffic/*.yaml --out "$root/ref-campaign" --workers 2 --timeout-s 180
