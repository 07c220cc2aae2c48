"""Basic nodes: constants, arithmetic, a comparison, a range check and a report of named numbers.

Arithmetic operands are params, so each can be typed in or fed by a wire to ``node.a``.
"""

from __future__ import annotations

import math
import operator
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from flowmc.errors import NodeError
from flowmc.registry import In, NodeType, Out, Ports, register


class _Params(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)


# ---------------------------------------------------------------- constants

class NumberParams(_Params):
    value: float = Field(0.0, description="The number")


class BoolParams(_Params):
    value: bool = Field(False, description="The flag")


class TextParams(_Params):
    value: str = Field("", description="The text")


@register
class NumberConst(NodeType):
    type_id = "basic.number"
    title = "Number"
    category = "Basic"
    description = "A constant number."
    Params = NumberParams
    outputs = (Out("value", "Number", doc="The number"),)

    def run(self, ctx, params: NumberParams):
        return {"value": params.value}


@register
class BoolConst(NodeType):
    type_id = "basic.bool"
    title = "Bool"
    category = "Basic"
    description = "A constant true/false flag."
    Params = BoolParams
    outputs = (Out("value", "Bool", doc="The flag"),)

    def run(self, ctx, params: BoolParams):
        return {"value": params.value}


@register
class TextConst(NodeType):
    type_id = "basic.text"
    title = "Text"
    category = "Basic"
    description = "A constant text."
    Params = TextParams
    outputs = (Out("value", "Text", doc="The text"),)

    def run(self, ctx, params: TextParams):
        return {"value": params.value}


# ---------------------------------------------------------------- arithmetic

class BinaryParams(_Params):
    a: float = Field(0.0, description="First operand")
    b: float = Field(0.0, description="Second operand")


class _Binary(NodeType):
    category = "Math"
    Params = BinaryParams
    outputs = (Out("result", "Number", doc="The result"),)

    def run(self, ctx, params: BinaryParams):
        return {"result": self.apply(params.a, params.b)}

    def apply(self, a: float, b: float) -> float:
        raise NotImplementedError


@register
class Add(_Binary):
    type_id = "basic.add"
    title = "Add"
    description = "a + b"

    def apply(self, a, b):
        return a + b


@register
class Subtract(_Binary):
    type_id = "basic.subtract"
    title = "Subtract"
    description = "a - b"

    def apply(self, a, b):
        return a - b


@register
class Multiply(_Binary):
    type_id = "basic.multiply"
    title = "Multiply"
    description = "a * b"

    def apply(self, a, b):
        return a * b


@register
class Divide(_Binary):
    type_id = "basic.divide"
    title = "Divide"
    description = "a / b; fails when b is 0."

    def apply(self, a, b):
        if b == 0:
            raise NodeError("division by zero (b = 0)")
        return a / b


class CompareParams(BinaryParams):
    op: Literal["<", "<=", ">", ">=", "==", "!="] = Field(">=", description="How a is compared with b")


_COMPARE = {"<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge, "==": operator.eq,
            "!=": operator.ne}


@register
class Compare(NodeType):
    type_id = "basic.compare"
    title = "Compare"
    category = "Math"
    description = "a op b as a Bool (a While loop's stop condition, a case selector)."
    Params = CompareParams
    outputs = (Out("result", "Bool", doc="True when a op b holds"),)

    def run(self, ctx, params: CompareParams):
        return {"result": bool(_COMPARE[params.op](params.a, params.b))}


class RatioParams(_Params):
    value: float = Field(0.0, description="Measured value")
    reference: float = Field(1.0, description="Reference value it is compared with")


@register
class Ratio(NodeType):
    type_id = "basic.ratio"
    title = "Ratio"
    category = "Math"
    description = "Compare a value with a reference: value / reference and the change in percent."
    Params = RatioParams
    outputs = (
        Out("ratio", "Number", doc="value / reference"),
        Out("change_percent", "Number", doc="100 * (value - reference) / reference"),
    )

    def run(self, ctx, params: RatioParams):
        if params.reference == 0:
            raise NodeError("reference is 0, so no ratio")
        ratio = params.value / params.reference
        return {"ratio": ratio, "change_percent": 100.0 * (ratio - 1.0)}


# ---------------------------------------------------------------- check and report

class CheckParams(_Params):
    min: float | None = Field(None, description="Smallest allowed value (none: no lower bound)")
    max: float | None = Field(None, description="Largest allowed value (none: no upper bound)")
    label: str = Field("", description="What is checked, for the failure message")


@register
class Check(NodeType):
    type_id = "basic.check"
    title = "Check"
    category = "Basic"
    description = "Fail the run when a number is outside [min, max]; graphs check their own results with it."
    pure = False  # a check must be seen to run every time
    Params = CheckParams
    inputs = (In("value", "Number", doc="Number to check"),)
    outputs = (Out("value", "Number", doc="The same number, when it passed"),)

    def run(self, ctx, params: CheckParams, value: float):
        what = params.label or "value"
        low = -math.inf if params.min is None else params.min
        high = math.inf if params.max is None else params.max
        if math.isnan(value) or not low <= value <= high:
            raise NodeError(f"check failed: {what} = {value:g} is outside [{_bound(params.min)}, {_bound(params.max)}]")
        ctx.log(f"{what} = {value:g} within [{_bound(params.min)}, {_bound(params.max)}]")
        return {"value": value}


def _bound(value: float | None) -> str:
    return "-" if value is None else f"{value:g}"


class ReportParams(_Params):
    names: list[str] = Field(default_factory=lambda: ["value"], min_length=1,
                             description="Names of the numbers to collect: one input each")
    title: str = Field("", description="Heading of the text report")
    digits: int = Field(6, ge=0, le=17, description="Significant digits in the text report")

    @field_validator("names")
    @classmethod
    def _names_are_ports(cls, names: list[str]) -> list[str]:
        for name in names:
            if not name.isidentifier() or name in ("ctx", "params", "title", "digits", "names"):
                raise ValueError(f"{name!r} cannot be a port name (letters, digits and _; not a param name)")
        if len(set(names)) != len(names):
            raise ValueError("names must be distinct")
        return names


@register
class Report(NodeType):
    type_id = "basic.report"
    title = "Report"
    category = "Basic"
    description = "Collect named numbers into a table (name, value) and a text report."
    Params = ReportParams
    outputs = (Out("table", "Table", doc="Columns name and value"), Out("text", "Text", doc="One 'name = value' line each"))

    @classmethod
    def ports(cls, params: ReportParams) -> Ports:
        inputs = tuple(In(name, "Number", doc=f"Value reported as {name!r}") for name in params.names)
        return Ports(inputs, cls.outputs)

    def run(self, ctx, params: ReportParams, **values: Any):
        from flowmc.motion.table import Table

        numbers = [float(values[name]) for name in params.names]
        lines = [params.title] if params.title else []
        lines += [f"{name} = {value:.{params.digits}g}" for name, value in zip(params.names, numbers)]
        return {"table": Table({"name": params.names, "value": numbers}), "text": "\n".join(lines)}
