"""What a run writes out: its best FSA, named and simplified, and, at its end, the last
files of the run directory and the :class:`~skillcompose.evolve.result.EvolutionResult`.

An exported FSA's states are named ``Skill_N``, but for those that survive from a seed FSA
file, which keep their names and comments (:class:`SeedNames`); its header names a
``skillcompose run`` command that runs it (:func:`run_command`).
"""

from __future__ import annotations

import dataclasses
import os
import shlex
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from skillcompose import FSA, dumps_fsa, loads_fsa
from skillcompose.fsafile import in_layout_of
from skillcompose.task import Task

from .genome import Genome, GenomeCompiler
from .holds import check_fresh, fresh_differs, required_rate
from .result import EvolutionResult
from .simplify import simplify
from .state import RunState

if TYPE_CHECKING:
    from .plan import Plan
    from .rundir import RunDir

__all__ = ["SeedNames", "best_fsa", "finish", "header", "named", "run_command",
           "unchanged"]


def best_fsa(run: RunState, simplified: dict[str, Any] | None = None) -> FSA:
    """The best genome as an FSA, states named ``Skill_N``."""
    assert run.best is not None
    g, f, gen = run.best
    info = run.record_info
    meta: dict[str, Any] = {
        "evolved": {
            "task": run.task.name,
            "task_module": info.get("task_module"),
            "task_settings": dict(info.get("task_settings") or run.task.settings),
            "fitness": f,
            "solved": run.task.solved(f),
            "found_in_generation": gen,
            "seed": run.seed,
            "config": run.cfg.to_dict(),
            "lineage": dict(g.origin),
        }
    }
    if simplified:
        meta["simplified"] = simplified
    return run.compiler.fsa(g, name=f"{run.task.name}_evolved", meta=meta)


def named(run: RunState, fsa: FSA) -> FSA:
    """``fsa`` with the seed file's state names (and comments) where they survive."""
    return run.seed_names.apply(fsa, header(run)) if run.seed_names else fsa


def header(run: RunState) -> str:
    """The comment at the head of an exported FSA file: where it comes from, and how to run
    it."""
    assert run.best is not None
    _, f, gen = run.best
    return (
        f"Evolved by skillcompose for task {run.task.name} (seed {run.seed}): fitness "
        f"{f:g} in generation {gen}.\nEdit freely: rename states, change parameters (in "
        "the skills' units), re-route outcomes.\nRun it with `"
        f"{run_command('FILE', run.record_info)}`,\nor evolve from it with "
        "`--seed-fsa FILE`."
    )


def run_command(path: str, info: Mapping[str, Any]) -> str:
    """A ``skillcompose run`` command line that runs an exported FSA on its task."""
    module = info.get("task_module")
    if not module:
        return f"skillcompose run {shlex.quote(path)} --task TASK"
    words = ["skillcompose", "run", path, "--task", str(module)]
    for k, v in dict(info.get("task_settings") or {}).items():
        words += ["--set", f"{k}={v}"]
    return " ".join(shlex.quote(w) for w in words)


class SeedNames:
    """The state names of a seed FSA file, given back to the states that survive evolution.

    A state of an exported FSA is the seed's state when it comes from the same genome node
    (its number) and runs the same skill with the same parameters: it takes the seed's name.
    When its transitions are the same as well, it keeps the seed file's entry, comments
    included; the rest of the file (the header, the other states) is written afresh.
    """

    def __init__(self, seed: FSA, genome: Genome, compiler: GenomeCompiler) -> None:
        self.seed = seed
        self.generated = compiler.fsa(genome)  # the seed as a genome exports it: Skill_N
        self.names: dict[str, str] = {}  # Skill_N -> the seed's name
        queue = [(self.generated.start, seed.start)]
        while queue:  # the two are the same graph: walk both from the start
            gen, own = queue.pop()
            if gen in self.names:
                continue
            self.names[gen] = own
            for outcome, target in self.generated.states[gen].transitions.items():
                if target in self.generated.states:
                    queue.append((target, seed.states[own].transitions[outcome]))

    def apply(self, fsa: FSA, header: str) -> FSA:
        rename: dict[str, str] = {}
        unchanged: set[str] = set()
        for name, st in fsa.states.items():
            was = self.generated.states.get(name)
            if name not in self.names or was is None or (st.skill, dict(st.params)) != (
                    was.skill, dict(was.params)):
                continue
            rename[name] = self.names[name]
            if dict(st.transitions) == dict(was.transitions):
                unchanged.add(self.names[name])
        taken = set(fsa.states) - set(rename)
        rename = {k: v for k, v in rename.items() if v not in taken}

        def to(n: str) -> str:
            return rename.get(n, n)

        states = {
            to(n): dataclasses.replace(st, transitions={o: to(t) for o, t in
                                                        st.transitions.items()})
            for n, st in fsa.states.items()
        }
        named = fsa.replace(states=states, start=to(fsa.start))
        return in_layout_of(named, self.seed, unchanged & set(rename.values()), header)


ExportSettings = tuple[bool, int, int, "float | None"]
"""What :func:`make_export` needs besides the task: whether to simplify, the run's seed,
the simplification's trials and the time limit of an evaluation."""


def make_export(task: Task, simplify_it: bool, seed: int, trials: int,
                time_limit: float | None) -> Callable[[FSA], FSA]:
    """What a run writes for an evolved FSA: simplified (unless ``simplify_it`` is false)."""
    def export(fsa: FSA) -> FSA:
        """The FSA the run writes for ``fsa``: simplified (unless asked not to)."""
        if not simplify_it:
            return fsa
        out = simplify(task, fsa, seed=seed, trials=trials, time_limit=time_limit)
        return out.replace(meta={**fsa.meta, **out.meta}, name=fsa.name)

    return export


def export_settings(plan: Plan) -> ExportSettings:
    """The :data:`ExportSettings` of ``plan``."""
    return plan.simplify, plan.seed, plan.simplify_trials, plan.cfg.eval_time_limit


def finish(run: RunState, plan: Plan, fitness: list[float] | None) -> EvolutionResult:
    """The end of a run: its last checkpoint, its best FSA as evolved and as exported (both
    named), whether it solved the task, the exported FSA on fresh episodes, the run
    directory's last files; what it found."""
    assert run.best is not None and fitness is not None
    task, cfg, rundir = run.task, run.cfg, run.rundir
    if rundir is not None:  # the evolution is over: a kill from here on only redoes exports
        rundir.save_checkpoint(run.checkpoint(fitness))
    best_genome, best_f, _ = run.best
    evolved = best_fsa(run)
    best = evolved
    simplify_result, check_used = plan.simplify, plan.check_trials
    # a task that kills a worker can end a process; only the process and Ray backends have
    # workers, and there the checks run in a child of their own (run.isolated)
    exported = True  # best is the FSA the run would export (the one a holds test checks)
    if simplify_result:
        got = run.check(export_in, run.export_settings, evolved)
        if got is None:  # the task killed the process simplifying: nothing more here
            _died(run, "simplification and the fresh-episode check are skipped; "
                  "best.yaml is the evolved FSA")
            check_used, exported = 0, False
        best = evolved if got is None else got
    evolved, best = named(run, evolved), named(run, best)
    # with require_holds, solved is the statement of the holds test, unless its FSA is not
    # the one written (the simplification's process was killed)
    solved_by = "holds" if cfg.require_holds and exported else "evaluation"
    solved = task.solved(best_f) and (solved_by == "evaluation" or run.holds_passed is not None)
    solved = solved and not run.checks_pending  # its checks did not fit in the budget
    fresh = _fresh(run, best, best_f, solved and solved_by == "holds", check_used)
    faults = run.faults()
    files: list[Path] = []
    if rundir is not None:
        files = _write_final(run, fitness, evolved, best, {
            "solved": solved,
            "solved_by": solved_by,
            "best_fitness": best_f,
            "generations": run.generation,
            "evaluations": run.evaluations,
            "stopped_by": run.stopped_by,
            "budgets": run.budget_use(),
            "fresh": fresh,
            "faults": faults.to_dict(),
            "first_error": faults.first_error,
        })
    return EvolutionResult(
        best_fsa=best,
        best_fitness=best_f,
        solved=solved,
        generations=run.generation,
        evaluations=run.evaluations,
        wall_time=run.wall(),
        history=run.history,
        evolved_fsa=evolved,
        best_genome=best_genome,
        seed=run.seed,
        out_dir=rundir.path if rundir is not None else None,
        files=files,
        budget=cfg.generations,
        run_command=run_command(str(rundir.best_yaml) if rundir else "FILE", plan.record),
        faults=faults,
        fresh=fresh,
        solved_by=solved_by,
        genome_evaluations=run.genome_evaluations,
        stopped_by=run.stopped_by,
        budgets=run.budget_use(),
    )


def _fresh(run: RunState, best: FSA, best_f: float, held: bool,
           check_trials: int) -> dict[str, Any]:
    """The exported FSA on fresh episodes: the holds test's when it ``held`` (and so
    decided "solved"), else ``check_trials`` episodes of their own (0: none, empty)."""
    fresh: dict[str, Any] = {}
    if held:
        assert run.holds_passed is not None
        fresh = {**run.holds_passed["fresh"], "differs": False}
    elif check_trials > 0:
        task, cfg = run.task, run.cfg
        got = run.check(fresh_in, best, run.seed, check_trials, cfg.eval_time_limit,
                        required_rate(task, cfg), cfg.holds_confidence)
        if got is None:
            _died(run, "the fresh-episode check is skipped")
            return {}
        fresh = {**got, "differs": fresh_differs(task, best_f, got["mean_fitness"])}
    return fresh


def export_in(task: Task, compiler: GenomeCompiler, settings: ExportSettings, fsa: FSA) -> FSA:
    """What the run writes for ``fsa`` (:func:`make_export`), where the checks run
    (:mod:`.isolated`)."""
    return make_export(task, *settings)(fsa)


def fresh_in(task: Task, compiler: GenomeCompiler, fsa: FSA, seed: int, trials: int,
             time_limit: float | None, required: float, confidence: float) -> dict[str, Any]:
    """The final fresh-episode check of ``fsa`` (:func:`~.holds.check_fresh`), where the
    checks run (:mod:`.isolated`)."""
    return check_fresh(task, fsa, seed, trials, time_limit, required=required,
                       confidence=confidence)


def _died(run: RunState, skipped: str) -> None:
    """Say that a check at the end of the run killed the process running it, or ran past
    the time limit where no signal stopped it (counted by :meth:`RunState.check`)."""
    if run.isolated is not None and run.isolated.last_overran:
        why = ("an episode ran past the evaluation time limit where no signal stopped it "
               "(SIGALRM blocked, a wait in C code), and its process was killed")
    else:
        why = "it killed its process (os._exit in the task or a skill, a crash in C code)"
    print(f"warning: the end of the run ran task {run.task.name} and {why}: {skipped}",
          file=sys.stderr)


def _write_final(run: RunState, fitness: list[float], evolved: FSA, best: FSA,
                 result: dict[str, Any]) -> list[Path]:
    """Write the run directory's last files (``result`` goes into ``run.json``), the
    checkpoint last; the files of the run directory."""
    rundir, task = run.rundir, run.task
    assert rundir is not None
    rundir.write_best(evolved, task.registry, header(run), rundir.best_evolved_yaml)
    rundir.write_best(best, task.registry, header(run))
    rundir.plots([r.to_dict() for r in run.history], best)
    rundir.update_run_info({"result": result})
    run.exported = True  # last: a kill before this redoes only the exports
    rundir.save_checkpoint({**run.checkpoint(fitness),
                            "best_yaml": dumps_fsa(best, task.registry, header=header(run)),
                            "fresh": result["fresh"], "solved_by": result["solved_by"]})
    written = [rundir.best_yaml, rundir.best_evolved_yaml, rundir.best_dot, rundir.best_png,
               rundir.history, rundir.fitness_png, rundir.checkpoint, rundir.run_json]
    return [p for p in written if p.exists()]  # best.png: none for a large FSA (plots)


def unchanged(run: RunState, checkpoint: Mapping[str, Any], rundir: RunDir,
              stopped_by: str) -> EvolutionResult:
    """The result of a run that had finished (``stopped_by`` what): read from its
    checkpoint. Nothing is written but the exported FSAs found missing (deleted), written
    again as the run wrote them; ``files`` names those."""
    assert run.best is not None
    text = checkpoint.get("best_yaml")
    evolved = named(run, best_fsa(run))
    best = loads_fsa(text, str(rundir.checkpoint)) if isinstance(text, str) else evolved
    fresh = checkpoint.get("fresh")
    g, f, _ = run.best
    solved_by = checkpoint.get("solved_by")  # as the run's end decided (older: recomputed)
    if solved_by not in ("holds", "evaluation"):
        solved_by = "holds" if run.cfg.require_holds and not run.faults().lost else \
            "evaluation"
    solved = run.task.solved(f) and (solved_by == "evaluation" or run.holds_passed is not None)
    solved = solved and not run.checks_pending
    restored: list[Path] = []
    for path, again in ((rundir.best_yaml, text if isinstance(text, str) else None),
                        (rundir.best_evolved_yaml, None)):
        if not os.path.lexists(path):
            again = again or dumps_fsa(evolved, run.task.registry, header=header(run))
            rundir.write_editable(path, again.encode("utf-8"))
            restored.append(path)
    return EvolutionResult(
        best_fsa=best, best_fitness=f, solved=solved, generations=run.generation,
        evaluations=run.evaluations, wall_time=run.wall_before, history=run.history,
        evolved_fsa=evolved, best_genome=g, seed=run.seed, out_dir=rundir.path,
        files=restored,
        unchanged=True, budget=run.cfg.generations,
        run_command=run_command(str(rundir.best_yaml), run.record_info),
        faults=run.faults(), fresh=fresh if isinstance(fresh, dict) else {},
        solved_by=solved_by, genome_evaluations=run.genome_evaluations,
        stopped_by=stopped_by, budgets=run.budget_use(),
    )
