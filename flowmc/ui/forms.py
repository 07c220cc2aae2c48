"""From a params model's JSON Schema to form fields: which widget each param gets, its label
with the unit, its bounds, and what a new table row holds. Plain data; ``inspector`` builds it.

Kinds: number, integer, checkbox, dropdown, text, vector2, vector3, optional (a text box where
empty means none, wrapping ``inner``), list (comma-separated scalars), points (one "x, y, z" line
per point), rows (a table of objects: ``variants`` by discriminator tag, "" for plain objects), json.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any

__all__ = ["MISSING", "FieldSpec", "form_fields", "new_row", "blank_value"]

class _Missing:
    def __repr__(self) -> str:
        return "MISSING"

    def __deepcopy__(self, memo: dict) -> "_Missing":
        return self


MISSING: Any = _Missing()


@dataclass
class FieldSpec:
    name: str
    kind: str
    label: str
    hint: str = ""
    default: Any = MISSING
    required: bool = False
    minimum: float | None = None
    maximum: float | None = None
    options: tuple[str, ...] = ()
    inner: "FieldSpec | None" = None
    tag: str | None = None  # rows: the discriminator property
    variants: dict[str, list["FieldSpec"]] = field(default_factory=dict)
    item: "FieldSpec | None" = None  # rows of fixed tuples: the vector field


def _resolve(schema: dict, defs: dict) -> dict:
    while "$ref" in schema:
        target = defs[schema["$ref"].rsplit("/", 1)[-1]]
        schema = {**target, **{k: v for k, v in schema.items() if k != "$ref"}}
    return schema


def _bounds(s: dict) -> tuple[float | None, float | None]:
    low = s.get("minimum", s.get("exclusiveMinimum"))
    high = s.get("maximum", s.get("exclusiveMaximum"))
    return low, high


def _is_vector(s: dict) -> bool:
    prefix = s.get("prefixItems")
    return bool(prefix) and len(prefix) in (2, 3) and all(p.get("type") in ("number", "integer") for p in prefix)


def classify(name: str, s: dict, defs: dict, required: bool = False) -> FieldSpec:
    s = _resolve(s, defs)
    unit = s.get("unit")
    spec = FieldSpec(name, "json", f"{name} ({unit})" if unit else name, s.get("description", ""),
                     copy.deepcopy(s.get("default", MISSING)), required)
    if "anyOf" in s:
        options = [_resolve(o, defs) for o in s["anyOf"]]
        others = [o for o in options if o.get("type") != "null"]
        if len(others) == 1 and len(options) == 2:
            spec.kind = "optional"
            spec.inner = classify(name, {**others[0], "unit": unit}, defs, True)
        return spec
    kind = s.get("type")
    if "enum" in s:
        spec.kind, spec.options = "dropdown", tuple(str(v) for v in s["enum"])
    elif kind == "boolean":
        spec.kind = "checkbox"
    elif kind in ("number", "integer"):
        spec.kind = kind
        spec.minimum, spec.maximum = _bounds(s)
    elif kind == "string":
        spec.kind = "text"
    elif kind == "array" and _is_vector(s):
        spec.kind = f"vector{len(s['prefixItems'])}"
    elif kind == "array":
        _classify_array(spec, _resolve(s.get("items", {}), defs), defs)
    return spec


def _classify_array(spec: FieldSpec, items: dict, defs: dict) -> None:
    union = items.get("oneOf") or items.get("anyOf")
    if union and "discriminator" in items:
        spec.kind, spec.tag = "rows", items["discriminator"]["propertyName"]
        for option in union:
            obj = _resolve(option, defs)
            tag_schema = obj.get("properties", {}).get(spec.tag, {})
            tag = tag_schema.get("const", tag_schema.get("default"))
            spec.variants[str(tag)] = _object_fields(obj, defs, skip=spec.tag)
    elif items.get("type") == "object":
        spec.kind = "rows"
        spec.variants[""] = _object_fields(items, defs)
    elif _is_vector(items):
        spec.kind = "points"
        spec.item = FieldSpec("point", f"vector{len(items['prefixItems'])}", "point")
    elif items.get("type") in ("number", "integer", "string"):
        spec.kind = "list"
        spec.inner = FieldSpec("item", items["type"], "item")


def _object_fields(obj: dict, defs: dict, skip: str | None = None) -> list[FieldSpec]:
    required = set(obj.get("required", ()))
    return [classify(name, prop, defs, name in required)
            for name, prop in obj.get("properties", {}).items() if name != skip]


def form_fields(schema: dict) -> list[FieldSpec]:
    """One FieldSpec per param of a params model's JSON Schema, in declaration order."""
    return _object_fields(schema, schema.get("$defs", {}))


def blank_value(spec: FieldSpec) -> Any:
    """A starting value for a field that has no default: inside its bounds, the first choice."""
    if spec.default is not MISSING:
        return copy.deepcopy(spec.default)
    if spec.kind in ("number", "integer"):
        low = spec.minimum if spec.minimum is not None else 0.0
        value = max(low, 1.0) if spec.minimum is not None else 0.0
        value = min(value, spec.maximum) if spec.maximum is not None else value
        return int(value) if spec.kind == "integer" else float(value)
    return {"checkbox": False, "dropdown": spec.options[0] if spec.options else "", "text": "",
            "vector2": [0.0, 0.0], "vector3": [0.0, 0.0, 0.0], "optional": None, "list": [], "rows": [],
            "points": []}.get(spec.kind)


def new_row(spec: FieldSpec, variant: str, old: dict | None = None) -> dict:
    """A new table row of ``variant``: its required fields blank (inside their bounds), keeping the
    values of ``old`` (the row it replaces) for fields both variants have."""
    fields = {f.name: f for f in spec.variants[variant]}
    row = {spec.tag: variant} if spec.tag else {}
    for name, f in fields.items():
        if old is not None and name in old:
            row[name] = copy.deepcopy(old[name])
        elif f.required:
            row[name] = blank_value(f)
    return row
