"""ATC's cylindrical protected zone (separated horizontally OR vertically) beside the thesis's sphere."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from mal_planner.landing.constraints import CYLINDER_P, ProtectedZone
from mal_planner.landing.margins import Margins
from mal_planner.scenario import ScenarioError, load_scenario, scenario_from_text
from mal_planner.units import ft_to_nm


def _cylinder_text(extra: str) -> str:
    text = Path("scenarios/thesis.yaml").read_text()
    return text.replace("  distance_nm: 0.25\n", extra)


def test_separation_keys_parse_to_a_cylinder() -> None:
    sc = scenario_from_text(_cylinder_text("  horizontal_nm: 0.25\n  vertical_ft: 1000\n"))
    assert sc.separation_nm == 0.25
    assert sc.vertical_separation_nm == pytest.approx(1000 * 0.3048 / 1852)
    assert sc.separation_radius_nm == pytest.approx(np.hypot(0.25, ft_to_nm(1000)))
    assert load_scenario("scenarios/thesis.yaml").vertical_separation_nm is None  # the thesis keeps its sphere
    with pytest.raises(ScenarioError, match="distance_nm or horizontal_nm"):
        scenario_from_text(_cylinder_text("  horizontal_nm: 0.25\n  distance_nm: 0.25\n"))
    with pytest.raises(ScenarioError, match="vertical_ft"):
        scenario_from_text(_cylinder_text("  horizontal_nm: 0.25\n  vertical_ft: -5\n"))


def test_the_smooth_cylinder_is_conservative_and_tight() -> None:
    """measure >= lower implies max(h / H', |dz| / V') >= 1 (never unsafe); on the axes it asks for at most
    2^(1/p) of the minimum."""
    zone = ProtectedZone(3.0, ft_to_nm(1000.0))
    d = ca.SX.sym("d", 3)
    f = ca.Function("f", [d], [zone.measure(d)])
    rng = np.random.default_rng(0)
    pts = rng.uniform(-1.0, 1.0, (3, 20000)) * np.array([[6.0], [6.0], [0.5]])
    value = np.asarray(f.map(pts.shape[1])(pts)).ravel()
    ratio = np.maximum(np.hypot(pts[0], pts[1]) / zone.horizontal_nm, np.abs(pts[2]) / zone.vertical_nm)
    assert np.all(ratio[value >= zone.lower] >= 1.0)
    edge = 2.0 ** (1.0 / CYLINDER_P)
    assert float(f([3.0 * edge * 1.0001, 0.0, 0.0])) >= zone.lower > float(f([3.0 * edge * 0.9999, 0.0, 0.0]))
    sphere = ProtectedZone.of(load_scenario("scenarios/thesis.yaml"), Margins(0.01, 0.01, 1e-4, 0.002, 0.001, 0, 0))
    assert sphere.vertical_nm is None and sphere.lower == pytest.approx(0.26**2)


def test_thesis_with_a_cylinder_plans_verified() -> None:
    from mal_planner.pipeline import plan

    sc = scenario_from_text(_cylinder_text("  horizontal_nm: 0.25\n  vertical_ft: 300\n"))
    result = plan(sc)
    assert result.verified
    assert result.landing.objective == pytest.approx(-284.376, abs=2e-3)
