"""What a run is, settled before it starts: :func:`evolve`'s arguments checked, the defaults
filled in, the seed FSA read (from its file, or from a resumed run's checkpoint) and the
run's record made (:class:`Plan`)."""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from skillcompose import FSA, load_fsa, loads_fsa
from skillcompose.checks import whole_in
from skillcompose.limits import MAX_WORKERS
from skillcompose.task import Task

from .config import DEFAULT_PRESET, EvolutionConfig, preset_settings
from .errors import CheckpointError, EvolutionError
from .genome import Genome, SkillSet
from .resume import run_record

if TYPE_CHECKING:
    from .rundir import RunDir

__all__ = ["Plan", "check_arguments", "make_plan", "takes_vectors", "task_preset"]


def takes_vectors(task: Task) -> bool:
    """Whether a skill evolution may place on ``task`` takes a vector parameter (a
    network's weights): the default preset for such a noisy task is ``push``, whose every
    mutated node's parameters move by small steps, judged on 20 shared episodes. The
    islands of :data:`~skillcompose.evolve.config.NOISY_DEFAULT` perturb a node's numbers
    one child in three with steps twice as large; on moving to push's held-out seeds they
    solved none of 5 with ``push``'s individuals and 4 of 5 with four times its episodes,
    where ``push`` solved all 5 (docs/evolve.md, "The default for noisy tasks")."""
    return any(p.size is not None for name in task.skill_names()
               for p in task.registry.spec(name).params)


def task_preset(name: str, task: Task) -> dict[str, Any]:
    """The settings of preset ``name`` for ``task``: ``default`` as it resolves for the
    task (:func:`~skillcompose.evolve.config.preset_settings`), the others as listed."""
    return preset_settings(name, task.deterministic, takes_vectors(task))


@dataclass(frozen=True)
class Plan:
    """A run as it was asked for: every value checked, every default filled in."""

    task: Task
    cfg: EvolutionConfig
    seed: int
    skills: SkillSet
    backend: str
    workers: int | None
    trials: int  # episodes per evaluation (1 on a deterministic task)
    simplify: bool
    simplify_trials: int  # the trials simplification runs (1 on a deterministic task)
    check_trials: int  # the final fresh check's episodes (at most 1 on a deterministic task)
    stream: TextIO | None  # where progress goes
    record: dict[str, Any]  # what the run is, as the checkpoint and run.json record it
    seed_text: str | None  # the seed FSA file's text, kept in every checkpoint
    seed_fsa: FSA | None
    seed_genome: Genome | None

    @property
    def info(self) -> dict[str, Any]:
        """What ``run.json`` says: the record, and how the run is evaluated."""
        return {**self.record, "backend": self.backend, "workers": self.workers}


def check_arguments(
    task: Any, cfg: Any, workers: Any, progress: Any, on_generation: Any, resume: Any,
    out_dir: Any,
) -> None:
    """The kinds of :func:`evolve`'s arguments, refused in one line naming the fix (else
    they fail deep inside, or after a generation has run)."""
    if not isinstance(task, Task):
        raise TypeError(f"evolve() takes a Task, got {type(task).__name__}; load one with "
                        "skillcompose.task.load_task('examples.toy_task', ...)")
    if cfg is not None and not isinstance(cfg, EvolutionConfig):
        raise TypeError(f"evolve(cfg=...) takes an EvolutionConfig, got {type(cfg).__name__}"
                        "; write EvolutionConfig(**PRESETS['robust']), say")
    if workers is not None and not whole_in(workers, 1, MAX_WORKERS, numpy=True):
        raise EvolutionError(f"workers = {workers!r}: expected a whole number from 1 to "
                             f"{MAX_WORKERS} (or None: every core)")
    if progress is not None and not isinstance(progress, (bool, int)) and \
            not callable(getattr(progress, "write", None)):
        raise TypeError(f"evolve(progress=...) takes True, False or a stream, got "
                        f"{type(progress).__name__}")
    if on_generation is not None and not callable(on_generation):
        raise TypeError(f"evolve(on_generation=...) takes a function, got "
                        f"{type(on_generation).__name__}")
    for name, path in (("resume", resume), ("out_dir", out_dir)):
        if path is not None and not isinstance(path, (str, os.PathLike)):
            raise TypeError(f"evolve({name}=...) takes a folder's path, got "
                            f"{type(path).__name__}")
        if path is not None and not os.fspath(path):
            raise EvolutionError(f"evolve({name}='') names no folder; give the run's folder")
        if path is not None and Path(path).is_symlink() and not Path(path).exists():
            raise EvolutionError(f"{name}={os.fspath(path)!r} is a link to nothing; give a "
                                 "folder")
        if path is not None and Path(path).exists() and not Path(path).is_dir():
            raise EvolutionError(f"{name}={os.fspath(path)!r} is not a folder; give the run's "
                                 "folder" if name == "resume" else
                                 f"{name}={os.fspath(path)!r} is not a folder; give a new "
                                 "folder for the run")


def make_plan(
    task: Task, cfg: EvolutionConfig | None, seed: int | None, workers: int | None,
    backend: str, seed_fsa: FSA | str | os.PathLike[str] | None, progress: bool | TextIO,
    rundir: RunDir | None, checkpoint: Mapping[str, Any] | None,
    record: dict[str, Any] | None, simplify_result: bool | None,
    simplify_trials: int | None, check_trials: int | None,
) -> Plan:
    """The run :func:`evolve` was asked for (``checkpoint`` and ``record``: a resumed run's,
    whose seed, seed FSA and settings stand)."""
    if cfg is None:  # the honest default: "solved" means the exported FSA holds
        cfg = EvolutionConfig(**task_preset(DEFAULT_PRESET, task))
    simplify_result = True if simplify_result is None else simplify_result
    simplify_trials = 200 if simplify_trials is None else simplify_trials
    if not whole_in(simplify_trials, 1):
        raise EvolutionError(f"simplify_trials must be a whole number >= 1, got "
                             f"{simplify_trials!r}")
    check_trials = 200 if check_trials is None else check_trials
    if not whole_in(check_trials, 0):
        raise EvolutionError(f"check_trials must be a whole number >= 0, got {check_trials!r}")
    if seed is None:
        seed = int(np.random.SeedSequence().generate_state(2, np.uint64)[0] >> 1)
    if not whole_in(seed, 0, numpy=True):
        raise EvolutionError(f"seed must be a whole number >= 0, got {seed!r}")
    seed = int(seed)
    skills = SkillSet.from_task(task, pairs=cfg.pairs, pairs_only=cfg.pairs_only)
    trials = cfg.trials or task.trials
    # the run records the trials asked for; a deterministic task uses one: every episode is
    # the same, one says it all
    simplify_used, check_used = simplify_trials, check_trials
    if task.deterministic:
        trials = 1
        simplify_used, check_used = min(simplify_used, 1), min(check_used, 1)
    if checkpoint is None:  # a resumed run's budgets are checked against what it used
        _check_first_generation(cfg, trials)
    stream: TextIO | None = sys.stderr if progress is True else (progress or None)
    if backend == "process" and workers is None:
        workers = os.cpu_count() or 1
    seed_text, seed_source, seed_path = _seed_source(seed_fsa, checkpoint, rundir)
    seed_genome: Genome | None = None
    if seed_source is not None:
        seed_genome = _seed_genome(seed_source, seed_path, skills,
                                   warn=checkpoint is None)  # said once, as the run starts
    if record is None:
        record = run_record(task, seed, cfg, seed_path, simplify_result, simplify_trials,
                            check_trials)
    else:
        record = {**record, "config": cfg.to_dict()}  # a resume may extend the budget
    return Plan(task=task, cfg=cfg, seed=seed, skills=skills, backend=backend,
                workers=workers, trials=trials, simplify=simplify_result,
                simplify_trials=simplify_used, check_trials=check_used, stream=stream,
                record=record, seed_text=seed_text, seed_fsa=seed_source,
                seed_genome=seed_genome)


def _check_first_generation(cfg: EvolutionConfig, trials: int) -> None:
    """Refuse budgets that cannot hold the first generation: every individual evaluated
    on ``trials`` episodes."""
    for option, limit, need in (
            ("max_evaluations", cfg.max_evaluations, cfg.population),
            ("max_episodes", cfg.max_episodes, cfg.population * trials)):
        if limit is not None and limit < need:
            raise EvolutionError(
                f"{option} = {limit} cannot hold the first generation ({need:,} "
                f"{option[4:]}: {cfg.population} individuals"
                + ("" if option == "max_evaluations" else f" of {trials} trials")
                + f"); give --{option.replace('_', '-')} {need} or more, or a smaller "
                "population"
            )


def _seed_source(
    seed_fsa: FSA | str | os.PathLike[str] | None, checkpoint: Mapping[str, Any] | None,
    rundir: RunDir | None,
) -> tuple[str | None, FSA | None, str | None]:
    """The seed FSA's file text, the FSA, and its path: a resumed run's from its checkpoint,
    a new run's from ``seed_fsa``."""
    seed_text: str | None = None
    seed_source: FSA | None = None
    seed_path: str | None = None
    if checkpoint is not None:
        seed_text = checkpoint.get("seed_fsa_text")
        if seed_text is not None:
            if not isinstance(seed_text, str):
                raise CheckpointError(f"{rundir and rundir.checkpoint}: seed_fsa_text is not text")
            seed_source = loads_fsa(seed_text, "the run's seed FSA")
    elif seed_fsa is not None:
        if isinstance(seed_fsa, FSA):
            seed_source = seed_fsa
        else:
            seed_path = str(seed_fsa)
            seed_source = load_fsa(seed_fsa)
            seed_text = Path(seed_fsa).read_text(encoding="utf-8")
    return seed_text, seed_source, seed_path


def _seed_genome(seed_source: FSA, seed_path: str | None, skills: SkillSet,
                 warn: bool) -> Genome:
    """The seed FSA as a genome; with ``warn``, a line on standard error when some of its
    states have a time limit, which does not evolve."""
    seed_genome = Genome.from_fsa(seed_source, skills, seed_path or seed_source.path or "")
    limited = [f"{name} ({st.time_limit:g} s)" for name, st in seed_source.states.items()
               if st.time_limit is not None]
    if limited and warn:
        print(f"warning: {seed_path or 'the seed FSA'}: the time_limit of "
              f"{', '.join(limited)} is not part of what evolves: evolution runs the "
              "states without it and the evolved FSA has none; put it back in the "
              "exported file (or bound whole evaluations with --eval-time-limit)",
              file=sys.stderr)
    return seed_genome
