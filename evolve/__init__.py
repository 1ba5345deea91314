"""evolve: the paper's evolution of FSAs (sections 3.2-3.7), run against skillcompose's runtime.

::

    from evolve import EvolutionConfig, evolve, simplify
    from skillcompose.task import load_task

    task = load_task("examples.toy_task", p_fail=0.1)
    result = evolve(task, EvolutionConfig(population=100), seed=0, out_dir="runs/toy")
    print(result.best_fitness, result.generations, list(result.best_fsa.states))

What evolution finds is an ordinary :class:`skillcompose.FSA` (states named ``Skill_N``),
saved as an editable FSA file that ``skillcompose run`` runs and ``--seed-fsa`` evolves again.
"""

from __future__ import annotations

from .algorithm import EvolutionResult, GenerationRecord, check_fresh, evolve
from .config import PRESETS, EvolutionConfig
from .errors import CheckpointError, EvolutionConfigError, EvolutionError, SeedFSAError
from .evaluation import (
    BACKENDS,
    EvalLimits,
    Faults,
    Job,
    ProcessEvaluator,
    RayEvaluator,
    SerialEvaluator,
    evaluate_genome,
    make_evaluator,
)
from .genome import Genome, GenomeCompiler, Node, SkillChoice, SkillSet
from .operators import (
    add_node,
    change_start,
    crossover,
    delete_node,
    fix_start,
    initialize,
    mutate,
    mutate_genes,
    mutate_node,
)
from .rundir import RunDir, draw_fsa, plot_history
from .simplify import merge_duplicates, simplify

__all__ = [
    "BACKENDS",
    "PRESETS",
    "CheckpointError",
    "EvalLimits",
    "EvolutionConfig",
    "EvolutionConfigError",
    "EvolutionError",
    "EvolutionResult",
    "Faults",
    "GenerationRecord",
    "Genome",
    "GenomeCompiler",
    "Job",
    "Node",
    "ProcessEvaluator",
    "RayEvaluator",
    "RunDir",
    "SeedFSAError",
    "SerialEvaluator",
    "SkillChoice",
    "SkillSet",
    "add_node",
    "change_start",
    "check_fresh",
    "crossover",
    "delete_node",
    "draw_fsa",
    "evaluate_genome",
    "evolve",
    "fix_start",
    "initialize",
    "make_evaluator",
    "merge_duplicates",
    "mutate",
    "mutate_genes",
    "mutate_node",
    "plot_history",
    "simplify",
]
