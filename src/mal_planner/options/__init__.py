"""Every option declared once (:mod:`.table`), its checks and spellings (:mod:`.option`, :mod:`.arguments`), and
the pipeline's :class:`PlanOptions` built from option values by one mapping (:mod:`.plan`)."""

from mal_planner.options.arguments import (
    add_arguments,
    campaign_defaults,
    check_values,
    from_campaign,
    to_campaign,
    values_from_args,
)
from mal_planner.options.option import INT64_MAX, Option
from mal_planner.options.plan import PlanOptions, build_plan_options, resolve_flown, scenario_for, tracking_margins
from mal_planner.options.table import (
    BY_NAME,
    DEFAULTS,
    NODE_BY_NAME,
    NODE_OPTIONS,
    PLAN_OPTIONS,
    SERVICE_TIME_LIMIT_S,
)

__all__ = ["BY_NAME", "DEFAULTS", "INT64_MAX", "NODE_BY_NAME", "NODE_OPTIONS", "PLAN_OPTIONS", "SERVICE_TIME_LIMIT_S",
           "Option", "PlanOptions", "add_arguments", "build_plan_options", "campaign_defaults", "check_values",
           "from_campaign", "resolve_flown", "scenario_for", "to_campaign", "tracking_margins", "values_from_args"]
