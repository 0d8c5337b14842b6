"""The options in each interface: command-line flags (argparse), campaign keys, and checks that name the spelling."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from mal_planner.options.option import Option
from mal_planner.options.table import BY_NAME, DEFAULTS, PLAN_OPTIONS


def check_values(values: Mapping[str, Any], spelling: Callable[[Option], str | None] = lambda o: o.name) -> str | None:
    """The first problem with ``values`` (by option name) as one line naming the option as ``spelling`` gives it
    (e.g. its flag), or None."""
    for name, value in values.items():
        option = BY_NAME[name]
        try:
            option.check(value)
        except ValueError as exc:
            return f"{spelling(option) or name}: {exc}, got {value!r}"
    return None


def add_arguments(parser: Any, names: tuple[str, ...] | None = None, flags: Mapping[str, str] | None = None,
                  defaults: Mapping[str, Any] | None = None) -> None:
    """Add the options that have a flag (``names``: only these) to an argparse parser or group; ``flags``
    renames some (e.g. the campaigns' ``--plan-time-limit-s``), ``defaults`` replaces some defaults (e.g. the
    service's time limit). Values are converted here and checked by the caller with :func:`check_values` (one
    line naming the flag, as the other errors of the command)."""
    for option in PLAN_OPTIONS:
        if option.flag is None or (names is not None and option.name not in names):
            continue
        flag = (flags or {}).get(option.name, option.flag)
        if option.kind is bool:
            parser.add_argument(flag, dest=option.name, action="store_const", const=option.flag_sets,
                                default=option.default, help=option.flag_help or option.help)
            continue
        default = (defaults or {}).get(option.name, option.default)
        default_text = "" if default is None else " (default: %(default)s)"
        parser.add_argument(flag, dest=option.name, type=option.kind, default=default,
                            choices=option.choices or None, metavar=option.metavar,
                            help=option.help + (f" [{option.unit}]" if option.unit else "") + default_text)


def values_from_args(args: Any, names: tuple[str, ...] | None = None) -> dict[str, Any]:
    """The option values an argparse namespace holds (those with a flag; ``names``: only these)."""
    return {o.name: getattr(args, o.name) for o in PLAN_OPTIONS
            if o.flag is not None and (names is None or o.name in names) and hasattr(args, o.name)}



def campaign_defaults() -> dict[str, Any]:
    """The campaign's plan options (keys as in ``campaign.json``) at their defaults."""
    return to_campaign(DEFAULTS)


def to_campaign(values: Mapping[str, Any]) -> dict[str, Any]:
    """Option values by name -> the campaign's keys (those a campaign offers)."""
    return {o.campaign: (not values[o.name]) if o.campaign_inverted else values[o.name]
            for o in PLAN_OPTIONS if o.campaign is not None and o.name in values}


def from_campaign(options: Mapping[str, Any]) -> dict[str, Any]:
    """The campaign's keys -> option values by name (keys it does not know are left out)."""
    return {o.name: (not options[o.campaign]) if o.campaign_inverted else options[o.campaign]
            for o in PLAN_OPTIONS if o.campaign is not None and o.campaign in options}
