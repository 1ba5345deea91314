"""Drawing FSAs: Graphviz DOT and Mermaid text, and SVG/PNG through the ``dot`` program.

The drawings follow the paper's figures 6, 9 and 11: one node per state labelled with its
name and skill, the start state marked in red, edges labelled with outcomes, and the
terminal outcomes as boxes. ``timeout`` is implicit (every state can time out) and not drawn.
Pictures (SVG, PNG, PDF) come from Graphviz ``dot`` when it is installed, else from
matplotlib with a layered layout of its own.

Whatever the names hold, the text is valid: nodes have generated ids (``s0``, ``s1``, ... for
states, ``t0``, ... for terminal outcomes), so no state can merge with another node, and names
appear only in labels, escaped for DOT (``\\"``) or Mermaid (entity codes such as ``#34;``);
control characters show as escapes (``\\x1b``). A drawing is written beside its file and
renamed over it, never over the FSA file it draws.
"""

from __future__ import annotations

import io
import os
import shutil
import subprocess
from collections import Counter, defaultdict
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .errors import SkillcomposeError, one_line
from .files import temporary_beside

if TYPE_CHECKING:  # drawing needs only an FSA's attributes: fsa.py may import this module
    from .fsa import FSA, State

__all__ = ["DrawingError", "draw_matplotlib", "layers", "render", "to_dot", "to_mermaid",
           "to_svg"]


class DrawingError(SkillcomposeError):
    """A drawing cannot be produced (no ``dot`` program, an unknown format)."""


def _q(text: str) -> str:
    """``text`` as a quoted DOT string: line breaks become label breaks (``\\n``), other
    control characters visible escapes, backslashes and quotes escaped."""
    lines = (one_line(part).replace("\\", "\\\\").replace('"', '\\"')
             for part in str(text).split("\n"))
    return '"' + "\\n".join(lines) + '"'


_MERMAID_PLAIN = frozenset(" _-.,")


def _m(text: str) -> str:
    """``text`` for a Mermaid label: letters, digits, spaces and ``_-.`` as they are, every
    other character as an entity code (``"`` is ``#34;``), control characters as visible
    escapes first; nothing in it can end the label or the statement."""
    return "".join(c if c.isalnum() or c in _MERMAID_PLAIN else f"#{ord(c)};"
                   for c in one_line(str(text)))


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, (list, tuple)):  # a vector parameter: its length, not its numbers
        return f"[{len(v)} values]"
    return str(v)


def _label(sname: str, st: State, params: bool) -> str:
    """A state's label: its lines (name, skill, parameters) each printable as one line."""
    name = one_line(sname)
    text = name if sname.startswith(st.skill) else f"{name}\n({one_line(st.skill)})"
    if params and st.params:
        text += "\n" + one_line(", ".join(f"{k}={_fmt(v)}" for k, v in st.params.items()))
    return text


def _routes(fsa: FSA) -> Iterator[tuple[str, str, str]]:
    """(state, target, its outcomes joined by commas): parallel edges merged."""
    for sname, st in fsa.states.items():
        grouped: dict[str, list[str]] = defaultdict(list)
        for outcome, target in st.transitions.items():
            grouped[target].append(outcome)
        for target, outs in grouped.items():
            yield sname, target, ", ".join(outs)


def _used_terminals(fsa: FSA) -> list[str]:
    used = {t for st in fsa.states.values() for t in st.transitions.values()}
    return [t for t in fsa.terminals if t in used]


def _node_ids(fsa: FSA) -> dict[str, str]:
    """Generated node ids: ``s<k>`` for the k-th state, ``t<k>`` for the k-th terminal outcome
    (distinct whatever the names are)."""
    ids = {s: f"s{k}" for k, s in enumerate(fsa.states)}
    ids.update({t: f"t{k}" for k, t in enumerate(fsa.terminals) if t not in ids})
    return ids


def to_dot(fsa: FSA, *, params: bool = True, title: str | None = None) -> str:
    """The FSA in Graphviz DOT. Parallel edges to one target merge into one labelled edge."""
    lines = [f"digraph {_q(fsa.name or 'fsa')} {{", "  rankdir=LR;",
             '  node [shape=ellipse, fontname="Helvetica"];',
             '  edge [fontname="Helvetica", fontsize=10];']
    label = title if title is not None else fsa.name
    if label:
        lines.append(f"  labelloc=t; label={_q(label)};")
    ids = _node_ids(fsa)
    for sname, st in fsa.states.items():
        attrs = [f"label={_q(_label(sname, st, params))}"]
        if sname == fsa.start:
            attrs += ["color=red", "penwidth=2.5", "fontcolor=red"]
        lines.append(f"  {ids[sname]} [{', '.join(attrs)}];")
    for t in _used_terminals(fsa):
        if t not in fsa.states:
            lines.append(f"  {ids[t]} [label={_q(t)}, shape=box, style=rounded];")
    for sname, target, label in _routes(fsa):
        lines.append(f"  {ids[sname]} -> {ids[target]} [label={_q(label)}];")
    lines.append("}")
    return "\n".join(lines) + "\n"


def to_mermaid(fsa: FSA) -> str:
    """The FSA as a Mermaid ``stateDiagram-v2``."""
    ids = {s: f"s{k}" for k, s in enumerate(fsa.states)}
    lines = ["stateDiagram-v2"]
    for sname, st in fsa.states.items():
        lines.append(f'  state "{_m(sname)} ({_m(st.skill)})" as {ids[sname]}')
    lines.append(f"  [*] --> {ids[fsa.start]}")
    for sname, target, label in _routes(fsa):
        if target in ids:
            lines.append(f"  {ids[sname]} --> {ids[target]} : {_m(label)}")
        else:
            lines.append(f"  {ids[sname]} --> [*] : {_m(label)} → {_m(target)}")
    lines.append(f"  classDef start stroke:red,stroke-width:3px\n  class {ids[fsa.start]} start")
    return "\n".join(lines) + "\n"


def render(
    fsa: FSA, out: str | Path, *, params: bool = True, engine: str = "auto"
) -> Path:
    """Write a drawing; the format comes from the suffix: .dot, .mmd, .svg, .png, .pdf.

    Pictures are laid out by Graphviz ``dot`` when it is installed (``engine="dot"``
    insists on it), else drawn with matplotlib (``engine="matplotlib"``). The drawing is
    written beside ``out`` and renamed onto it: a symbolic link at ``out`` is replaced, not
    written through. Raises :class:`DrawingError` when ``out`` is the file the FSA was read
    from, however it is reached (a link, another spelling of the path).
    """
    out = Path(out)
    fmt = out.suffix.lower().lstrip(".")
    if fmt not in ("dot", "gv", "mmd", "mermaid", "svg", "png", "pdf"):
        raise DrawingError(
            f"cannot draw to {out.name}: use a .dot, .mmd, .svg, .png or .pdf file name"
        )
    if engine not in ("auto", "dot", "matplotlib"):
        raise DrawingError(f"unknown drawing engine {engine!r}: auto, dot or matplotlib")
    _refuse_source(fsa, out)
    if fmt in ("dot", "gv", "mmd", "mermaid"):
        text = to_dot(fsa, params=params) if fmt in ("dot", "gv") else to_mermaid(fsa)
        with temporary_beside(out, suffix=out.suffix) as tmp:
            tmp.write_text(text, encoding="utf-8")
        return out
    dot = shutil.which("dot")
    if engine == "matplotlib" or (engine == "auto" and dot is None):
        with temporary_beside(out, suffix=out.suffix) as tmp:
            draw_matplotlib(fsa, tmp, params=params, fmt=fmt)
        return out
    if dot is None:
        raise DrawingError(
            f"drawing {out.name} with Graphviz needs the `dot` program, which is not "
            "installed; install it (Debian/Ubuntu: `apt-get install graphviz`, macOS: `brew "
            "install graphviz`), or draw with matplotlib (engine='matplotlib')"
        )
    with temporary_beside(out, suffix=out.suffix) as tmp:
        proc = subprocess.run(
            [dot, f"-T{fmt}", "-o", str(tmp)],
            input=to_dot(fsa, params=params), text=True, capture_output=True, timeout=60,
        )
        if proc.returncode != 0:
            raise DrawingError(f"`dot` failed drawing {out.name}: {proc.stderr.strip()}")
    return out


def _refuse_source(fsa: FSA, out: Path) -> None:
    """Raise :class:`DrawingError` when ``out`` names the file ``fsa`` was read from."""
    source = fsa.path
    if source is None:
        return
    try:
        same = os.path.samefile(out, source)
    except OSError:  # one of them does not exist (or cannot be looked at): not the same
        same = False
    if same:
        raise DrawingError(
            f"cannot draw to {out}: it is the FSA file being drawn ({source}); name another "
            "output file"
        )


def to_svg(fsa: FSA, *, params: bool = True) -> str:
    """The FSA as SVG text (what a notebook shows): laid out by Graphviz ``dot`` when it is
    installed, else drawn with matplotlib."""
    dot = shutil.which("dot")
    if dot is not None:
        proc = subprocess.run([dot, "-Tsvg"], input=to_dot(fsa, params=params), text=True,
                              capture_output=True, timeout=60)
        if proc.returncode == 0:
            return proc.stdout
    buffer = io.StringIO()
    draw_matplotlib(fsa, buffer, params=params, fmt="svg")
    return buffer.getvalue()


def layers(fsa: FSA) -> dict[str, tuple[int, int]]:
    """(column, row) of every state and terminal outcome for a left-to-right drawing:
    the column is the breadth-first depth from the start; terminals take the last column;
    states the start cannot reach come after the reachable ones."""
    depth = {fsa.start: 0}
    for s in fsa.reachable():
        for t in fsa.successors(s):
            depth.setdefault(t, depth[s] + 1)
    last = max(depth.values(), default=0)
    for s in fsa.states:
        if s not in depth:
            last += 1
            depth[s] = last
    end = max(depth.values(), default=0) + 1
    pos: dict[str, tuple[int, int]] = {}
    rows: dict[int, int] = defaultdict(int)
    for s in sorted(fsa.states, key=lambda s: depth[s]):
        pos[s] = (depth[s], rows[depth[s]])
        rows[depth[s]] += 1
    for k, t in enumerate(fsa.terminals):
        pos[t] = (end, k)
    return pos


def draw_matplotlib(fsa: FSA, out: str | Path | io.StringIO, *, params: bool = True,
                    fmt: str | None = None) -> Any:
    """A picture of the FSA without Graphviz: states in columns by their distance from the
    start (in red), terminal outcomes (boxes) on the right, one arrow per target labelled
    with its outcomes, self-loops as labels over the state. ``out``: a file (its suffix
    gives the format) or a text buffer with ``fmt="svg"``; returns ``out`` (a path as a
    :class:`~pathlib.Path`)."""
    from matplotlib.figure import Figure
    from matplotlib.patches import FancyArrowPatch

    grid = layers(fsa)
    ncols = max(c for c, _ in grid.values()) + 1
    height = max((r for _, r in grid.values()), default=0) + 1
    col_size = Counter(c for c, _ in grid.values())
    xy = {name: (3.2 * c, (col_size[c] - 1) / 2.0 - r)  # columns centred vertically
          for name, (c, r) in grid.items()}
    fig = Figure(figsize=(max(6.0, 2.4 * ncols), max(3.5, 1.3 * height + 1.5)))
    ax = fig.add_subplot()
    boxes = {}
    for sname, st in fsa.states.items():
        text = _label(sname, st, params)
        colour = "tab:red" if sname == fsa.start else "tab:blue"
        boxes[sname] = ax.annotate(
            text, xy[sname], ha="center", va="center", fontsize=8, zorder=3, parse_math=False,
            bbox={"boxstyle": "round,pad=0.4", "fc": "white", "ec": colour,
                  "lw": 2.0 if sname == fsa.start else 1.0},
        )
    for t in _used_terminals(fsa):
        boxes[t] = ax.annotate(one_line(t), xy[t], ha="center", va="center", fontsize=8,
                               zorder=3, parse_math=False,
                               bbox={"boxstyle": "square,pad=0.4", "fc": "#eef7ee",
                                     "ec": "tab:green"})
    for sname, target, label in _routes(fsa):
        (x0, y0), (x1, y1) = xy[sname], xy[target]
        if target == sname:
            ax.annotate(f"↻ {one_line(label)}", (x0, y0 + 0.42), ha="center", fontsize=7,
                        color="dimgray", parse_math=False)
            continue
        back = x1 <= x0  # edges going back or sideways bend more
        rad = 0.35 if back else 0.12
        ax.add_patch(FancyArrowPatch(
            (x0, y0), (x1, y1), connectionstyle=f"arc3,rad={rad}", arrowstyle="-|>",
            mutation_scale=10, color="gray", lw=1.0, shrinkA=28, shrinkB=28, zorder=1,
        ))
        mx, my = (x0 + x1) / 2, (y0 + y1) / 2
        dx, dy = x1 - x0, y1 - y0  # the arc's bulge is to the right of the direction
        ax.annotate(one_line(label), (mx + rad * dy / 2, my - rad * dx / 2), ha="center",
                    va="center", fontsize=7, color="dimgray", zorder=2, parse_math=False,
                    bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none",
                          "alpha": 0.8})
    xs, ys = zip(*xy.values(), strict=True)
    ax.set_xlim(min(xs) - 1.6, max(xs) + 1.6)
    ax.set_ylim(min(ys) - 1.0, max(ys) + 1.0)
    ax.axis("off")
    ax.set_title(f"{one_line(fsa.name or 'FSA')}: start in red, terminal outcomes in green; "
                 f"runs over {fsa.step_limit} steps end in timeout", fontsize=9,
                 parse_math=False)
    fig.tight_layout()
    if isinstance(out, io.StringIO):
        fig.savefig(out, format=fmt or "svg")
        return out
    path = Path(out)
    fig.savefig(path, dpi=110, format=fmt)
    return path
