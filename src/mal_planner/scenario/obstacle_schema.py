"""The scenario file's obstacles (pydantic): superquadrics, gates and walls with a hole, in nm and degrees."""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from mal_planner.obstacles import Gate, Superquadric, wall_with_hole
from mal_planner.scenario.quantities import Interval, Strict, Vec3, quantity

AXIS_INDEX = {"x": 0, "y": 1, "z": 2}


def _is_even(value: int) -> int:
    if value < 2 or value % 2:
        raise ValueError(f"the exponent p must be an even integer >= 2, got {value}")
    return value


class SuperquadricConfig(Strict):
    type: Literal["superquadric"] = "superquadric"
    name: str
    center: Vec3 = quantity("nm")
    semi_axes: Vec3 = quantity("nm")
    p: int = 2

    _even = field_validator("p")(_is_even)

    @field_validator("semi_axes")
    @classmethod
    def _positive(cls, value: Vec3) -> Vec3:
        if min(value) <= 0.0:
            raise ValueError("semi-axes must all be > 0")
        return value


class GateConfig(Strict):
    name: str = "gate"
    axis: Literal["x", "y", "z"] = "y"
    position: float = quantity("nm")
    direction: Literal[-1, 1] = -1
    """Sign of the travel along ``axis`` when passing the gate."""
    bounds: dict[Literal["x", "y", "z"], Interval] = quantity("nm")
    """The hole's bounds along the two other axes."""
    flight_path_angle_deg: float = quantity("deg", 0.0)
    heading_deg: float = quantity("deg", -90.0)

    @model_validator(mode="after")
    def _two_other_axes(self) -> GateConfig:
        expected = set("xyz") - {self.axis}
        if set(self.bounds) != expected:
            raise ValueError(f"bounds must give exactly the axes {sorted(expected)}")
        for key, value in self.bounds.items():
            if not value[0] < value[1]:
                raise ValueError(f"bounds.{key}: lower bound must be below upper bound")
        return self

    def to_gate(self) -> Gate:
        axis = AXIS_INDEX[self.axis]
        others = [a for a in "xyz" if a != self.axis]
        return Gate(
            name=self.name,
            axis=axis,
            position=self.position,
            direction=self.direction,
            bounds=(tuple(self.bounds[others[0]]), tuple(self.bounds[others[1]])),
            flight_path_angle=float(np.radians(self.flight_path_angle_deg)),
            heading=float(np.radians(self.heading_deg)),
        )


class WallConfig(Strict):
    """A thin wall with a rectangular hole; expands to four superquadrics and a gate."""

    type: Literal["wall_with_hole"]
    name: str = "wall"
    axis: Literal["x", "y", "z"] = "y"
    position: float = quantity("nm")
    """Coordinate of the wall's gate face (the thesis: y = 3, the wall spans [3, 3.001])."""
    thickness: float = quantity("nm", gt=0.0)
    span: dict[Literal["x", "y", "z"], Interval] = quantity("nm")
    hole: dict[Literal["x", "y", "z"], Interval] = quantity("nm")
    p: int = 50
    direction: Literal[-1, 1] = -1
    flight_path_angle_deg: float = quantity("deg", 0.0)
    heading_deg: float = quantity("deg", -90.0)

    _even = field_validator("p")(_is_even)

    @model_validator(mode="after")
    def _consistent(self) -> WallConfig:
        expected = set("xyz") - {self.axis}
        for label, value in (("span", self.span), ("hole", self.hole)):
            if set(value) != expected:
                raise ValueError(f"{label} must give exactly the axes {sorted(expected)}")
        for a in sorted(expected):
            (s0, s1), (h0, h1) = self.span[a], self.hole[a]
            if not s0 < h0 < h1 < s1:
                raise ValueError(f"hole.{a} {list(self.hole[a])} must lie strictly inside span.{a} {[s0, s1]}")
        return self

    def expand(self) -> tuple[list[Superquadric], GateConfig]:
        others = [a for a in "xyz" if a != self.axis]
        pieces = wall_with_hole(
            self.name,
            AXIS_INDEX[self.axis],
            self.position,
            self.thickness,
            (self.span[others[0]], self.span[others[1]]),
            (self.hole[others[0]], self.hole[others[1]]),
            self.p,
        )
        gate = GateConfig(
            name=f"{self.name}-hole",
            axis=self.axis,
            position=self.position,
            direction=self.direction,
            bounds=dict(self.hole),
            flight_path_angle_deg=self.flight_path_angle_deg,
            heading_deg=self.heading_deg,
        )
        return pieces, gate


ObstacleConfig = Annotated[SuperquadricConfig | WallConfig, Field(discriminator="type")]
