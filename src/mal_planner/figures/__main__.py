"""``python -m mal_planner.figures PLAN_JSON [--out DIR] [--figures ...]`` (see :mod:`.cli`)."""

import sys

from mal_planner.figures.cli import main

sys.exit(main())
