"""Structures, as in LabVIEW: a For loop, a While loop and a Case structure, each holding graphs.

A structure node holds its bodies in the graph file (``Node.bodies``) and binds them through the
runtime's binding protocol, so every body is validated with the graph that holds it (every case,
not only the one that runs) and its ports come from the body's interface:

- **Loops** hold one body, ``"body"``. Its interface input ``i`` (Number, optional) is the 0-based
  iteration index. Names listed in ``shift`` are shift registers: a body input and output of the same
  name and type; the loop's input of that name is the first iteration's value, each iteration's output
  is the next one's input, and the loop's output is the last value. Other body inputs are tunnels (the
  same value every iteration). Other body outputs are the loop's outputs: the last iteration's value, or
  for names listed in ``indexed`` every iteration's (auto-indexing): Paths joined in order (with a
  tool-up rapid wherever one does not start where the last ended), Numbers, Bools and Texts as a table
  column beside ``i``, Tables stacked with the iteration in a column in front (``i``, or ``j`` when the
  table has an ``i`` already: a loop in a loop). ``iterations`` says how many ran.
- **For loop**: ``count`` iterations (0 runs none: the outputs are the shift registers' initial values
  and empty collections).
- **While loop**: runs until the body's ``stop`` output (Bool) is true after an iteration, at least once
  and at most ``max_iterations`` (required); reaching it without stopping is an error naming the loop.
- **Case structure**: a ``selector`` (Bool, Number or Text) picks one body by its label: Bool labels are
  ``True`` and ``False``; Number labels are integers, lists (``1, 3``) and ranges (``4..6``, ``..0``,
  ``10..``), the selector rounded to the nearest integer; Text labels match exactly. ``default`` names
  the case that runs when no label matches (its label may then be any text). Every case shares one
  interface: the same outputs; inputs are the union (a case may leave one unused).

Iterations run through ``flowmc.runtime.iterations.BodyRunner``: cached by content when the body is
pure, announced as ``iteration`` events, failures named by iteration.
"""

from __future__ import annotations

import hashlib
import math
import threading
from dataclasses import dataclass
from typing import Annotated, Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field

import flowmc.budget as budget
from flowmc.errors import GraphError, NodeError
from flowmc.graph import NAME_PATTERN, Issue
from flowmc.nodes.subgraph import interface_ports
from flowmc.ports import REQUIRED, In, Out, Ports
from flowmc.registry import NodeType, register
from flowmc.runtime.binding import BindContext, Binding
from flowmc.runtime.iterations import BodyRunner, iteration_text
from flowmc.runtime.schedule import Plan

__all__ = ["ForLoop", "WhileLoop", "CaseStructure", "MAX_DEPTH", "LoopBody", "CaseBodies"]

MAX_DEPTH = 16  # structures inside structures
INDEX = "i"
STOP = "stop"
ITERATIONS = "iterations"
BODY = "body"
_INDEX_NAMES = ("i", "j", "k", "l", "m", "n")  # a table collected in a loop in a loop: j is the outer index
INDEXABLE = {"Path": "Path", "Number": "Table", "Bool": "Table", "Text": "Table", "Table": "Table"}

_Name = Annotated[str, Field(pattern=NAME_PATTERN)]


class _Params(BaseModel):
    model_config = ConfigDict(extra="forbid", defer_build=True)


class _LoopParams(_Params):
    shift: list[_Name] = Field(default_factory=list, description="Shift registers: body inputs fed by the "
                               "same-named body output of the iteration before (the loop's input: the first value)")
    indexed: list[_Name] = Field(default_factory=list, description="Body outputs collected from every iteration "
                                 "(Paths joined, numbers into a table) instead of the last value")


class ForParams(_LoopParams):
    count: int = Field(1, ge=0, description="N: how many iterations")


class WhileParams(_LoopParams):
    max_iterations: int = Field(ge=1, description="Most iterations before the loop fails (it stops earlier when "
                                "the body's stop output is true)")


class CaseParams(_Params):
    selector_type: Literal["Bool", "Number", "Text"] = Field("Text", description="Type of the selector input")
    default: str = Field("", description="The case that runs when no label matches (none: every value must match)")


# ---------------------------------------------------------------- binding bodies

_depth = threading.local()


@dataclass(frozen=True)
class _Bound:
    plan: Plan
    ports: Ports
    key: str


def _structure_issue(at: BindContext, message: str, *where: Any) -> Issue:
    return Issue("structure", ("nodes", at.node_id, *where), f"node {at.node_id!r}: {message}")


def _bind_body(at: BindContext, name: str, what: str) -> _Bound:
    """Plan one body with the outer graph's registry; its issues name the structure and the body."""
    graph = at.bodies.get(name)
    if graph is None:
        raise GraphError(f"no body {name!r}", issues=[_structure_issue(at, f"{what} is missing", "bodies", name)])
    depth = getattr(_depth, "value", 0)
    if depth >= MAX_DEPTH:
        raise GraphError("nested too deep", issues=[_structure_issue(
            at, f"structures nested more than {MAX_DEPTH} deep", "bodies", name)])
    _depth.value = depth + 1
    try:
        plan: Plan = at.plan(graph, at.site)
    finally:
        _depth.value = depth
    if plan.issues:
        issues = [Issue(i.code, ("nodes", at.node_id, "bodies", name, *i.location),
                        f"node {at.node_id!r}, {what}: {i.message}") for i in plan.issues]
        raise GraphError(issues[0].message, issues=issues)
    h = hashlib.blake2b(graph.fingerprint_json().encode(), digest_size=16)
    for node_id in plan.order:
        h.update(plan.nodes[node_id].static)
    return _Bound(plan, interface_ports(graph, plan), h.hexdigest())


def _refuse(issues: list[Issue]) -> None:
    if issues:
        raise GraphError(issues[0].message, issues=issues)


# ---------------------------------------------------------------- loops

@dataclass(frozen=True)
class LoopBody:
    """A loop's bound body: its plan, and what the loop feeds and collects."""

    plan: Plan
    key: str
    inputs: tuple[str, ...]  # body inputs the loop feeds (tunnels and shift registers; not i)
    has_index: bool
    outputs: dict[str, str]  # the loop's outputs taken from the body (not stop), by name: body output type

    @property
    def size(self) -> int:  # nodes it expands to (the expansion budget)
        return self.plan.size


def _bind_loop(cls: type[NodeType], params: _LoopParams, at: BindContext, needs_stop: bool) -> Binding:
    bound = _bind_body(at, BODY, "loop body")
    body_in = {p.name: p for p in bound.ports.inputs}
    body_out = {p.name: p for p in bound.ports.outputs}
    issues: list[Issue] = []
    extra = sorted(set(at.bodies) - {BODY})
    if extra:
        issues.append(_structure_issue(at, f"a loop holds one body, 'body'; remove {', '.join(map(repr, extra))}",
                                       "bodies"))
    if INDEX in body_in and body_in[INDEX].types != ("Number",):
        issues.append(_structure_issue(at, f"the body's input {INDEX!r} is the iteration index, a Number", "bodies"))
    if needs_stop:
        stop = body_out.get(STOP)
        if stop is None or stop.type != "Bool":
            issues.append(_structure_issue(at, f"a While loop's body needs a Bool output {STOP!r} (true: stop after "
                                               "this iteration)", "bodies", BODY))
    reserved_in = {p.name for p in cls.param_ports()}
    for name in sorted(set(body_in) & reserved_in):
        issues.append(_structure_issue(at, f"the body's input {name!r} clashes with the loop's param of that name; "
                                           "rename it", "bodies", BODY))
    if ITERATIONS in body_out:
        issues.append(_structure_issue(at, f"the body's output {ITERATIONS!r} clashes with the loop's count of "
                                           "iterations; rename it", "bodies", BODY))
    for k, name in enumerate(params.shift):
        inp, out = body_in.get(name), body_out.get(name)
        if inp is None or out is None:
            missing = " and ".join(w for w, p in (("input", inp), ("output", out)) if p is None)
            issues.append(_structure_issue(at, f"shift register {name!r} needs a body {missing} of that name",
                                           "params", "shift", k))
        elif inp.types != (out.type,):
            issues.append(_structure_issue(at, f"shift register {name!r}: the body's input is {inp.type} but its "
                                               f"output is {out.type}", "params", "shift", k))
    for k, name in enumerate(params.indexed):
        out = body_out.get(name)
        if out is None or name in params.shift or name == STOP:
            issues.append(_structure_issue(at, f"indexed output {name!r} must be a body output that is not a shift "
                                               f"register{' or the stop condition' if needs_stop else ''}",
                                           "params", "indexed", k))
        elif out.type not in INDEXABLE:
            issues.append(_structure_issue(at, f"indexed output {name!r} is a {out.type}; only "
                                               f"{', '.join(INDEXABLE)} can be collected", "params", "indexed", k))
    _refuse(issues)
    inputs = tuple(p for p in bound.ports.inputs if p.name != INDEX)
    loop_outputs = {name: p.type for name, p in body_out.items() if not (needs_stop and name == STOP)}
    outputs = tuple(Out(name, INDEXABLE[t] if name in params.indexed else t,
                        doc=("every iteration's " if name in params.indexed else "last ") + (body_out[name].doc or name))
                    for name, t in loop_outputs.items())
    outputs += (Out(ITERATIONS, "Number", doc="How many iterations ran"),)
    body = LoopBody(bound.plan, bound.key, tuple(p.name for p in inputs), INDEX in body_in, loop_outputs)
    return Binding(Ports(inputs, outputs), bound.plan.pure, bound.key, body, dict(bound.plan.deps))


def _collect(name: str, body_type: str, values: list[Any], k_done: int) -> Any:
    """Every iteration's value of one output, as auto-indexing gathers them."""
    import numpy as np  # the values' types: imported when a loop runs, not when a graph is validated

    from flowmc.motion.path import Path
    from flowmc.motion.table import Table

    if body_type == "Path":
        return Path.joined(values)
    index = np.arange(k_done, dtype=float)
    if body_type == "Table":
        if not values:
            return Table({INDEX: index})
        names = values[0].names
        column = next(c for c in (*_INDEX_NAMES, *(f"i{n}" for n in range(2, 99))) if c not in names)
        for k, table in enumerate(values):
            if table.names != names:
                raise NodeError(f"indexed output {name!r}: {iteration_text(k + 1, k_done)} gives columns "
                                f"{', '.join(table.names)}, the first gave {', '.join(names)}")
        stacked = {column: np.repeat(index, [len(t) for t in values])}
        stacked.update({n: np.concatenate([t[n] for t in values]) for n in names})
        return Table(stacked)
    return Table({INDEX: index, name: values})


class _Loop(NodeType):
    """What For and While loops share: running the body with shift registers, tunnels and collection."""

    category = "Structures"
    holds_bodies = True
    until_stop: ClassVar[bool] = False  # a While loop: the body has a stop output, and runs until it is true
    limit_param: ClassVar[str]  # the param that bounds the iterations

    @classmethod
    def bind_graph(cls, params: _LoopParams, at: BindContext) -> Binding:
        return _bind_loop(cls, params, at, needs_stop=cls.until_stop)

    def run(self, ctx: Any, params: _LoopParams, **inputs: Any) -> dict[str, Any]:
        limit = getattr(params, self.limit_param)
        budget.check("iterations", limit, what=f"a loop with {self.limit_param} {limit:,}",
                     change="loop over fewer, larger steps, or split the work over several loops")
        return self._loop(ctx, params, inputs, None if self.until_stop else limit, limit)

    def _loop(self, ctx: Any, params: _LoopParams, inputs: dict[str, Any], count: int | None, limit: int) -> dict:
        body: LoopBody = ctx.binding
        state = {name: inputs.get(name) for name in body.inputs}
        collected: dict[str, list[Any]] = {name: [] for name in params.indexed}
        last: dict[str, Any] = {}
        k = 0
        with BodyRunner(ctx, body.plan, body.key, limit=limit if count is None else None) as runner:
            while k < (count if count is not None else limit):
                given = {**state, **({INDEX: float(k)} if body.has_index else {})}
                out = runner.iteration(k + 1, count, given)
                k += 1
                for name in params.shift:
                    state[name] = out[name]
                for name, values in collected.items():
                    values.append(out[name])
                last = out
                if count is None and out[STOP]:
                    break
            else:
                if count is None:
                    raise NodeError(f"While loop ran its maximum of {limit} iterations and its stop condition never "
                                    "turned true (raise max_iterations, or check the body's stop output)")
        outputs: dict[str, Any] = {ITERATIONS: float(k)}
        for name, body_type in body.outputs.items():
            if name in collected:
                outputs[name] = _collect(name, body_type, collected[name], k)
            elif name in params.shift:
                outputs[name] = state[name]
            elif name in last:
                outputs[name] = last[name]
            else:
                raise NodeError(f"output {name!r} has no value: the loop ran no iteration (collect it with "
                                "'indexed', or make it a shift register)")
        missing = [n for n in body.outputs if n in params.shift and outputs[n] is None]
        if missing:
            raise NodeError(f"shift register {missing[0]!r} has no value: wire its initial value into the loop")
        return outputs


@register
class ForLoop(_Loop):
    type_id = "struct.for"
    title = "For loop"
    description = "Run the body N times (index i), with shift registers and outputs collected per iteration."
    Params = ForParams
    limit_param = "count"


@register
class WhileLoop(_Loop):
    type_id = "struct.while"
    title = "While loop"
    description = "Run the body until its stop output is true, at most max_iterations times, with shift registers."
    Params = WhileParams
    until_stop = True
    limit_param = "max_iterations"


# ---------------------------------------------------------------- case

_BOOL_LABELS = {"True": True, "False": False}


def _number_label(label: str) -> list[tuple[float, float]]:
    """``"1, 3, 5..7, ..0"`` -> closed integer intervals; ValueError when it is not such a list."""
    out = []
    for part in label.split(","):
        part = part.strip()
        if ".." in part:
            lo_text, _, hi_text = part.partition("..")
            lo = int(lo_text) if lo_text.strip() else -math.inf
            hi = int(hi_text) if hi_text.strip() else math.inf
            if lo > hi:
                raise ValueError(f"range {part!r} runs backwards")
            out.append((lo, hi))
        else:
            out.append((int(part), int(part)))
    return out


@dataclass(frozen=True)
class CaseBodies:
    """A case structure's bound bodies, by label, and how a selector value picks one."""

    plans: dict[str, Plan]
    keys: dict[str, str]
    matches: tuple[tuple[str, Any], ...]  # (label, True/False | intervals | text), in file order
    default: str | None

    @property
    def size(self) -> int:
        return sum(plan.size for plan in self.plans.values())

    def choose(self, selector: Any) -> str:
        if isinstance(selector, float) and not math.isfinite(selector):
            raise NodeError(f"the selector is {selector}, which picks no case")
        for label, match in self.matches:
            if isinstance(match, list):
                value = math.floor(float(selector) + 0.5)
                if any(lo <= value <= hi for lo, hi in match):
                    return label
            elif isinstance(match, bool):
                if bool(selector) is match:
                    return label
            elif match == selector:
                return label
        if self.default is None:
            raise NodeError(f"no case for the selector {selector!r}, and no default case")
        return self.default


def _case_matches(params: CaseParams, at: BindContext) -> tuple[tuple[tuple[str, Any], ...], list[Issue]]:
    matches: list[tuple[str, Any]] = []
    issues: list[Issue] = []
    for label in at.bodies:
        if params.selector_type == "Text":
            matches.append((label, label))
        elif params.selector_type == "Bool":
            if label in _BOOL_LABELS:
                matches.append((label, _BOOL_LABELS[label]))
            elif label != params.default:
                issues.append(_structure_issue(at, f"case {label!r}: a Bool case is 'True' or 'False'", "bodies", label))
        else:
            try:
                matches.append((label, _number_label(label)))
            except ValueError as exc:
                if label != params.default:
                    issues.append(_structure_issue(at, f"case {label!r}: a Number case is integers and ranges like "
                                                       f"'1, 3, 5..7' ({exc})", "bodies", label))
    numbered = [(label, m) for label, m in matches if isinstance(m, list)]
    for a, (label_a, ranges_a) in enumerate(numbered):
        for label_b, ranges_b in numbered[a + 1:]:
            if any(max(lo1, lo2) <= min(hi1, hi2) for lo1, hi1 in ranges_a for lo2, hi2 in ranges_b):
                issues.append(_structure_issue(at, f"cases {label_a!r} and {label_b!r} both match some values",
                                               "bodies", label_b))
    if params.default and params.default not in at.bodies:
        issues.append(_structure_issue(at, f"default case {params.default!r} is not one of the cases "
                                           f"({', '.join(map(repr, at.bodies))})", "params", "default"))
    elif not params.default and not (params.selector_type == "Bool" and set(at.bodies) == set(_BOOL_LABELS)):
        issues.append(_structure_issue(at, "name a default case: some selector values match no case",
                                       "params", "default"))
    return tuple(matches), issues


def _shared_ports(bound: dict[str, _Bound], at: BindContext) -> tuple[tuple[In, ...], tuple[Out, ...], list[Issue]]:
    """Inputs: the union of the cases' (one type each). Outputs: the same in every case."""
    issues: list[Issue] = []
    inputs: dict[str, In] = {}
    first_label = next(iter(bound))
    first = {p.name: p for p in bound[first_label].ports.outputs}
    for label, b in bound.items():
        for port in b.ports.inputs:
            seen = inputs.get(port.name)
            if seen is None:
                inputs[port.name] = port
            elif seen.types != port.types:
                issues.append(_structure_issue(at, f"case {label!r}: input {port.name!r} is {port.type}, another case "
                                                   f"takes {seen.type}", "bodies", label))
            elif port.required and not seen.required:
                inputs[port.name] = port
        outs = {p.name: p for p in b.ports.outputs}
        for name in sorted(set(first) | set(outs)):
            if name not in outs:
                issues.append(_structure_issue(at, f"case {label!r} has no output {name!r} (every case gives the same "
                                                   "outputs)", "bodies", label))
            elif name not in first:
                issues.append(_structure_issue(at, f"case {label!r} gives output {name!r}, which case "
                                                   f"{first_label!r} does not", "bodies", label))
            elif outs[name].type != first[name].type:
                issues.append(_structure_issue(at, f"case {label!r}: output {name!r} is {outs[name].type}, case "
                                                   f"{first_label!r} gives {first[name].type}", "bodies", label))
    return tuple(inputs.values()), tuple(first.values()), issues


@register
class CaseStructure(NodeType):
    type_id = "struct.case"
    title = "Case"
    category = "Structures"
    description = "Run the one body whose label matches the selector (or the default case); all share one interface."
    Params = CaseParams
    fixed_params = ("selector_type", "default")
    holds_bodies = True

    @classmethod
    def bind_graph(cls, params: CaseParams, at: BindContext) -> Binding:
        if not at.bodies:
            raise GraphError("no cases", issues=[_structure_issue(at, "a case structure holds at least one case",
                                                                  "bodies")])
        issues: list[Issue] = []
        bound: dict[str, _Bound] = {}
        for label in at.bodies:  # every case is validated, not only the one that runs
            try:
                bound[label] = _bind_body(at, label, f"case {label!r}")
            except GraphError as exc:
                issues.extend(exc.issues)
        matches, match_issues = _case_matches(params, at)
        issues += match_issues
        _refuse(issues)
        inputs, outputs, port_issues = _shared_ports(bound, at)
        if "selector" in {p.name for p in inputs}:
            port_issues.append(_structure_issue(at, "a case's input 'selector' clashes with the structure's selector; "
                                                    "rename it", "bodies"))
        _refuse(port_issues)
        selector = In("selector", params.selector_type, doc="Picks the case that runs")
        h = hashlib.blake2b(digest_size=16)
        for label, b in bound.items():
            h.update(f"{label}\0{b.key};".encode())
        bodies = CaseBodies({k: b.plan for k, b in bound.items()}, {k: b.key for k, b in bound.items()}, matches,
                            params.default or None)
        deps = {path: stat for b in bound.values() for path, stat in b.plan.deps.items()}
        pure = all(b.plan.pure for b in bound.values())
        return Binding(Ports((selector, *inputs), outputs), pure, h.hexdigest(), bodies, deps)

    def run(self, ctx: Any, params: CaseParams, selector: Any = REQUIRED, **inputs: Any) -> dict[str, Any]:
        bodies: CaseBodies = ctx.binding
        label = bodies.choose(selector)
        ctx.log(f"case {label!r}")
        plan = bodies.plans[label]
        given = {name: value for name, value in inputs.items() if name in plan.iface_inputs}
        with BodyRunner(ctx, plan, bodies.keys[label], runtime=ctx.child_runtime().child(label)) as runner:
            return runner.run(given, f"case {label!r}")
