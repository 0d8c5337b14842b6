"""Which sequential recovery fixed what: tallies a campaign's logs (``mal-campaign --out OUT``: OUT/logs/*.log).

The sequential strategy logs each aircraft that found no plan against the plans before it, every recovery it
tried ('another guess', 'later landing', 'give way', 'swap with previous') and whether it worked, and the joint
fallback when none did. Usage: ``python benchmarks/recoveries.py OUT [OUT ...]`` prints a Markdown table.
"""

from __future__ import annotations

import argparse
import re
from collections import Counter
from pathlib import Path

NO_PLAN = re.compile(r"sequential: (\S+) found no (?:accurate )?plan \((\w+)")
RECOVERY = re.compile(r"sequential: (\S+): recovery '([^']+)' (worked|failed)")
FALLBACK = re.compile(r"trying the next fallback")


def tally(logs: list[Path]) -> tuple[Counter, Counter, Counter, int]:
    """(tried, worked, no-plan statuses, logs where the pipeline fell back (joint NLP or further)) over ``logs``."""
    tried, worked, causes, fallbacks = Counter(), Counter(), Counter(), 0
    for log in logs:
        text = log.read_text(errors="replace")
        causes.update(m.group(2) for m in NO_PLAN.finditer(text))
        for m in RECOVERY.finditer(text):
            tried[m.group(2)] += 1
            worked[m.group(2)] += m.group(3) == "worked"
        fallbacks += bool(FALLBACK.search(text))
    return tried, worked, causes, fallbacks


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("campaigns", nargs="+", type=Path, help="campaign folders (with logs/)")
    args = parser.parse_args()
    logs = sorted(p for c in args.campaigns for p in (c / "logs").glob("*.log"))
    tried, worked, causes, fallbacks = tally(logs)
    print(f"{len(logs)} scenario logs; aircraft without a plan against the earlier ones: {sum(causes.values())} "
          f"({', '.join(f'{k} {v}' for k, v in causes.most_common())}); "
          f"fell back (joint NLP or further) in {fallbacks}\n")
    print("| recovery (in the order tried) | tried | worked |")
    print("|---|---|---|")
    for name in tried:
        print(f"| {name} | {tried[name]} | {worked[name]} |")


if __name__ == "__main__":
    main()
