"""Drawings are valid DOT and Mermaid whatever the names hold, and never overwrite the FSA
file they draw."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

from skillcompose import FSA, State, load_fsa
from skillcompose.cli import main
from skillcompose.draw import DrawingError, render, to_dot, to_mermaid

UNDERSCORED = FSA({
    "A": State("FindBlock", {}, {"success": "__success"}),
    "__success": State("PickBlock", {}, {"success": "success", "failure": "failure"}),
}, "A")
ODD = 'a"b\\c;#d{e}[f]<g>%%h:-->i'
QUOTED = FSA({
    ODD: State('Find"Block', {"s": 'x"y\\', "t": "é\x1b"}, {"success": "B", "fail": "failure"}),
    "B": State("Skill", {}, {"success": ODD, "failure": "success"}),
}, ODD, name='n"ame')


def test_a_state_named_like_a_terminal_node_stays_its_own_node() -> None:
    dot = to_dot(UNDERSCORED)
    assert dot.splitlines()[4:] == [
        '  s0 [label="A\\n(FindBlock)", color=red, penwidth=2.5, fontcolor=red];',
        '  s1 [label="__success\\n(PickBlock)"];',
        '  t0 [label="success", shape=box, style=rounded];',
        '  t1 [label="failure", shape=box, style=rounded];',
        '  s0 -> s1 [label="success"];',
        '  s1 -> t0 [label="success"];',
        '  s1 -> t1 [label="failure"];',
        "}",
    ]


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # pydot's own, on pyparsing
def test_dot_escapes_every_name_and_parses() -> None:
    dot = to_dot(QUOTED)
    assert dot.splitlines()[0] == 'digraph "n\\"ame" {'
    assert '  s0 [label="a\\"b\\\\c;#d{e}[f]<g>%%h:-->i\\n(Find\\"Block)\\ns=x\\"y\\\\, ' \
        't=é\\\\x1b", color=red' in dot
    assert "\x1b" not in dot
    pydot = pytest.importorskip("pydot")
    (graph,) = pydot.graph_from_dot_data(dot)
    assert sorted(n.get_name() for n in graph.get_nodes() if n.get_name()[0] in "st") == [
        "s0", "s1", "t0", "t1"]
    assert len(graph.get_edges()) == 4


def test_mermaid_writes_names_as_entity_codes() -> None:
    assert to_mermaid(QUOTED).splitlines() == [
        "stateDiagram-v2",
        '  state "a#34;b#92;c#59;#35;d#123;e#125;#91;f#93;#60;g#62;#37;#37;h#58;--#62;i '
        '(Find#34;Block)" as s0',
        '  state "B (Skill)" as s1',
        "  [*] --> s0",
        "  s0 --> s1 : success",
        "  s0 --> [*] : fail → failure",
        "  s1 --> s0 : success",
        "  s1 --> [*] : failure → success",
        "  classDef start stroke:red,stroke-width:3px",
        "  class s0 start",
    ]
    # a label is one quoted string: no quote, line break or control character inside
    for line in to_mermaid(QUOTED).splitlines():
        assert line.isprintable()
        if line.lstrip().startswith("state "):
            assert re.fullmatch(r'  state "[^"]*" as s\d+', line)


def test_pictures_show_names_as_text(tmp_path: Path) -> None:
    dollars = FSA({"Cost$x$_$": State("S$", {"p": "$\\frac$"}, {"ok": "success"})},
                  "Cost$x$_$", name="$a$")
    assert render(dollars, tmp_path / "d.svg", engine="matplotlib").stat().st_size > 1000


def _write_fsa(path: Path) -> str:
    text = "format: 1\nstart: A\nstates:\n  A: {skill: FindBlock, transitions: " \
        "{success: success}}\n"
    path.write_text(text)
    return text


def test_show_refuses_mermaid_to_a_file_of_another_format(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    src = tmp_path / "f.yaml"
    _write_fsa(src)
    out = tmp_path / "x.dot"
    assert main(["show", str(src), "--mermaid", "-o", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"skillcompose show: error: --mermaid writes Mermaid, but -o {out} asks for DOT (with "
        "-o the file's suffix picks the format); name a .mmd file, or leave out --mermaid\n")
    assert not out.exists()
    assert main(["show", str(src), "--mermaid", "-o", str(tmp_path / "x.mmd")]) == 0
    assert (tmp_path / "x.mmd").read_text().startswith("stateDiagram-v2\n")
    assert main(["show", str(src), "-o", str(tmp_path / "y.mmd")]) == 0  # the suffix says
    assert (tmp_path / "y.mmd").read_text() == (tmp_path / "x.mmd").read_text()


@pytest.mark.parametrize("how", ["symlink", "hardlink", "relative symlink"])
def test_show_never_writes_over_the_file_it_draws(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], how: str,
) -> None:
    src = tmp_path / "mine.yaml"
    text = _write_fsa(src)
    out = tmp_path / "sub" / "link.dot"
    out.parent.mkdir()
    if how == "symlink":
        out.symlink_to(src)
    elif how == "hardlink":
        os.link(src, out)
    else:
        out.symlink_to(Path("..") / "mine.yaml")
    assert main(["show", str(src), "-o", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"skillcompose show: error: cannot draw to {out}: it is the FSA file being drawn "
        f"({src}); name another output file\n")
    assert src.read_text() == text
    with pytest.raises(DrawingError, match="it is the FSA file being drawn"):
        render(load_fsa(src), out)


def test_a_drawing_replaces_a_link_instead_of_writing_through_it(tmp_path: Path) -> None:
    src = tmp_path / "f.yaml"
    _write_fsa(src)
    other = tmp_path / "notes.txt"
    other.write_text("keep me\n")
    link = tmp_path / "d.dot"
    link.symlink_to(other)
    assert main(["show", str(src), "-o", str(link)]) == 0
    assert other.read_text() == "keep me\n"
    assert not link.is_symlink() and link.read_text().startswith('digraph "fsa" {')
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.dot", "f.yaml", "notes.txt"]
