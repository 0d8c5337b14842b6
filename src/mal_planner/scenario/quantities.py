"""Fields with a unit: the unit is declared once, on the schema's field, and read back by the loader's error
messages (``aircraft[0].speed: must be > 0 nm/s, got -0.1``)."""

from __future__ import annotations

from typing import Any, get_args

from pydantic import BaseModel, ConfigDict, Field
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

Vec3 = tuple[float, float, float]
Interval = tuple[float, float]


class Strict(BaseModel):
    """A schema model: unknown keys are errors, values are frozen."""

    model_config = ConfigDict(extra="forbid", frozen=True)


def quantity(unit: str, default: Any = PydanticUndefined, **constraints: Any) -> Any:
    """A field measured in ``unit`` (declared once: validation errors name it, see :func:`field_unit`)."""
    return Field(default, json_schema_extra={"unit": unit}, **constraints)


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    """The pydantic models an annotation holds (through unions, lists, dicts and ``Annotated``)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in get_args(annotation) for m in _models_in(arg)]


def field_unit(loc: tuple[int | str, ...], root: type[BaseModel]) -> str | None:
    """The unit declared (with :func:`quantity`) for the field of model ``root`` at a validation error's location
    (pydantic's ``loc``), if any."""
    models: list[type[BaseModel]] = [root]
    info: FieldInfo | None = None
    for part in loc:
        found = next((m.model_fields[part] for m in models if isinstance(part, str) and part in m.model_fields),
                     None)
        if found is not None:
            info = found
            models = _models_in(found.annotation)
    extra = info.json_schema_extra if info is not None else None
    return extra.get("unit") if isinstance(extra, dict) else None  # type: ignore[return-value]
