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

import importlib
import sys
import types
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
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

# Each public name and the module that defines it: the package imports that module when the
# name is first used, so that importing the package (the command line's --help does) stays
# cheap.
_HOMES = {
    "merge_duplicates": ".simplify",
    "simplify": ".simplify",
    "BACKENDS": ".evaluation",
    "CheckpointError": ".errors",
    "EvalLimits": ".evaluation",
    "EvolutionConfig": ".config",
    "EvolutionConfigError": ".errors",
    "EvolutionError": ".errors",
    "EvolutionResult": ".algorithm",
    "Faults": ".evaluation",
    "GenerationRecord": ".algorithm",
    "Genome": ".genome",
    "GenomeCompiler": ".genome",
    "Job": ".evaluation",
    "Node": ".genome",
    "PRESETS": ".config",
    "ProcessEvaluator": ".evaluation",
    "RayEvaluator": ".evaluation",
    "RunDir": ".rundir",
    "SeedFSAError": ".errors",
    "SerialEvaluator": ".evaluation",
    "SkillChoice": ".genome",
    "SkillSet": ".genome",
    "add_node": ".operators",
    "change_start": ".operators",
    "check_fresh": ".algorithm",
    "crossover": ".operators",
    "delete_node": ".operators",
    "draw_fsa": ".rundir",
    "evaluate_genome": ".evaluation",
    "evolve": ".algorithm",
    "fix_start": ".operators",
    "initialize": ".operators",
    "make_evaluator": ".evaluation",
    "mutate": ".operators",
    "mutate_genes": ".operators",
    "mutate_node": ".operators",
    "plot_history": ".rundir",
}

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


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(home, __name__), name)
    globals()[name] = value  # later uses skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


class _Package(types.ModuleType):
    """The package's module object. ``simplify`` names both a function and the module
    ``evolve.simplify``; importing that module would set the package's ``simplify`` to the
    module, so a public name is never replaced by a submodule (``sys.modules`` keeps it)."""

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _HOMES and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
