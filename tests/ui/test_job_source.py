"""The job panel's source view without a browser: G-code from a node's text or its file (inside the
graph's folder only), segment-table rows, the segment names otherwise; every line escaped."""

from __future__ import annotations

import re

from flowmc.graph import Graph, Node
from flowmc.ui.job_source import SourceView


def _shown(html: str) -> list[tuple[int, bool, str]]:
    return [(int(n), on == "1", text) for n, on, text in
            re.findall(r"data-n='(\d+)' data-current='(\d)'.*?</span>(.*?)</div>", html)]


def test_gcode_file_lines_around_the_current_one_escaped(tmp_path):
    (tmp_path / "part.ngc").write_text("".join(f"G1 X{i} (<b>{i}</b>)\n" for i in range(1, 21)))
    graph = Graph(nodes=[Node(id="g", type="path.gcode_in", params={"file": "part.ngc"})])
    shown = _shown(SourceView(graph, tmp_path).html(("part.ngc:9", "part.ngc:10"), 1, None))
    assert [n for n, _on, _t in shown] == list(range(8, 15))  # 2 before, 4 after
    assert [n for n, on, _t in shown if on] == [10]
    assert shown[2][2] == "G1 X10 (&lt;b&gt;10&lt;/b&gt;)"  # text, never markup
    # a program stop's line wins over the segment's own (held at the stop's line)
    assert [n for n, on, _t in _shown(SourceView(graph, tmp_path).html(("part.ngc:9",), 0, 11)) if on] == [11]


def test_a_file_outside_the_graph_folder_is_not_read(tmp_path):
    (tmp_path / "secret.ngc").write_text("G1 X1\nG1 X2\n")
    inner = tmp_path / "graph"
    inner.mkdir()
    graph = Graph(nodes=[Node(id="g", type="path.gcode_in", params={"file": "../secret.ngc"})])
    html = SourceView(graph, inner).html(("../secret.ngc:2",), 0, None)
    assert "G1 X2" not in html and "data-kind='segments'" in html  # the segment names instead


def test_segment_table_row_and_plain_segment_names(tmp_path):
    rows = [{"type": "line", "end": [i, 0, 0]} for i in range(1, 6)]
    graph = Graph(nodes=[Node(id="t", type="path.segment_table", params={"rows": rows})])
    view = SourceView(graph, tmp_path)
    shown = _shown(view.html(tuple(f"row {i}" for i in range(1, 6)), 3, None))
    assert [n for n, on, _t in shown if on] == [4] and "end=[4,0,0]" in shown[[n for n, *_ in shown].index(4)][2]
    html = view.html(("<script>x</script>", "b"), 0, None)
    assert "<script>" not in html and "&lt;script&gt;" in html
    assert "flowmc-src-line" not in view.html(("a",), None, None)  # before the program: nothing
