"""Graph file model: canonical, atomic saving and loading that refuses what it does not know."""

from __future__ import annotations

import json
import os

import pytest
from pydantic import ValidationError

import flowmc
from flowmc import migrations
from flowmc.errors import GraphError
from flowmc.graph import dumps, json_schema, load, loads, save


def _demo():
    g = flowmc.GraphBuilder(title="Demo", description="A test graph")
    a = g.add("basic.number", id="zeta", value=2.5, pos=(10, 20))
    s = g.add("basic.add", id="alpha", b=3, pos=(300.5, -4))
    r = g.add("basic.report", id="mid", names=["first", "second"], title="Totals")
    g.wire(a.value, s.a)
    g.wire(s.result, r.first)
    g.wire(a.value, r.second)
    g.input("offset", "Number", [s.b], default=1.5, description="added")
    g.output("sum", "Number", s.result, description="the sum")
    return g.build()


def test_load_save_round_trip_is_byte_identical(tmp_path):
    first = tmp_path / "a.flowmc.json"
    save(_demo(), first)
    second = tmp_path / "b.flowmc.json"
    save(load(first), second)
    assert first.read_bytes() == second.read_bytes()
    assert load(second).model_dump() == load(first).model_dump()


def test_saving_is_canonical_whatever_the_input_order(tmp_path):
    graph = _demo()
    shuffled = graph.model_copy(deep=True)
    shuffled.nodes.reverse()
    shuffled.wires.reverse()
    shuffled.nodes[0].params = dict(reversed(list(shuffled.nodes[0].params.items())))
    assert dumps(shuffled) == dumps(graph)
    data = json.loads(dumps(graph))
    assert [n["id"] for n in data["nodes"]] == ["alpha", "mid", "zeta"]
    assert list(data) == ["schema_version", "title", "description", "nodes", "wires", "interface"]
    assert data["nodes"][2]["pos"] == [10.0, 20.0]


def test_hand_written_file_is_normalised_once_then_stable(tmp_path):
    text = ('{"wires": [], "schema_version": 1, "nodes": [{"type": "basic.number", "id": "b", "params": {"value": 1}},'
            ' {"id": "a", "type": "basic.text", "params": {"value": "é"}, "pos": [1, 2]}]}')
    path = tmp_path / "hand.flowmc.json"
    path.write_text(text, encoding="utf-8")
    save(load(path), path)
    once = path.read_bytes()
    save(load(path), path)
    assert path.read_bytes() == once
    assert "é" in once.decode("utf-8")


def test_save_is_atomic_and_leaves_no_temp_files(tmp_path):
    path = tmp_path / "g.flowmc.json"
    save(_demo(), path)
    before = path.read_bytes()
    bad = _demo()
    bad.nodes[0].params["value"] = float("nan")  # JSON cannot hold NaN: refused before writing
    with pytest.raises(GraphError, match="cannot be saved"):
        save(bad, path)
    assert path.read_bytes() == before
    assert os.listdir(tmp_path) == ["g.flowmc.json"]


def test_unknown_field_is_refused_with_file_and_json_path(tmp_path):
    path = tmp_path / "bad.flowmc.json"
    data = json.loads(dumps(_demo()))
    data["nodes"][1]["colour"] = "red"
    data["wires"][0]["via"] = "x"
    path.write_text(json.dumps(data))
    with pytest.raises(GraphError) as info:
        load(path)
    err = info.value
    assert str(path) in str(err)
    messages = [i.message for i in err.issues]
    assert any("$.nodes[1]" in m and "(node 'mid')" in m and "unknown field 'colour'" in m for m in messages)
    assert any("$.wires[0]" in m and "'via'" in m for m in messages)
    assert {i.location for i in err.issues} == {("nodes", 1, "colour"), ("wires", 0, "via")}


def test_unknown_schema_version_is_refused(tmp_path):
    path = tmp_path / "future.flowmc.json"
    path.write_text('{"schema_version": 7, "nodes": []}')
    with pytest.raises(GraphError, match=r"schema_version: unknown schema version 7 \(this flowmc reads 2\)") as info:
        load(path)
    assert str(path) in str(info.value)
    with pytest.raises(GraphError, match="missing or not an integer"):
        loads('{"nodes": []}')


def test_migrations_are_applied_in_one_place(monkeypatch):
    def from_zero(raw):
        raw = dict(raw)
        raw["title"] = raw.pop("name")
        return {**raw, "schema_version": 1}

    monkeypatch.setitem(migrations.MIGRATIONS, 0, from_zero)
    graph = loads('{"schema_version": 0, "name": "old"}')
    assert graph.title == "old" and graph.schema_version == 2  # then 1 -> 2 (bodies, the view section)


def test_malformed_json_names_file_line_and_column(tmp_path):
    path = tmp_path / "broken.flowmc.json"
    path.write_text('{\n  "schema_version": 1,\n  "nodes": [,]\n}')
    with pytest.raises(GraphError) as info:
        load(path)
    assert str(info.value).startswith(f"{path}:3:")
    assert "line 3, column 13" in str(info.value)


def test_missing_file_and_wrong_value_types(tmp_path):
    with pytest.raises(GraphError, match="no such graph file"):
        load(tmp_path / "nope.flowmc.json")
    with pytest.raises(GraphError, match=r"\$\.nodes\[0\]\.pos"):
        loads('{"schema_version": 1, "nodes": [{"id": "a", "type": "t", "pos": "left"}]}')
    with pytest.raises(GraphError, match=r"\$\.wires\[0\]\.from"):
        loads('{"schema_version": 1, "wires": [{"from": "no-port", "to": "a.b"}]}')
    with pytest.raises(GraphError, match="NaN is not valid JSON"):
        loads('{"schema_version": 1, "title": NaN}')


def test_json_schema_is_the_model():
    schema = json_schema()
    assert schema["additionalProperties"] is False
    assert set(schema["properties"]) == {"schema_version", "title", "description", "nodes", "wires", "interface", "view"}
    node = schema["$defs"]["Node"]
    assert node["additionalProperties"] is False and set(node["required"]) == {"id", "type"}
    wire = schema["$defs"]["Wire"]
    assert set(wire["properties"]) == {"from", "to"}
    assert "Path" in schema["$defs"]["InterfaceInput"]["properties"]["type"]["enum"]


def test_schema_matches_the_snapshot():
    """A schema change is a file-format change: update tests/core/snapshots/graph.schema.json on purpose."""
    from pathlib import Path

    snapshot = Path(__file__).parent / "snapshots" / "graph.schema.json"
    assert json.loads(snapshot.read_text()) == json_schema()


def test_an_edited_position_saves_canonically(tmp_path):
    """The editor moves nodes by assignment: what it saves must still load and save byte-identical."""
    g = flowmc.GraphBuilder(title="moved")
    g.add("basic.number", id="n", value=1.0)
    graph = g.build()
    graph.nodes[0].pos = (3, -52)  # ints from a drag: stored as floats
    flowmc.save(graph, tmp_path / "moved.flowmc.json")
    text = (tmp_path / "moved.flowmc.json").read_text()
    assert flowmc.dumps(flowmc.load(tmp_path / "moved.flowmc.json")) == text
    with pytest.raises(ValidationError):
        graph.nodes[0].pos = ("left", 0)
