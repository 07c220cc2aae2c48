"""Node registry: declarations checked at import, param ports, describe, registries as plain objects."""

from __future__ import annotations

from typing import Literal

import pytest
from pydantic import BaseModel, ConfigDict, Field

import flowmc
from flowmc.errors import GraphError
from flowmc.plugins import default_registry
from flowmc.registry import In, NodeType, Out, Ports, Registry, register


class _P(BaseModel):
    model_config = ConfigDict(extra="forbid")
    speed: float = Field(1.0, gt=0, description="speed")
    count: int = 3
    on: bool = False
    mode: Literal["fast", "slow"] = "fast"
    note: str | None = None
    rows: list[float] = []


def _make(**attrs):
    base = {"type_id": "test.made", "title": "Made", "category": "Test", "description": "one line",
            "run": lambda self, ctx, params, **kw: {}}
    base.update(attrs)
    return type("Made", (NodeType,), base)


def test_param_ports_follow_the_params_model():
    cls = register(_make(Params=_P, inputs=(In("path", "Path"),), outputs=(Out("path", "Path"),)))
    ports = {p.name: p for p in cls.param_ports()}
    assert {n: p.types for n, p in ports.items()} == {
        "speed": ("Number",), "count": ("Number",), "on": ("Bool",), "mode": ("Text",), "note": ("Text",)}
    assert ports["speed"].default == 1.0 and ports["speed"].param and not ports["speed"].required
    assert "rows" not in ports  # lists are not scalar: no port


@pytest.mark.parametrize(
    "attrs, message",
    [
        ({"type_id": "Bad Id"}, "type_id"),
        ({"type_id": "lib.mine"}, "reserved"),
        ({"description": "two\nlines"}, "one line"),
        ({"inputs": (In("x", "Vector"),)}, "unknown port type"),
        ({"outputs": (Out("y", "Number"), Out("y", "Number"))}, "declared twice"),
        ({"Params": _P, "inputs": (In("speed", "Number"),)}, "declared twice"),
        ({"inputs": (In("params", "Number"),)}, "not a valid identifier"),
        ({"Params": type("Loose", (BaseModel,), {"__annotations__": {"a": int}, "a": 1})}, 'extra="forbid"'),
    ],
)
def test_bad_declarations_fail_at_registration(attrs, message):
    with pytest.raises(TypeError, match=message):
        register(_make(**attrs))
    reg = Registry()
    with pytest.raises(TypeError, match=message):
        reg.add(_make(**attrs))
    assert "test.made" not in reg


def test_type_id_cannot_be_taken_twice():
    reg = Registry([_make()])
    other = type("Other", (NodeType,), {"type_id": "test.made", "title": "O", "category": "T", "description": "d",
                                        "run": lambda self, ctx, params: {}})
    with pytest.raises(TypeError, match="already used"):
        reg.add(other)


def test_describe_gives_ports_schema_and_text(registry):
    d = registry.describe("test.sink")
    assert d["description"] == "Takes a Path or a Trajectory and reports its label length."
    assert d["inputs"] == [{"name": "path", "types": ["Path", "Trajectory"], "doc": "blob", "required": True,
                            "default": None, "param": False}]
    assert d["outputs"][0] == {"name": "n", "type": "Number", "doc": "label length"}
    blob = registry.describe("test.blob")
    assert blob["params_schema"]["properties"]["feed"]["exclusiveMinimum"] == 0
    assert [p["name"] for p in blob["param_inputs"]] == ["label", "feed"]


def test_dynamic_ports_are_described_for_given_params(registry):
    d = registry.describe("basic.report", params={"names": ["cycle", "error"]})
    assert [p["name"] for p in d["inputs"]] == ["cycle", "error"]
    assert registry.types()["basic.report"].dynamic_ports()
    assert not registry.types()["basic.add"].dynamic_ports()


def test_describe_all_lists_every_type_sorted(registry):
    ids = [d["type_id"] for d in registry.describe_all()]
    assert ids == sorted(ids)
    assert {"basic.number", "basic.check", "basic.report", "subgraph", "test.blob", "lib.home_all"} <= set(ids)


def test_registries_are_independent_objects(registry):
    mine = registry.copy()
    mine.add(_make())
    assert "test.made" in mine and "test.made" not in registry and "test.made" not in default_registry()
    assert mine.generation != registry.generation
    with pytest.raises(GraphError, match="unknown node type"):
        registry.lookup("test.made")
    g = flowmc.GraphBuilder()
    g.add("test.made", id="m")
    assert flowmc.validate(g.build(), registry=mine) == []
    assert [i.code for i in flowmc.validate(g.build(), registry=registry)] == ["unknown-node-type"]
    before = mine.generation
    mine.remove("test.made")
    assert "test.made" not in mine and mine.generation != before


def test_overridden_ports_are_checked_when_used(registry):
    class Dyn(NodeType):
        type_id = "test.dyn"
        title = "Dyn"
        category = "Test"
        description = "Ports from params."

        @classmethod
        def ports(cls, params):
            return Ports((In("x", "Nope"),), ())

        def run(self, ctx, params, **kw):
            return {}

    registry.add(Dyn)
    g = flowmc.GraphBuilder()
    g.add("test.dyn", id="d")
    issues = flowmc.validate(g.build(), registry=registry)
    assert len(issues) == 1 and "node 'd'" in issues[0].message and "unknown port type" in issues[0].message


def test_every_node_module_of_the_package_loads_and_every_type_describes_itself():
    """A node module that fails to import is only recorded at run time: here it fails the build."""
    registry = default_registry()
    assert registry.failures == {}
    described = registry.describe_all()
    ids = {d["type_id"] for d in described}
    for expected in ("path.segment_table", "path.gcode_in", "plan.lookahead", "interp.point_by_point",
                     "device.card_output", "machine", "lib.home_all"):
        assert expected in ids
    assert all(d["description"] and "\n" not in d["description"] for d in described)


def test_a_deferred_source_loads_on_first_need_and_is_no_change():
    loads = []

    def source(reg):
        loads.append("a")
        reg.add(_make(type_id="test.deferred"), origin="source a")
        reg.add(_make(type_id="test.unannounced"), origin="source a")

    reg = Registry()
    reg.defer(source, ["test.deferred"])
    generation = reg.generation
    assert loads == []
    assert reg.lookup("test.deferred").type_id == "test.deferred" and loads == ["a"]
    assert reg.generation == generation and reg.origin("test.deferred") == "source a"
    other = Registry()
    other.defer(source)  # ids not announced: found by loading every pending source
    assert other.lookup("test.unannounced").type_id == "test.unannounced" and loads == ["a", "a"]
    broken = Registry()
    broken.defer(lambda r: r.failures.update({"source b": "ImportError: no"}), ["test.b"])
    with pytest.raises(GraphError, match="unknown node type 'test.b'"):
        broken.lookup("test.b")
    assert "source b: ImportError: no" in broken.unknown_type_hint()


def test_adding_loads_earlier_deferred_sources_first_so_they_keep_their_ids():
    reg = Registry()
    reg.defer(lambda r: r.add(_make(type_id="test.first"), origin="first"), ["test.first"])
    clash = type("Clash", (NodeType,), {"type_id": "test.first", "title": "C", "category": "T", "description": "d",
                                        "run": lambda self, ctx, params: {}})
    with pytest.raises(TypeError, match="already used"):
        reg.add(clash)
    assert reg.origin("test.first") == "first"


def test_lookup_and_types_hand_out_types_with_their_params_built():
    """Params models build on first use (defer_build), which pydantic does not make thread-safe: the registry
    builds them, under a lock, before handing a type out, so threads validating params never race a build."""

    class LazyParams(BaseModel):
        model_config = ConfigDict(extra="forbid", defer_build=True)
        speed: float = Field(1.0, gt=0)

    class OtherParams(LazyParams):
        count: int = 3

    reg = Registry([_make(type_id="test.lazy", Params=LazyParams), _make(type_id="test.other", Params=OtherParams)])
    assert not LazyParams.__pydantic_complete__ and not OtherParams.__pydantic_complete__
    assert reg.lookup("test.lazy").Params.__pydantic_complete__
    assert not OtherParams.__pydantic_complete__  # only the type handed out
    assert all(cls.Params.__pydantic_complete__ for cls in reg.types().values())
    assert OtherParams.model_validate({"count": 4}).count == 4
