"""What a run gives back: a :class:`GenerationRecord` per generation, and an
:class:`EvolutionResult` at its end."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from skillcompose import FSA

from .evaluation import Faults
from .genome import Genome
from .holds import describe_fresh

__all__ = ["EvolutionResult", "GenerationRecord"]


@dataclass(frozen=True)
class GenerationRecord:
    """One generation: fitness statistics, the best's size, evaluations and timing."""

    generation: int
    best: float
    mean: float
    median: float
    best_size: int
    evaluations: int  # episodes run in this generation
    total_evaluations: int
    evals_per_s: float
    wall_time: float  # seconds since the run started, across resumes
    faults: dict[str, int] = field(default_factory=dict)  # Faults.to_dict() of the generation
    population: int = 0  # its individuals (0 in older runs' records: the config's population)

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass
class EvolutionResult:
    """What :func:`evolve` found."""

    best_fsa: FSA  # simplified unless config.simplify is off; states named Skill_N
    best_fitness: float  # as measured during evolution
    solved: bool
    generations: int  # the index of the last generation evaluated (0: the initial one)
    evaluations: int  # episodes run during evolution (the older name; also ``episodes``)
    wall_time: float
    history: list[GenerationRecord]
    evolved_fsa: FSA  # the best FSA as evolved, before simplification
    best_genome: Genome
    seed: int
    out_dir: Path | None = None
    files: list[Path] = field(default_factory=list)
    unchanged: bool = False  # a resumed run that had finished: nothing done (``files``: the
    # exported FSAs it found deleted and wrote again)
    budget: int = 0  # the generation budget
    run_command: str = ""  # a command line that runs the exported FSA on its task
    faults: Faults = field(default_factory=Faults)  # over the whole run
    fresh: dict[str, Any] = field(default_factory=dict)  # see check_fresh (empty: not run)
    # "holds": solved means the exported FSA held on fresh episodes (``fresh``, kind
    # "holds"); "evaluation": solved when an evaluation reached the target (the paper)
    solved_by: str = "evaluation"
    genome_evaluations: int = 0  # genomes evaluated to rank them (what max_evaluations bounds)
    # what ended the run: "solved", or the budget it used: "generations", "evaluations" or
    # "episodes" (see skillcompose.evolve.budgets)
    stopped_by: str = ""
    # each budget's limit (None: none) and what the run used of it:
    # {"generations": {"limit": 1000, "used": 37}, "evaluations": {...}, "episodes": {...}}
    budgets: dict[str, dict[str, int | None]] = field(default_factory=dict)

    @property
    def episodes(self) -> int:
        """Episodes of evaluations, confirmations and holds tests (what max_episodes
        bounds; ``evaluations`` is the same count under its older name)."""
        return self.evaluations

    def _repr_html_(self) -> str:
        """In a notebook: the summary, the fitness per generation and the best FSA."""
        from skillcompose.display import html_table
        from skillcompose.draw import to_svg

        from .rundir import history_svg

        rows = [
            ("solved", self.solved), ("best fitness", f"{self.best_fitness:g}"),
            ("generations", f"{self.generations} of {self.budget}"),
            ("evaluations", self._used("evaluations", self.genome_evaluations)),
            ("episodes", self._used("episodes", self.evaluations)),
            ("ended by", self.stopped_by or "?"), ("wall time", f"{self.wall_time:.1f} s"),
            ("states (evolved)", f"{len(self.best_fsa.states)} "
                                 f"({len(self.evolved_fsa.states)})"),
            ("seed", self.seed),
        ]
        if self.fresh:
            rows.append(("fresh episodes", describe_fresh(self.fresh)))
            rows.append(("solved means", "it holds on fresh episodes"
                         if self.solved_by == "holds" else
                         "an evaluation reached the target (the paper's criterion)"))
        if self.faults.total:
            rows.append(("faults", self.faults.describe()))
        if self.out_dir is not None:
            rows.append(("run directory", self.out_dir))
        return (html_table(("", ""), rows) + history_svg([r.to_dict() for r in self.history])
                + to_svg(self.best_fsa))

    def _used(self, budget: str, used: int) -> str:
        limit = self.budgets.get(budget, {}).get("limit")
        return f"{used:,}" if limit is None else f"{used:,} of {limit:,}"

    @property
    def nothing_succeeded(self) -> bool:
        """Every evaluation of the run failed (raised in every episode, timed out, or killed
        its worker): nothing was learnt about the task."""
        return self.faults.jobs > 0 and self.faults.failed == self.faults.jobs
