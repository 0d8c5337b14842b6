"""Arrival sequencing: the published optima of the OR-Library landing benchmark, FCFS, position shifting,
time limits and the one-line errors of infeasible windows and bad files."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from mal_planner.sequencing import SequencingInfeasible, SequencingOptions, SequencingProblem, sequence
from mal_planner.sequencing.cli import main
from mal_planner.sequencing.orlib import BUNDLED, PUBLISHED_OPTIMA, ORLibraryError, parse_airland, read_airland

OPTIMAL = SequencingOptions(strategy="optimal", time_limit_s=60.0)


def brute_force(problem: SequencingProblem) -> float:
    """The least cost over every order, each timed by an LP: an independent check for small problems."""
    from scipy.optimize import linprog

    n, best = problem.n, np.inf
    for order in itertools.permutations(range(n)):
        # variables x, a, b; x = T - a + b; x_j - x_i >= S_ij for i before j
        c = np.concatenate([np.zeros(n), problem.cost_early, problem.cost_late])
        a_eq = np.hstack([np.eye(n), np.eye(n), -np.eye(n)])
        rows, rhs = [], []
        for p, q in itertools.combinations(range(n), 2):
            i, j = order[p], order[q]
            row = np.zeros(3 * n)
            row[i], row[j] = 1.0, -1.0
            rows.append(row)
            rhs.append(-problem.separation[i, j])
        bounds = [(problem.earliest[i], problem.latest[i]) for i in range(n)] + [(0, None)] * (2 * n)
        res = linprog(c, A_ub=np.array(rows), b_ub=rhs, A_eq=a_eq, b_eq=problem.target, bounds=bounds)
        if res.status == 0:
            best = min(best, res.fun)
    return best


def random_problem(rng: np.random.Generator, n: int) -> SequencingProblem:
    target = np.sort(rng.uniform(0, 60 * n, n))
    earliest = target - rng.uniform(0, 60, n)
    latest = target + rng.uniform(200, 600, n)
    category = rng.integers(0, 3, n)
    table = np.array([[96, 157, 196], [60, 69, 131], [60, 69, 82]])  # s, heavy/medium/light-like
    separation = table[np.ix_(category, category)].astype(float)
    return SequencingProblem(tuple(f"A{k}" for k in range(n)), earliest, target, latest,
                             rng.integers(1, 4, n).astype(float), rng.integers(1, 6, n).astype(float), separation)


@pytest.mark.parametrize("name", BUNDLED)
def test_published_optima(name: str) -> None:
    problem = read_airland(name)
    result = sequence(problem, OPTIMAL)
    assert result.status == "optimal" and result.gap == 0.0
    assert result.value == pytest.approx(PUBLISHED_OPTIMA[name], abs=1e-4)
    assert problem.violations(result.times) == []
    assert [result.times[i] for i in result.order] == sorted(result.times)
    fcfs = sequence(problem, SequencingOptions(strategy="fcfs"))
    assert problem.violations(fcfs.times) == [] and fcfs.cost >= result.cost - 1e-6


def test_optimal_matches_enumeration_of_every_order() -> None:
    rng = np.random.default_rng(3)
    for _ in range(4):
        problem = random_problem(rng, 5)
        assert sequence(problem, OPTIMAL).cost == pytest.approx(brute_force(problem), abs=1e-6)


def test_narrowing_and_cuts_keep_the_optimum_of_the_plain_milp() -> None:
    """Reduced-cost narrowing, segment cuts and blocks against Beasley's MILP without them (HiGHS, no time
    limit reached): the same least cost on random problems too large to enumerate."""
    from mal_planner.sequencing.formulation import build_model, pair_relations, run_milp

    rng = np.random.default_rng(11)
    checked = 0
    while checked < 3:
        problem = random_problem(rng, 12)
        latest = problem.bounded_latest()
        fixed, free = pair_relations(problem, latest, None)
        plain = run_milp(build_model(problem, problem.earliest, latest, OPTIMAL, fixed, free), 60.0, 1e-9)
        if plain.infeasible:  # windows too tight for twelve: draw again
            continue
        assert plain.optimal and plain.times is not None
        checked += 1
        result = sequence(problem, OPTIMAL)
        assert result.status == "optimal" and problem.violations(result.times) == []
        assert result.cost == pytest.approx(problem.cost(plain.times), abs=1e-6)


def test_independent_blocks_split_where_no_separation_links() -> None:
    from mal_planner.sequencing.bounds import independent_blocks

    sep = np.full((4, 4), 60.0)
    problem = SequencingProblem(("A", "B", "C", "D"), [0, 10, 500, 530], [0, 10, 500, 530], [100, 200, 600, 700],
                                [1] * 4, [1] * 4, sep)
    assert independent_blocks(problem, problem.earliest, problem.latest) == [[0, 1], [2, 3]]
    # B may land as late as 450: 450 + 60 > 500, so C and D are linked to it
    assert independent_blocks(problem, problem.earliest, np.array([100, 450, 600, 700.0])) == [[0, 1, 2, 3]]


def test_position_shifting_keeps_every_aircraft_within_k_places() -> None:
    problem = read_airland("airland3")
    first_come = problem.first_come_order()
    costs = []
    for k in (0, 1, 2):
        result = sequence(problem, SequencingOptions(strategy="optimal", max_shift=k, time_limit_s=60.0))
        assert result.status == "optimal" and problem.violations(result.times) == []
        shift = [abs(result.order.index(i) - p) for p, i in enumerate(first_come)]
        assert max(shift) <= k
        costs.append(result.cost)
    assert all(a >= b - 1e-6 for a, b in itertools.pairwise([*costs, PUBLISHED_OPTIMA["airland3"]]))
    assert costs == pytest.approx([1730, 1380, 820])  # airland3: every shift allowed pays off


def test_makespan_objective() -> None:
    problem = read_airland("airland1")
    result = sequence(problem, SequencingOptions(strategy="optimal", objective="makespan"))
    assert problem.violations(result.times) == []
    assert result.value == pytest.approx(max(result.times))
    # nothing shorter: all must fit after the earliest landing; the optimal cost schedule lands later or equal
    assert result.value <= max(sequence(problem, OPTIMAL).times) + 1e-6


def test_time_limit_returns_best_order_with_its_gap() -> None:
    problem = read_airland("airland8")
    result = sequence(problem, SequencingOptions(strategy="optimal", time_limit_s=0.5))
    assert problem.violations(result.times) == []
    if result.status == "feasible" and result.gap is not None:  # None: nothing found in time, FCFS returned
        assert result.gap > 0
        assert result.bound is not None and result.bound <= PUBLISHED_OPTIMA["airland8"] + 1e-6
    assert result.cost >= PUBLISHED_OPTIMA["airland8"] - 1e-6


def test_infeasible_windows_name_the_aircraft() -> None:
    sep = np.array([[0.0, 60.0], [60.0, 0.0]])
    with pytest.raises(SequencingInfeasible, match=r"^B: latest landing time 10 s is before its earliest 20 s$"):
        SequencingProblem(("A", "B"), [0, 20], [0, 20], [100, 10], [1, 1], [1, 1], sep)
    squeezed = SequencingProblem(("A", "B"), [0, 0], [0, 0], [10, 10], [1, 1], [1, 1], sep)
    for strategy in ("fcfs", "optimal"):
        with pytest.raises(SequencingInfeasible) as err:
            sequence(squeezed, SequencingOptions(strategy=strategy))
        assert "\n" not in str(err.value) and ("A" in err.value.names or "B" in err.value.names)


def test_fcfs_lands_in_target_order_at_the_earliest_free_slot() -> None:
    sep = np.full((3, 3), 60.0)
    problem = SequencingProblem(("C", "A", "B"), [0, 0, 0], [100, 0, 30], [1000] * 3, [1] * 3, [1] * 3, sep)
    result = sequence(problem, SequencingOptions(strategy="fcfs"))
    assert result.order_names(problem) == ["A", "B", "C"]
    assert list(result.times) == [120.0, 0.0, 60.0]


def test_bad_files_are_one_line_errors(tmp_path: Path) -> None:
    with pytest.raises(ORLibraryError, match="2 planes need 18 numbers, found 3"):
        parse_airland("2 10 5", "x.txt")
    with pytest.raises(ORLibraryError, match="not an OR-Library landing file"):
        parse_airland("2 ten", "x.txt")
    assert main([str(tmp_path / "missing.txt")]) == 2


def test_cli_prints_cost_order_times_and_gap(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["airland1", "--time-limit", "30"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("airland1: 10 aircraft  cost 700.00  optimal  gap 0.00 %")
    assert out[1].split()[1:] == ["3", "4", "5", "6", "7", "8", "9", "1", "10", "2"]
    assert out[2].startswith("  times: 3@98 ")


def test_wake_tables_distances_and_times() -> None:
    from mal_planner.wake import RECAT_EU_DISTANCE_NM, wake_distance_nm, wake_spacing_s

    radar = 3.0
    assert wake_distance_nm("icao", "H", "L", radar) == 6.0
    assert wake_distance_nm("icao", "J", "M", radar) == 7.0
    assert wake_distance_nm("icao", "M", "H", radar) == radar  # a heavy behind a medium: radar minimum
    assert wake_distance_nm("icao", "M", "M", 2.5) == 2.5
    assert [wake_distance_nm("recat-eu", "A", f, radar) for f in "ABCDEF"] == [3, 4, 5, 5, 6, 8]
    assert [wake_distance_nm("recat-eu", "B", f, 2.5) for f in "ABCDEF"] == [2.5, 3, 4, 4, 5, 7]
    assert [wake_distance_nm("recat-eu", lead, "F", radar) for lead in "CDEF"] == [6, 5, 4, 3]
    assert len(RECAT_EU_DISTANCE_NM) == 6 + 5 + 4 + 3
    # 6 nm at 0.04 nm/s (144 kt) is 150 s; the floor wins when the table asks for less
    assert wake_spacing_s("icao", "H", "L", 0.04, radar, 90.0) == pytest.approx(150.0)
    assert wake_spacing_s("icao", "L", "H", 0.04, radar, 90.0) == 90.0
    assert wake_spacing_s("none", None, None, 0.04, radar, 90.0) == 90.0
    with pytest.raises(ValueError, match="follower category 'H' is not one of A, B"):
        wake_distance_nm("recat-eu", "A", "H", radar)


def test_scenario_wake_option_checks_the_categories() -> None:
    import yaml

    from mal_planner.scenario import ScenarioError, parse_scenario
    from mal_planner.sequencing.schedule import landing_spacing

    scenarios = Path(__file__).resolve().parents[1] / "scenarios"
    data = yaml.safe_load((scenarios / "thesis.yaml").read_text())
    plain = parse_scenario(data)
    assert plain.wake == "none"
    data["separation"] = {**data.get("separation", {}), "wake": "icao"}
    data["aircraft"][0].pop("wake_category", None)
    with pytest.raises(ScenarioError, match=r"aircraft\[0\]\.wake_category: separation.wake icao needs one of J, H"):
        parse_scenario(data)
    for ac, cat in zip(data["aircraft"], itertools.cycle("HL"), strict=False):
        ac["wake_category"] = cat
    scenario = parse_scenario(data)
    heavy, light = scenario.aircraft[0], scenario.aircraft[1]
    assert landing_spacing(scenario, heavy, light) == pytest.approx(
        max(landing_spacing(plain, plain.aircraft[0], plain.aircraft[1]), 6.0 / light.speed))
    data["separation"]["wake"] = "faa"
    with pytest.raises(ScenarioError, match="wake"):
        parse_scenario(data)


def _scenario_data(name: str = "five_aircraft.yaml") -> dict:
    import yaml

    return yaml.safe_load((Path(__file__).resolve().parents[1] / "scenarios" / name).read_text())


def test_make_schedule_goes_through_sequencing_with_the_scenario_strategy() -> None:
    """fcfs (default) lands in order of the earliest times; optimal puts the heavy that would hold the others
    back by its wake minima last, and its total delay is below first come, first served's."""
    from mal_planner.scenario import parse_scenario
    from mal_planner.sequencing.schedule import make_schedule, planned_spacing
    from mal_planner.sequencing.timing import earliest_landing_times

    data = _scenario_data()
    data["separation"]["wake"] = "icao"
    for ac, cat in zip(data["aircraft"], "HMLML", strict=True):
        ac["wake_category"] = cat
    fcfs = parse_scenario(data)
    earliest = earliest_landing_times(fcfs)
    first = make_schedule(fcfs, earliest)
    assert list(first.order) == sorted(earliest, key=earliest.get) and first.strategy == "fcfs"
    data["sequencing"] = {"strategy": "optimal", "time_limit_s": 5}
    optimal = make_schedule(parse_scenario(data), earliest)
    assert optimal.strategy == "optimal" and optimal.status == "optimal"
    assert optimal.order[-1] == "B1" and first.order[0] == "B1"  # the heavy: first come, landed last
    for schedule in (first, optimal):
        for a, b in itertools.pairwise(schedule.order):
            need = planned_spacing(fcfs, fcfs.aircraft_by_callsign(a), fcfs.aircraft_by_callsign(b))
            assert schedule.times[b] - schedule.times[a] >= need - 1e-9
    delay = {s.strategy: sum(s.delay(cs) for cs in s.order) for s in (first, optimal)}
    assert 0.0 <= delay["optimal"] < delay["fcfs"]


@pytest.mark.parametrize(("sequencing", "message"), [
    ({"strategy": "best"}, "sequencing.strategy"),
    ({"max_shift": -1}, "sequencing.max_shift"),
    ({"time_limit_s": 0}, "sequencing.time_limit_s"),
    ({"strategy": "optimal", "gap": 1}, "sequencing.gap"),
])
def test_bad_sequencing_options_are_one_line_errors(sequencing: dict, message: str) -> None:
    from mal_planner.scenario import ScenarioError, parse_scenario

    data = _scenario_data()
    data["sequencing"] = sequencing
    with pytest.raises(ScenarioError, match=message) as err:
        parse_scenario(data, "x.yaml")
    assert "\n" not in str(err.value)


def test_fixed_landing_times_closer_than_their_wake_minimum_are_refused() -> None:
    from mal_planner.errors import InfeasibleRequest
    from mal_planner.scenario import parse_scenario
    from mal_planner.sequencing.schedule import check_request

    data = _scenario_data("thesis.yaml")
    data["separation"]["wake"] = "icao"
    data["aircraft"][0]["wake_category"] = "H"  # A1 lands 15 s before the medium A2: 5 nm needs 125 s
    with pytest.raises(InfeasibleRequest, match=r"A1 and A2 land 15 s apart .* icao wake minimum H->M needs 125.0 s"):
        check_request(parse_scenario(data))


def test_mixed_wake_scenario_plans_verified_with_the_table_spacings(tmp_path: Path) -> None:
    """scenarios/wake_mixed.yaml: the optimal sequence puts the lights first and the heavies last; the plan is
    verified, and every consecutive landing of the flown plan is at least the ICAO table's distance apart at the
    follower's speed (recomputed here from the published table, not taken from the planner)."""
    import json

    from mal_planner.options import PlanOptions
    from mal_planner.pipeline import plan
    from mal_planner.report import validation_report, write_outputs
    from mal_planner.scenario import load_scenario

    icao_nm = {("H", "H"): 4.0, ("H", "M"): 5.0, ("H", "L"): 6.0, ("M", "L"): 5.0}  # Doc 4444, J not used
    scenario = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "wake_mixed.yaml")
    result = plan(scenario, PlanOptions(seed=0))
    assert result.verified, result.verification.reasons
    landed = result.landing_times()
    order = sorted(landed, key=landed.get)
    categories = [scenario.aircraft_by_callsign(cs).wake_category for cs in order]
    assert categories == ["L", "L", "M", "H", "H"]
    for a, b in itertools.pairwise(order):
        lead, follow = scenario.aircraft_by_callsign(a), scenario.aircraft_by_callsign(b)
        nm = max(icao_nm.get((lead.wake_category, follow.wake_category), 0.0), scenario.separation_nm)
        assert landed[b] - landed[a] >= max(nm / follow.speed, scenario.landing_spacing_s), (a, b)
    assert landed[order[-1]] - landed[order[-2]] >= 100.0  # heavy behind heavy: 4 nm at 0.04 nm/s
    write_outputs(result, tmp_path, figures="none")
    doc = json.loads((tmp_path / "plan.json").read_text())
    sequence = doc["sequence"]
    assert sequence["strategy"] == "optimal" and [r["callsign"] for r in sequence["aircraft"]] == order
    assert all(r["delay_s"] >= -1e-6 for r in sequence["aircraft"])
    gaps = doc["verification"]["landings"]
    assert [g["pair"] for g in gaps] == [f"{a}->{b}" for a, b in itertools.pairwise(order)]
    assert all(g["gap_s"] >= g["needed_s"] for g in gaps) and gaps[-1]["needed_s"] == pytest.approx(100.0)
    assert "## Landing spacing" in validation_report(result) and "H->H | 4 |" in validation_report(result)


def test_free_landing_times_keep_each_pairs_wake_spacing_in_the_nlp() -> None:
    """With free landing times the NLP's landing-spacing events are each consecutive pair's spacing with wake
    (heavy behind heavy: 100 s at 0.04 nm/s), not one number for every pair."""
    from mal_planner.landing.guess import straight_line_guess
    from mal_planner.landing.problem import build_landing_problem
    from mal_planner.landing.solve import layout_for
    from mal_planner.scenario import load_scenario
    from mal_planner.sequencing.schedule import planned_spacing

    scenario = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "wake_mixed.yaml")
    order = ["B5", "B4", "B2", "B1", "B3"]
    guesses = straight_line_guess(scenario, order, [150.0, 165.0, 180.0, 195.0, 295.0])
    built = build_landing_problem(scenario, layout_for(scenario, guesses), guesses, fixed_landing_times=False)
    spacing = list(built.problem.events_lb)[-(len(order) - 1):]
    need = [planned_spacing(scenario, scenario.aircraft_by_callsign(a), scenario.aircraft_by_callsign(b))
            for a, b in itertools.pairwise(order)]
    assert spacing == pytest.approx(need) and spacing[-1] > 100.0 > spacing[0] > scenario.landing_spacing_s


def test_time_windows_and_costs_from_the_scenario() -> None:
    """Per aircraft target, latest time and costs per second early and late reach the sequencer (defaults: target =
    earliest, no latest, 0 and 1: the total delay); a latest time no landing can meet is refused naming it."""
    from mal_planner.errors import InfeasibleRequest
    from mal_planner.scenario import parse_scenario
    from mal_planner.sequencing.schedule import make_schedule, sequencing_problem
    from mal_planner.sequencing.timing import earliest_landing_times

    data = _scenario_data()
    plain = parse_scenario(data)
    earliest = earliest_landing_times(plain)
    default = sequencing_problem(plain, earliest, 5.0)
    assert np.allclose(default.target, default.earliest) and np.all(np.isinf(default.latest))
    assert np.all(default.cost_early == 0.0) and np.all(default.cost_late == 1.0)
    first = data["aircraft"][0]
    cs = first["callsign"]
    first.update({"target_time": earliest[cs] + 60.0, "latest_time": earliest[cs] + 120.0, "cost_early": 2.0,
                  "cost_late": 3.0})
    windows = parse_scenario(data)
    problem = sequencing_problem(windows, earliest, 5.0)
    assert (problem.target[0], problem.latest[0], problem.cost_early[0], problem.cost_late[0]) == (
        earliest[cs] + 60.0, earliest[cs] + 120.0, 2.0, 3.0)
    data["sequencing"] = {"strategy": "optimal"}
    schedule = make_schedule(parse_scenario(data), earliest, 5.0)
    assert schedule.times[cs] == pytest.approx(earliest[cs] + 60.0)  # on its target: early costs, late costs more
    first["latest_time"] = earliest[cs] - 30.0
    with pytest.raises(InfeasibleRequest, match=f"{cs}: latest landing time .* is before its earliest"):
        make_schedule(parse_scenario(data), earliest, 5.0)
