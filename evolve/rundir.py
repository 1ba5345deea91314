"""The run directory: what an evolution writes as it goes, and its checkpoints.

Files (all written atomically, so a killed run leaves no torn file but ``history.jsonl``,
which a resume rewrites from the checkpoint):

- ``best.yaml``      the best FSA so far, editable, in the runtime's file format; its
                     fitness and lineage are under ``meta:``. At the end: the simplified FSA.
- ``best_evolved.yaml`` the best FSA as evolved, before simplification (at the end).
- ``best.dot`` / ``best.png`` its drawing (Graphviz text; PNG at checkpoints and the end).
- ``history.jsonl``  one JSON line per generation: best / mean / median fitness, best
                     size, evaluations, evaluations/s, wall time.
- ``fitness.png``    the fitness plot.
- ``run.json``       the task, seed, backend and settings of the run.
- ``checkpoint.pkl`` everything needed to continue, every ``checkpoint_every`` generations.
"""

from __future__ import annotations

import json
import os
import pickle
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from skillcompose import FSA, save_fsa
from skillcompose.registry import Registry

from .errors import CheckpointError

__all__ = ["RunDir", "draw_fsa", "fsa_dot", "plot_history"]

CHECKPOINT_VERSION = 1


def _atomic_write(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


class RunDir:
    """Writes one run's files under ``path``."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.best_yaml = self.path / "best.yaml"
        self.best_evolved_yaml = self.path / "best_evolved.yaml"
        self.best_dot = self.path / "best.dot"
        self.best_png = self.path / "best.png"
        self.history = self.path / "history.jsonl"
        self.fitness_png = self.path / "fitness.png"
        self.run_json = self.path / "run.json"
        self.checkpoint = self.path / "checkpoint.pkl"

    def create(self, run_info: Mapping[str, Any]) -> None:
        self.path.mkdir(parents=True, exist_ok=True)
        if self.checkpoint.exists():
            raise CheckpointError(
                f"{self.path} holds a run already (checkpoint.pkl); continue it with "
                f"--resume {self.path}, or choose another --out directory"
            )
        _atomic_write(self.run_json, json.dumps(run_info, indent=2, default=str).encode())
        self.history.write_text("")

    def update_run_info(self, changes: Mapping[str, Any]) -> None:
        """Add or replace top-level entries of ``run.json`` (the result, at the end)."""
        info = self.load_run_info()
        info.update(changes)
        _atomic_write(self.run_json, json.dumps(info, indent=2, default=str).encode())

    def append_history(self, record: Mapping[str, Any]) -> None:
        with self.history.open("a", encoding="utf-8") as f:
            f.write(json.dumps(record) + "\n")

    def rewrite_history(self, records: Sequence[Mapping[str, Any]]) -> None:
        text = "".join(json.dumps(r) + "\n" for r in records)
        _atomic_write(self.history, text.encode())

    def write_best(
        self, fsa: FSA, registry: Registry, header: str, path: Path | None = None
    ) -> None:
        save_fsa(fsa, path or self.best_yaml, registry, header=header)
        try:
            from skillcompose.draw import to_dot

            dot = to_dot(fsa)
        except ImportError:  # an older runtime without skillcompose.draw
            dot = fsa_dot(fsa)
        _atomic_write(self.best_dot, dot.encode())

    def save_checkpoint(self, state: Mapping[str, Any]) -> None:
        data = pickle.dumps({"version": CHECKPOINT_VERSION, **state}, protocol=4)
        _atomic_write(self.checkpoint, data)

    def load_checkpoint(self) -> dict[str, Any]:
        if not self.checkpoint.exists():
            raise CheckpointError(
                f"{self.path} has no checkpoint.pkl to resume from; a run writes one every "
                "checkpoint_every generations (start it with --out DIR)"
            )
        try:
            state = pickle.loads(self.checkpoint.read_bytes())
        except Exception as exc:
            raise CheckpointError(f"{self.checkpoint} cannot be read: {exc}") from exc
        if not isinstance(state, dict) or state.get("version") != CHECKPOINT_VERSION:
            raise CheckpointError(
                f"{self.checkpoint} was written by another version of evolve; start afresh"
            )
        return state

    def load_run_info(self) -> dict[str, Any]:
        try:
            info = json.loads(self.run_json.read_text())
        except (OSError, ValueError) as exc:
            raise CheckpointError(f"{self.run_json} cannot be read: {exc}") from exc
        if not isinstance(info, dict):
            raise CheckpointError(f"{self.run_json} is not a JSON object")
        return info

    def plots(self, history: Sequence[Mapping[str, Any]], fsa: FSA | None) -> None:
        if history:
            plot_history(history, self.fitness_png)
        if fsa is not None:
            draw_fsa(fsa, self.best_png)


def fsa_dot(fsa: FSA) -> str:
    """Graphviz text of an FSA: states as boxes, terminal outcomes as double circles."""
    lines = [f'digraph "{fsa.name or "fsa"}" {{', "  rankdir=LR;", "  node [shape=box];"]
    lines.append(f'  __start [shape=point]; __start -> "{fsa.start}";')
    for t in fsa.terminals:
        lines.append(f'  "{t}" [shape=doublecircle];')
    for sname, st in fsa.states.items():
        params = ", ".join(
            f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}" for k, v in st.params.items()
        )
        label = sname + (f"\\n{params}" if params else "")
        lines.append(f'  "{sname}" [label="{label}"];')
        for o, t in st.transitions.items():
            lines.append(f'  "{sname}" -> "{t}" [label="{o}"];')
    lines.append("}")
    return "\n".join(lines) + "\n"


def draw_fsa(fsa: FSA, path: str | os.PathLike[str]) -> None:
    """A picture of an FSA (Graphviz when installed, else matplotlib): see
    :func:`skillcompose.draw.render`."""
    from skillcompose.draw import render

    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:  # written aside and renamed, so a reader never sees half a picture
        render(fsa, tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def plot_history(history: Sequence[Mapping[str, Any]], path: str | os.PathLike[str]) -> None:
    """Best, mean and median fitness per generation (matplotlib's object API: no pyplot
    state, no backend switch)."""
    from matplotlib.figure import Figure

    gens = [r["generation"] for r in history]
    fig = Figure(figsize=(7, 4))
    ax = fig.add_subplot()
    for key in ("best", "median", "mean"):
        ax.plot(gens, [r[key] for r in history], label=key)
    ax.set_xlabel("generation")
    ax.set_ylabel("fitness")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    _save_fig(fig, Path(path))


def _save_fig(fig: Any, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".png", dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=90)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
