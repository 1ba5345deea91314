"""Algorithm 1: evolve FSAs for a task, against the runtime that will run them.

::

    result = evolve(task, EvolutionConfig(population=100), seed=0, out_dir="runs/toy")
    result.best_fsa        # skillcompose.FSA, states named Skill_N, simplified
    save_fsa(result.best_fsa, "toy.yaml", task.registry)

Randomness: the breeding generator is ``SeedSequence(seed, spawn_key=(0,))``; the worlds
of individual ``i`` in generation ``g`` come from ``SeedSequence(seed, spawn_key=(1, g, i))``
(``(1, g)`` for every individual with common random numbers). Nothing depends on which
worker evaluates what, so a run is the same on any backend and number of workers, and a run
resumed from a checkpoint is the same as one never interrupted. Islands (``islands`` > 1)
change none of this: they are slices of the one population, bred one after the other from
the same breeding generator, and migration draws nothing at random.

The loop (:func:`_generations`) is DEAP's ``eaSimple``: breed (:mod:`.breeding`), evaluate
and record (:mod:`.generation`), and, before stopping, check the solution
(:mod:`.solution_checks`), until it is solved or a budget runs out (:mod:`.budgets`: no
generation or check starts that could overrun one). What a run knows and checkpoints is a
:class:`~skillcompose.evolve.state.RunState`; what it is asked for, a
:class:`~skillcompose.evolve.plan.Plan`; what it writes at its end, :mod:`.export`.
"""

from __future__ import annotations

import os
import shlex
import time
from collections.abc import Callable, Mapping
from typing import Any, TextIO

from skillcompose import FSA
from skillcompose.task import Task

from .backends import BACKENDS, make_evaluator
from .budgets import checks_due, checks_episodes, next_generation, overrun, stop_reason
from .config import EvolutionConfig
from .errors import CheckpointError, EvolutionError
from .evaluation import EvalLimits
from .export import SeedNames, export_settings, finish, unchanged
from .generation import cost, evaluate, record
from .genome import Genome
from .isolated import IsolatedChecks, check_kill_after
from .listeners import OnGeneration, RunDirWriter, RunListener
from .operators import initialize
from .plan import Plan, check_arguments, make_plan
from .progress import Progress
from .result import EvolutionResult, GenerationRecord
from .resume import open_resumed
from .rundir import RunDir
from .solution_checks import confirm, holds
from .state import RunState

__all__ = ["evolve"]



def evolve(
    task: Task,
    cfg: EvolutionConfig | None = None,
    seed: int | None = 0,
    workers: int | None = None,
    backend: str = "serial",
    out_dir: str | os.PathLike[str] | None = None,
    seed_fsa: FSA | str | os.PathLike[str] | None = None,
    progress: bool | TextIO = False,
    *,
    resume: str | os.PathLike[str] | None = None,
    simplify_result: bool | None = None,
    simplify_trials: int | None = None,
    check_trials: int | None = None,
    on_generation: Callable[[GenerationRecord], None] | None = None,
) -> EvolutionResult:
    """Evolve an FSA for ``task`` (algorithm 1), stopping when solved or out of a budget.

    - ``cfg``: the settings (default: the ``default`` preset for this task,
      :func:`~skillcompose.evolve.config.preset_settings`: solved means the exported FSA
      holds on fresh episodes at the task's ``success_rate``; ``EvolutionConfig()`` is the
      paper's table 1, solved on one evaluation).
    - ``seed``: the run's seed (``None`` draws one, recorded in the result and files).
    - ``backend``: ``"serial"``, ``"process"`` (``workers`` processes, default all cores) or
      ``"ray"`` (``workers`` actors, default one per CPU of the cluster); the result does not
      depend on it.
    - ``out_dir``: write the run directory (see :mod:`skillcompose.evolve.rundir`) as the run goes.
    - ``resume``: a run directory to continue from its last checkpoint (see
      :mod:`skillcompose.evolve.resume`). ``task`` must be the run's task; the seed, the
      settings, the simplification and the fresh-episode check are the run's. ``cfg``, when
      given, may differ from the run's only in its budgets (``generations``,
      ``max_evaluations``, ``max_episodes``: to extend a run, the result is the run an
      uninterrupted run to those budgets would have given), ``checkpoint_every``,
      ``chunks_per_worker``, ``worker_max_jobs`` and ``worker_max_growth_mb``. A finished
      run is not touched (``result.unchanged``), but for its exported FSAs, written again
      when they were deleted.
    - ``seed_fsa``: an FSA (or file) placed in the first population, the rest random; the
      states that survive evolution keep their names (and, from a file, their comments).
    - ``simplify_result``: simplify the best FSA at the end (default on) with
      ``simplify_trials`` fresh trials (default 200; see :func:`skillcompose.evolve.simplify`).
    - ``check_trials``: fresh episodes on which the exported FSA is measured at the end
      (default 200; :func:`check_fresh`; ``result.fresh``, ``run.json``), unless the run was
      solved by its holds test, whose episodes are then the measure; 0 skips it. A
      deterministic task (``Task.deterministic``) uses one trial for evaluations,
      simplification and this check.
    - ``progress``: progress on stderr (or on the given stream): a live line on a
      terminal, a line every 5 s otherwise; both show the faults so far.
    """
    check_arguments(task, cfg, workers, progress, on_generation, resume, out_dir)
    workers = None if workers is None else int(workers)  # numpy's: Python's, for run.json
    if backend not in BACKENDS:
        raise EvolutionError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    rundir: RunDir | None = None
    checkpoint: dict[str, Any] | None = None
    recorded: dict[str, Any] | None = None
    if resume is not None:
        if seed_fsa is not None:
            raise EvolutionError("seed_fsa starts a new run; a resumed run has its own already")
        rundir, checkpoint, recorded, cfg = open_resumed(resume, task, cfg, simplify_result,
                                                         simplify_trials, check_trials)
        seed = recorded["seed"]
        simplify_result, simplify_trials = recorded["simplify"], recorded["simplify_trials"]
        check_trials = recorded["check_trials"]
    elif out_dir is not None:
        rundir = RunDir(out_dir)  # created (and locked) once the run's record is known
    try:
        plan = make_plan(task, cfg, seed, workers, backend, seed_fsa, progress, rundir,
                         checkpoint, recorded, simplify_result, simplify_trials, check_trials)
        return _evolve(plan, rundir, checkpoint, on_generation)
    finally:
        if rundir is not None:
            rundir.unlock()


def _evolve(
    plan: Plan, rundir: RunDir | None, checkpoint: dict[str, Any] | None,
    on_generation: Callable[[GenerationRecord], None] | None,
) -> EvolutionResult:
    """The run of ``plan``: its state made, or restored from ``checkpoint``; its
    generations; its exports."""
    if rundir is not None and checkpoint is None:
        rundir.create(plan.info)
    run = RunState(plan.task, plan.cfg, plan.seed, plan.skills, rundir, plan.trials,
                   plan.record, seed_text=plan.seed_text)
    run.export_settings = export_settings(plan)
    if plan.seed_fsa is not None and plan.seed_genome is not None:
        run.seed_names = SeedNames(plan.seed_fsa, plan.seed_genome, run.compiler)
    fitness: list[float] | None = None
    if checkpoint is not None:
        assert rundir is not None
        fitness = _restore(run, checkpoint, rundir)
        ended = stop_reason(run, fitness) if run.exported else None
        if ended is not None:
            return unchanged(run, checkpoint, rundir, ended)
        rundir.write_run_info(plan.info)
        rundir.rewrite_history([r.to_dict() for r in run.history])
    else:
        _first_population(run, plan.seed_genome)
        if rundir is not None:
            rundir.save_checkpoint(run.checkpoint())
    run.exported = False
    if plan.backend != "serial":  # the checks where the evaluations are: apart from the run
        run.isolated = IsolatedChecks(plan.task, plan.skills,
                                      check_kill_after(plan.cfg.eval_time_limit))
    try:
        if run.isolated is not None:
            run.isolated.start()
        fitness = _generations(run, plan, fitness, on_generation)
        return finish(run, plan, fitness)
    finally:
        if run.isolated is not None:
            run.isolated.close()


def _restore(run: RunState, checkpoint: Mapping[str, Any], rundir: RunDir) -> list[float] | None:
    """Continue ``run`` from its checkpoint; the fitness of its population, if evaluated."""
    fitness = run.restore(checkpoint, str(rundir.checkpoint))
    cfg = run.cfg
    # finished or not, a budget cannot shrink below what the run has used
    for option, limit, used in (("--max-evaluations", cfg.max_evaluations,
                                 run.genome_evaluations),
                                ("--max-episodes", cfg.max_episodes, run.evaluations)):
        if limit is not None and limit < used:
            raise CheckpointError(
                f"{rundir.path} has used {used} {option[6:]} already; give {option} {used} "
                "or more, or leave it out to keep the run's budget"
            )
    if cfg.generations < run.generation:
        raise CheckpointError(
            f"{rundir.path} has reached generation {run.generation} already; give "
            f"--generations {run.generation} or more"
        )
    if fitness is None:  # bred, not evaluated: its jobs were counted when it was bred
        over = overrun(run, *cost(run))
        if over is not None:
            evaluations, episodes = cost(run)
            need = run.genome_evaluations + evaluations if over == "evaluations" else \
                run.evaluations + episodes
            raise CheckpointError(
                f"{rundir.path} has bred generation {run.generation}, which takes "
                f"{evaluations} evaluations ({episodes} episodes); give --max-{over} {need} "
                "or more, or leave it out to keep the run's budget"
            )
    return fitness


def _first_population(run: RunState, seed_genome: Genome | None) -> None:
    """Generation 0: random genomes, the seed FSA's first when there is one."""
    cfg = run.cfg
    for i in range(cfg.population):
        g = initialize(run.skills, run.rng, cfg.initial_nodes, cfg.terminal_weight)
        if i == 0 and seed_genome is not None:
            g = seed_genome.copy()
        g.origin = {**g.origin, "uid": run.uid(), "born": 0, "parents": [], "ops": [
            "seed_fsa" if (i == 0 and seed_genome is not None) else "init"]}
        run.population.append(g)


def _generations(
    run: RunState, plan: Plan, fitness: list[float] | None,
    on_generation: Callable[[GenerationRecord], None] | None,
) -> list[float] | None:
    """Algorithm 1's loop, until the task is solved or a budget spent: breed (each child
    goes to the evaluator as it is born), evaluate, record, and check a solution before
    stopping. The last generation's fitness; ``run.stopped_by`` says what ended it."""
    task, cfg = run.task, run.cfg
    run.stopped_by = stop_reason(run, fitness) or ""
    if run.stopped_by:
        return fitness
    # persistence (the run directory's), progress (the command line's), the caller's own
    listeners: list[RunListener] = [
        *([RunDirWriter(run.rundir)] if run.rundir is not None else []),
        Progress(plan.stream), *([OnGeneration(on_generation)] if on_generation else [])]

    def bred() -> None:  # runs as the last child is born, while the pool evaluates
        for listener in listeners:
            listener.bred(run)

    limits = EvalLimits(cfg.eval_time_limit, cfg.worker_max_jobs, cfg.worker_max_growth_mb)
    evaluator = make_evaluator(plan.backend, task, plan.skills, plan.workers,
                               cfg.chunks_per_worker, limits, islands=cfg.islands)
    stop = _checks(run, fitness) if fitness is not None and run.checks_pending else None
    try:
        while stop is None:
            children = None
            if fitness is not None:
                if run.generation >= cfg.generations:
                    stop = "generations"
                    break
                children, stop = next_generation(run, fitness, bred)
                if stop is not None:
                    break
            t = time.perf_counter()
            fitness, episodes = evaluate(run, evaluator, children)
            _check_not_all_lost(run)
            rec = record(run, fitness, episodes, time.perf_counter() - t)
            for listener in listeners:
                listener.generation(run, rec)
            stop = _checks(run, fitness)
    finally:
        evaluator.close()
        for listener in listeners:
            listener.close(run)
    run.stopped_by = stop
    return fitness


def _checks(run: RunState, fitness: list[float]) -> str | None:
    """After a generation: ``"solved"`` when its best at the target stands (confirmed and
    holding, when asked), ``"episodes"`` when those checks could overrun the episode budget
    (they wait for an extended run), else None: the run goes on."""
    assert run.best is not None
    if not run.task.solved(run.best[1]):
        return None
    if not checks_due(run):
        return "solved"
    over = overrun(run, 0, checks_episodes(run, fitness))
    run.checks_pending = over is not None
    if over is not None:
        return over
    solved = confirm(run, fitness) if run.cfg.confirm_trials else True
    if solved and run.cfg.require_holds:
        solved = holds(run, fitness)
    return "solved" if solved else None


LOST_IN_A_ROW = 3
"""With common random numbers, the generations in a row every evaluation of which killed its
worker that stop the run (without them, one does)."""


def _all_lost(faults: Mapping[str, Any]) -> bool:
    return faults.get("jobs", 0) > 0 and faults.get("lost", 0) >= faults["jobs"]


def _check_not_all_lost(run: RunState) -> None:
    """Stop the run when every evaluation of the generation killed the worker running it:
    the task does that, so going on would only count deaths. With common random numbers
    the evaluations of a generation share their episodes, so one episode that ends its
    process (a world 1 % of which do) kills every evaluation that reaches it: such a
    generation is recorded, every evaluation scoring worst and counted lost, and the run
    stops only at :data:`LOST_IN_A_ROW` such generations in a row (the last one not
    recorded). The history is the count, so a resumed run stops where the first would."""
    faults = run.gen_faults
    if not _all_lost(faults.to_dict()):
        return
    in_a_row = ""
    if run.cfg.common_random_numbers:
        before = 0
        for rec in reversed(run.history):
            if not _all_lost(rec.faults):
                break
            before += 1
        if before + 1 < LOST_IN_A_ROW:
            return
        in_a_row = (f", as did every evaluation of the {before} generation"
                    f"{'' if before == 1 else 's'} before it (they shared their episodes)")
    again = ""
    if run.rundir is not None:
        again = (f"; fix it, then go on with: skillcompose evolve --resume "
                 f"{shlex.quote(str(run.rundir.path))}")
    raise EvolutionError(
        f"every evaluation of generation {run.generation} ({faults.jobs}) killed the worker "
        f"process running it{in_a_row}: os._exit in task {run.task.name} or a skill, a crash "
        f"in C code, or the out-of-memory killer; the run stops without recording it{again}"
    )
