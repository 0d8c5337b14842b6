"""The plan options, declared once: ``mal-plan``'s flags, the campaigns' options and the planner node's parameters
are derived from :data:`PLAN_OPTIONS`, and so are their checks, ranges and help.

Each :class:`Option` has one value type, default, range and help, and its spelling in each interface that offers
it: a command-line flag (``mal-plan``; the campaigns use the same flags), a campaign key (as stored in
``campaign.json``) and a ROS 2 parameter of the node. Where an interface states the opposite of the value
(``--free-landing-times`` for ``fixed_landing_times: false``, ``--no-refine``, ``--initial-only``), ``flag_sets``
is the value its flag sets. :func:`build_plan_options` is the one place that turns values into
:class:`~mal_planner.pipeline.PlanOptions`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from mal_planner.landing.solve import LandingOptions
from mal_planner.verification import Tolerances

INT64_MAX = 2**63 - 1
"""The largest ROS 2 integer parameter: the upper end of an integer range without an upper bound."""


@dataclass(frozen=True)
class PlanOptions:
    initializer: str = "multi-rrt"
    """Path planner of the initializer: 'multi-rrt' or 'ompl:<planner>' (e.g. ompl:RRTConnect)."""
    seed: int | None = 0
    optimize: bool = True
    verify: bool = True
    landing: LandingOptions = field(default_factory=LandingOptions)
    tolerances: Tolerances | None = None
    """The verification's accuracy tolerances; None: the scenario's own (:meth:`Tolerances.for_scenario`)."""
    refinement_rounds: int = 3
    """Re-solves with a locally refined mesh where the verification finds a path constraint broken."""
    time_limit_s: float | None = None
    """Wall-clock limit of one whole plan, initializer included; when it runs out the best result so far is
    returned, or :class:`InitializerTimeout` raised when there is none yet (None: no limit)."""
    landed_within_turn_times: float = 0.4
    """On a replan, aircraft this close to their last planned landing leave the plan (in the scenario's turn
    times; thesis: 3 s)."""


def _known_planner(value: str) -> str | None:
    """A path planner that exists in this installation (imports the planners: ~1 s)."""
    from mal_planner.initializer.planners import known_specs

    known = known_specs()
    return None if value in known else f"no such planner (known: {', '.join(known)})"


@dataclass(frozen=True)
class Option:
    """One plan option (see the module docstring)."""

    name: str
    kind: type
    default: Any
    help: str
    lo: float | None = None
    """Inclusive lower bound (numbers)."""
    hi: float | None = None
    """Inclusive upper bound (numbers)."""
    above: float | None = None
    """Exclusive lower bound (numbers), e.g. 0 for "> 0"."""
    below: float | None = None
    """Exclusive upper bound (numbers)."""
    choices: tuple[str, ...] = ()
    validate: Callable[[Any], str | None] | None = None
    """A further check of a valid-looking value: the problem, or None."""
    none_as: Any = None
    """The value that stands for None where an interface cannot say None (a ROS parameter: 0 = no limit)."""
    flag: str | None = None
    flag_sets: Any = None
    """For a boolean flag: the value the flag sets (the opposite of the default)."""
    flag_help: str = ""
    """For a boolean flag: what setting it does (``help`` describes the option's value)."""
    campaign: str | None = None
    campaign_inverted: bool = False
    """The campaign key states the opposite (``free_landing_times`` for ``fixed_landing_times``)."""
    ros: str | None = None
    node_default: Any = None
    """The node's default where it differs (a service needs a time limit; ``mal-plan`` has none by default)."""
    unit: str = ""
    metavar: str | None = None

    def check(self, value: Any) -> Any:
        """The value, converted to the option's type; ValueError with the problem (one line, without the name)."""
        if value is None:
            if self.default is not None:
                raise ValueError("expected a value")
            return None
        if self.kind is bool:
            if not isinstance(value, bool):
                raise ValueError("expected true or false")
            return value
        if self.kind is str:
            if not isinstance(value, str):
                raise ValueError("expected a string")
            if self.choices and value not in self.choices:
                raise ValueError(f"expected one of {', '.join(self.choices)}")
        else:
            value = self._number(value)
        problem = self.validate(value) if self.validate else None
        if problem:
            raise ValueError(problem)
        return value

    def _number(self, value: Any) -> float | int:
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise ValueError("expected a finite number" if self.kind is float else "expected an integer")
        if self.kind is int and int(value) != value:
            raise ValueError("expected an integer")
        value = self.kind(value)
        fmt = "d" if self.kind is int else "g"
        for bound, ok, word in ((self.lo, lambda b: value >= b, ">="), (self.hi, lambda b: value <= b, "<="),
                                (self.above, lambda b: value > b, ">"), (self.below, lambda b: value < b, "<")):
            if bound is not None and not ok(bound):
                raise ValueError(f"must be {word} {bound:{fmt}}")
        return value

    @property
    def value_range(self) -> tuple[float, float] | None:
        """The inclusive range of a number, for a ROS parameter descriptor (an exclusive bound becomes the nearest
        representable value inside it); None for other kinds."""
        if self.kind not in (int, float):
            return None
        if self.kind is int:
            lo = self.lo if self.lo is not None else (self.above + 1 if self.above is not None else -INT64_MAX - 1)
            hi = self.hi if self.hi is not None else (self.below - 1 if self.below is not None else INT64_MAX)
            return int(lo), int(hi)
        lo = self.lo if self.lo is not None else (math.nextafter(self.above, math.inf) if self.above is not None
                                                  else -math.inf)
        if self.none_as is not None and self.none_as < lo:
            lo = self.none_as
        hi = self.hi if self.hi is not None else (math.nextafter(self.below, -math.inf) if self.below is not None
                                                  else math.inf)
        return lo, hi

    def ros_default(self) -> Any:
        """The default as a ROS parameter (which cannot be None)."""
        if self.node_default is not None:
            return self.node_default
        return self.none_as if self.default is None else self.default

    def check_ros(self, value: Any) -> Any:
        """:meth:`check` for a ROS parameter's value: ``none_as`` stands for None; returns the parameter's value."""
        if self.none_as is not None and value == self.none_as and not isinstance(value, bool):
            return type(self.none_as)(value)
        return self.check(value)


PLAN_OPTIONS: tuple[Option, ...] = (
    Option("initializer", str, "multi-rrt", "path planner of the initializer: multi-rrt (the thesis's), "
           "ompl:RRTConnect, ompl:RRT, ompl:RRTstar, ...", validate=_known_planner, flag="--initializer",
           campaign="initializer", ros="initializer"),
    Option("seed", int, 0, "random seed of the initializer; -1 draws one", lo=-1, flag="--seed", campaign="seed",
           ros="seed"),
    Option("optimize", bool, True, "run the pseudospectral optimizer (false: the initializer's paths only)",
           flag="--initial-only", flag_sets=False, flag_help="run the initializer only, no optimization",
           ros="optimize"),
    Option("verify", bool, True, "verify the optimized trajectories independently (flown controls, every minimum)",
           ros="verify"),
    Option("guess", str, "initializer", "optimizer initial guess: the initializer's paths or naive straight lines",
           choices=("initializer", "straight"), flag="--guess", campaign="guess", ros="guess"),
    Option("strategy", str, "auto", "one NLP for all aircraft (joint) or one per aircraft in landing order against "
           "the plans of those before it (sequential); auto: sequential from 4 aircraft on",
           choices=("auto", "joint", "sequential"), flag="--strategy", campaign="strategy", ros="strategy"),
    Option("fixed_landing_times", bool, True, "keep the scenario's landing times (else the optimizer chooses them, "
           "the minimum spacing from the scenario)", flag="--free-landing-times", flag_sets=False,
           flag_help="let the optimizer choose the landing times (minimum spacing from the scenario), also where "
                     "a file fixes them",
           campaign="free_landing_times", campaign_inverted=True, ros="fixed_landing_times"),
    Option("mesh_tol", float, 1e-5, "mesh error tolerance of the hp refinement", above=0.0, below=1.0,
           flag="--mesh-tol", campaign="mesh_tol", ros="mesh_tol"),
    Option("refine", bool, True, "hp mesh refinement and the verification-driven refinement (false: the initial "
           "mesh only)", flag="--no-refine", flag_sets=False,
           flag_help="solve on the initial mesh only (no hp refinement, no verification-driven refinement)",
           campaign="refine", ros="refine"),
    Option("segments", int, 4, "initial mesh segments per phase (refinement adds more where needed)", lo=1, hi=64,
           ros="segments"),
    Option("degree", int, 6, "collocation degree per segment (refinement splits dense segments instead)", lo=2,
           hi=16, ros="degree"),
    Option("nlp_tol", float, 1e-8, "IPOPT tolerance", above=0.0, below=1.0, ros="nlp_tol"),
    Option("max_nlp_iterations", int, 3000, "IPOPT iteration limit", lo=1, ros="max_nlp_iterations"),
    Option("max_mesh_iterations", int, 8, "mesh refinement iteration limit", lo=1, ros="max_mesh_iterations"),
    Option("output_dt", float, 0.25, "sample step of the published paths: no controller follows a path finer than "
           "100 Hz, a minute between samples is no path", lo=0.01, hi=60.0, unit="s", ros="output_dt"),
    Option("time_limit_s", float, None, "wall-clock limit of one whole plan, initializer included; when it runs "
           "out the best result so far is kept (a failure is reported)", above=0.0, none_as=0.0, unit="s",
           flag="--time-limit", campaign="time_limit_s", ros="planning_time_limit_s", node_default=60.0,
           metavar="S"),
)
"""Every plan option, once."""

BY_NAME: dict[str, Option] = {o.name: o for o in PLAN_OPTIONS}
DEFAULTS: dict[str, Any] = {o.name: o.default for o in PLAN_OPTIONS}


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


def build_plan_options(values: Mapping[str, Any], base: PlanOptions | None = None) -> PlanOptions:
    """PlanOptions from option values by name (the others: ``base``'s, else the defaults): the one mapping."""
    base = base or PlanOptions()
    v = {**{o.name: _current(o, base) for o in PLAN_OPTIONS}, **values}
    landing = replace(base.landing, guess=v["guess"], strategy=v["strategy"],
                      fixed_landing_times=v["fixed_landing_times"], mesh_tol=v["mesh_tol"], refine=v["refine"],
                      segments=v["segments"], degree=v["degree"], nlp_tol=v["nlp_tol"],
                      max_nlp_iterations=v["max_nlp_iterations"], max_mesh_iterations=v["max_mesh_iterations"],
                      output_dt=v["output_dt"])
    return replace(base, initializer=v["initializer"], seed=None if v["seed"] is None or v["seed"] < 0 else v["seed"],
                   optimize=v["optimize"], verify=v["verify"], landing=landing, time_limit_s=v["time_limit_s"],
                   refinement_rounds=base.refinement_rounds if v["refine"] else 0)


def _current(option: Option, base: PlanOptions) -> Any:
    """The value ``base`` has for ``option`` (e.g. ``output_dt`` None: the optimizer's own samples, as
    ``mal-plan`` and the campaigns publish them; the node sets it)."""
    holder = base.landing if hasattr(base.landing, option.name) else base
    return getattr(holder, option.name, option.default)


def add_arguments(parser: Any, names: tuple[str, ...] | None = None, flags: Mapping[str, str] | None = None) -> None:
    """Add the options that have a flag (``names``: only these) to an argparse parser or group; ``flags``
    renames some (e.g. the campaigns' ``--plan-time-limit-s``). Values are converted here and checked by the
    caller with :func:`check_values` (one line naming the flag, as the other errors of the command)."""
    for option in PLAN_OPTIONS:
        if option.flag is None or (names is not None and option.name not in names):
            continue
        flag = (flags or {}).get(option.name, option.flag)
        if option.kind is bool:
            parser.add_argument(flag, dest=option.name, action="store_const", const=option.flag_sets,
                                default=option.default, help=option.flag_help or option.help)
            continue
        default_text = "" if option.default is None else " (default: %(default)s)"
        parser.add_argument(flag, dest=option.name, type=option.kind, default=option.default,
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
