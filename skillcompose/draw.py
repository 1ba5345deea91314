"""Drawing FSAs: Graphviz DOT and Mermaid text, and SVG/PNG through the ``dot`` program.

The drawings follow the paper's figures 6, 9 and 11: one node per state labelled with its
name and skill, the start state marked in red, edges labelled with outcomes, and the
terminal outcomes as boxes. ``timeout`` is implicit (every state can time out) and not drawn.
"""

from __future__ import annotations

import shutil
import subprocess
from collections import defaultdict
from pathlib import Path
from typing import Any

from .errors import SkillcomposeError
from .fsa import FSA

__all__ = ["DrawingError", "render", "to_dot", "to_mermaid"]


class DrawingError(SkillcomposeError):
    """A drawing cannot be produced (no ``dot`` program, an unknown format)."""


def _q(text: str) -> str:
    escaped = str(text).replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
    return f'"{escaped}"'


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.3g}"
    return str(v)


def to_dot(fsa: FSA, *, params: bool = True, title: str | None = None) -> str:
    """The FSA in Graphviz DOT. Parallel edges to one target merge into one labelled edge."""
    lines = [f"digraph {_q(fsa.name or 'fsa')} {{"]
    lines.append("  rankdir=LR;")
    lines.append('  node [shape=ellipse, fontname="Helvetica"];')
    lines.append('  edge [fontname="Helvetica", fontsize=10];')
    label = title if title is not None else fsa.name
    if label:
        lines.append(f"  labelloc=t; label={_q(label)};")
    for sname, st in fsa.states.items():
        text = sname if sname.startswith(st.skill) else f"{sname}\n({st.skill})"
        if params and st.params:
            text += "\n" + ", ".join(f"{k}={_fmt(v)}" for k, v in st.params.items())
        attrs = [f"label={_q(text)}"]
        if sname == fsa.start:
            attrs += ["color=red", "penwidth=2.5", "fontcolor=red"]
        lines.append(f"  {_q(sname)} [{', '.join(attrs)}];")
    used_terminals = {
        t for st in fsa.states.values() for t in st.transitions.values() if t in fsa.terminals
    }
    for t in fsa.terminals:
        if t in used_terminals:
            lines.append(
                f"  {_q('__' + t)} [label={_q(t)}, shape=box, style=rounded];"
            )
    for sname, st in fsa.states.items():
        grouped: dict[str, list[str]] = defaultdict(list)
        for outcome, target in st.transitions.items():
            grouped[target].append(outcome)
        for target, outs in grouped.items():
            node = "__" + target if target in fsa.terminals else target
            lines.append(f"  {_q(sname)} -> {_q(node)} [label={_q(', '.join(outs))}];")
    lines.append("}")
    return "\n".join(lines) + "\n"


def to_mermaid(fsa: FSA) -> str:
    """The FSA as a Mermaid ``stateDiagram-v2``."""
    ids = {s: f"s{k}" for k, s in enumerate(fsa.states)}
    lines = ["stateDiagram-v2"]
    for sname, st in fsa.states.items():
        lines.append(f'  state "{sname} ({st.skill})" as {ids[sname]}')
    lines.append(f"  [*] --> {ids[fsa.start]}")
    for sname, st in fsa.states.items():
        grouped: dict[str, list[str]] = defaultdict(list)
        for outcome, target in st.transitions.items():
            grouped[target].append(outcome)
        for target, outs in grouped.items():
            if target in fsa.terminals:
                lines.append(f"  {ids[sname]} --> [*] : {', '.join(outs)} → {target}")
            else:
                lines.append(f"  {ids[sname]} --> {ids[target]} : {', '.join(outs)}")
    lines.append(f"  classDef start stroke:red,stroke-width:3px\n  class {ids[fsa.start]} start")
    return "\n".join(lines) + "\n"


def render(fsa: FSA, out: str | Path, *, params: bool = True) -> Path:
    """Write a drawing; the format comes from the suffix: .dot, .mmd, .svg, .png, .pdf."""
    out = Path(out)
    fmt = out.suffix.lower().lstrip(".")
    out.parent.mkdir(parents=True, exist_ok=True)
    if fmt in ("dot", "gv"):
        out.write_text(to_dot(fsa, params=params), encoding="utf-8")
        return out
    if fmt in ("mmd", "mermaid"):
        out.write_text(to_mermaid(fsa), encoding="utf-8")
        return out
    if fmt not in ("svg", "png", "pdf"):
        raise DrawingError(
            f"cannot draw to {out.name}: use a .dot, .mmd, .svg, .png or .pdf file name"
        )
    dot = shutil.which("dot")
    if dot is None:
        raise DrawingError(
            f"drawing {out.name} needs the Graphviz `dot` program, which is not installed; "
            "install it (Debian/Ubuntu: `apt-get install graphviz`, macOS: `brew install "
            "graphviz`), or write a .dot or .mmd file instead"
        )
    proc = subprocess.run(
        [dot, f"-T{fmt}", "-o", str(out)],
        input=to_dot(fsa, params=params), text=True, capture_output=True, timeout=60,
    )
    if proc.returncode != 0:
        raise DrawingError(f"`dot` failed drawing {out.name}: {proc.stderr.strip()}")
    return out
