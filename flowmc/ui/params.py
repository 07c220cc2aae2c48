"""Params checked against a node type's params model, with each problem keyed by the field it is about.

pydantic reports union branches and discriminator tags inside error locations
(``("rows", 2, "arc", "radius")``); the editor wants the path into the data
(``("rows", 2, "radius")``) so it can show the message beside the field that holds it.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ValidationError

__all__ = ["field_errors", "data_path"]


def data_path(data: Any, loc: tuple[Any, ...]) -> tuple[Any, ...]:
    """The part of a pydantic error location that walks through ``data`` (branch names dropped)."""
    path: list[Any] = []
    current = data
    for part in loc:
        if isinstance(current, dict):
            if part in current:
                current = current[part]
            elif isinstance(part, str) and part not in _tags(current):
                current = None  # a missing required field: still the field the message is about
            else:
                continue  # a discriminator tag
        elif isinstance(current, (list, tuple)) and isinstance(part, int) and 0 <= part < len(current):
            current = current[part]
        else:
            continue  # a union branch name, or beyond the data
        path.append(part)
    return tuple(path)


def _tags(obj: dict) -> set[str]:
    """String values of ``obj``: a discriminated union names its branch by one of them."""
    return {v for v in obj.values() if isinstance(v, str)}


def field_errors(model: type[BaseModel], params: dict[str, Any], skip: set[str] = frozenset()) -> dict[tuple, str]:
    """``{field path: message}`` for every problem with ``params``; top-level fields in ``skip``
    (params fed by a wire: their stored value is not used) are left out."""
    try:
        model.model_validate(params)
    except ValidationError as exc:
        errors: dict[tuple, str] = {}
        for err in exc.errors():
            path = data_path(params, tuple(err["loc"])) or ("(params)",)
            if path[0] in skip:
                continue
            message = "unknown param" if err["type"] == "extra_forbidden" else err["msg"]
            errors[path] = f"{errors[path]}; {message}" if path in errors and message not in errors[path] else message
        return errors
    return {}
