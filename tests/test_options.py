"""The plan options are declared once (mal_planner.options): mal-plan, the campaigns and the node derive from it."""

from __future__ import annotations

import argparse
import math

import pytest

from mal_planner.options import (
    BY_NAME,
    DEFAULTS,
    PLAN_OPTIONS,
    PlanOptions,
    add_arguments,
    build_plan_options,
    check_values,
    from_campaign,
    to_campaign,
    values_from_args,
)


def test_every_default_passes_its_own_check() -> None:
    for option in PLAN_OPTIONS:
        assert option.check(option.default) == option.default, option.name
        assert option.check_ros(option.ros_default()) == option.ros_default(), option.name


@pytest.mark.parametrize(("name", "value", "problem"), [
    ("seed", -2, "must be >= -1"), ("degree", 1000, "must be <= 16"), ("segments", 0, "must be >= 1"),
    ("mesh_tol", 0.0, "must be > 0"), ("mesh_tol", 1.0, "must be < 1"), ("mesh_tol", math.nan, "expected a finite"),
    ("output_dt", 1e-9, "must be >= 0.01"), ("time_limit_s", -1.0, "must be > 0"), ("degree", 2.5, "an integer"),
    ("guess", "curvy", "expected one of initializer, straight"), ("refine", 1, "expected true or false"),
    ("initializer", "ompl:Nope", "no such planner (known: multi-rrt"),
])
def test_checks_name_the_problem(name: str, value: object, problem: str) -> None:
    with pytest.raises(ValueError, match=problem.replace("(", r"\(")):
        BY_NAME[name].check(value)
    assert check_values({name: value}, lambda o: o.flag or o.ros).endswith(f", got {value!r}")


def test_ranges_for_descriptors_are_inclusive_and_hold_the_ros_defaults() -> None:
    assert BY_NAME["degree"].value_range == (2, 16)
    assert BY_NAME["time_limit_s"].value_range == (0.0, math.inf)  # the node's 0 = no limit is inside
    lo, hi = BY_NAME["mesh_tol"].value_range
    assert 0.0 < lo < 1e-300 and hi < 1.0
    for option in PLAN_OPTIONS:
        if option.value_range is not None:
            lo, hi = option.value_range
            assert lo <= option.ros_default() <= hi, option.name


def test_defaults_build_the_pipelines_defaults() -> None:
    assert build_plan_options({}) == PlanOptions()
    assert build_plan_options(DEFAULTS).landing.output_dt == 0.25  # given explicitly (the node does)
    no_refine = build_plan_options({"refine": False, "fixed_landing_times": False, "strategy": "joint"})
    assert no_refine.refinement_rounds == 0 and not no_refine.landing.refine
    assert not no_refine.landing.fixed_landing_times and no_refine.landing.strategy == "joint"
    assert build_plan_options({"seed": -1}).seed is None


def test_cli_flags_come_from_the_table_and_state_the_opposite_where_named_so() -> None:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(["--no-refine", "--free-landing-times", "--initial-only", "--time-limit", "5",
                              "--strategy", "sequential"])
    values = values_from_args(args)
    assert values["refine"] is False and values["fixed_landing_times"] is False and values["optimize"] is False
    assert values["time_limit_s"] == 5.0 and values["strategy"] == "sequential"
    assert set(values) == {o.name for o in PLAN_OPTIONS if o.flag}


def test_campaign_keys_round_trip_and_the_node_offers_every_ros_option() -> None:
    from mal_planner.campaign.plan_options import CAMPAIGN_OPTIONS
    from mal_planner.campaign.plan_options import DEFAULTS as CAMPAIGN_DEFAULTS
    from mal_planner.ros.node_params import PARAMETERS, NodeParams

    values = {name: DEFAULTS[name] for name in CAMPAIGN_OPTIONS}
    assert from_campaign(to_campaign(values)) == values
    assert to_campaign({"fixed_landing_times": True}) == {"free_landing_times": False}
    assert set(CAMPAIGN_DEFAULTS) == {*to_campaign(values), "closed_loop"}
    assert {o.ros for o in PLAN_OPTIONS if o.ros} <= set(PARAMETERS)
    node = NodeParams().plan_options()
    assert node.time_limit_s == 60.0 and node.landing.output_dt == 0.25  # the node's own defaults
    assert node.landing.strategy == "auto" and node.initializer == "multi-rrt"


def test_a_tracking_error_sizes_the_margins_of_flown_plans() -> None:
    """BlueSky's A320 flying an export strays up to 0.28 nm from the plan, with nothing to replan it (CDG 12:56 flew
    2.997 nm with the closed loop's 0.072-nm threshold): ``--tracking-error`` sizes the margins to what flies them."""
    from mal_planner.options import resolve_flown
    from mal_planner.scales import Scales
    from mal_planner.scenario import load_scenario

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    values = values_from_args(parser.parse_args(["--tracking-error", "0.3"]))
    options = build_plan_options(values)
    assert options.tracking_margins and options.tracking_threshold_nm == 0.3
    scenario = load_scenario("scenarios/tma_12.yaml")
    scales = Scales.of(scenario)
    flown = resolve_flown(options, scenario).landing.margins.in_nm(scales)
    default = resolve_flown(build_plan_options({"tracking_margins": True}), scenario).landing.margins.in_nm(scales)
    assert flown.separation_nm == pytest.approx(0.6)
    assert default.separation_nm == pytest.approx(2.0 * 10.0 * scales.accuracy_nm)
    assert not build_plan_options({}).tracking_margins
