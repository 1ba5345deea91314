"""evolve: the paper's evolution of FSAs (sections 3.2-3.7), run against skillcompose's runtime.

::

    from skillcompose.evolve import EvolutionConfig, evolve, simplify
    from skillcompose.task import load_task

    task = load_task("examples.toy_task", p_fail=0.1)
    result = evolve(task, EvolutionConfig(population=100), seed=0, out_dir="runs/toy")
    print(result.best_fitness, result.generations, list(result.best_fsa.states))

What evolution finds is an ordinary :class:`skillcompose.FSA` (states named ``Skill_N``),
saved as an editable FSA file that ``skillcompose run`` runs and ``--seed-fsa`` evolves again.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .algorithm import evolve as evolve
    from .backends import BACKENDS as BACKENDS
    from .backends import make_evaluator as make_evaluator
    from .config import PRESETS as PRESETS
    from .config import EvolutionConfig as EvolutionConfig
    from .config import preset_settings as preset_settings
    from .errors import CheckpointError as CheckpointError
    from .errors import EvolutionConfigError as EvolutionConfigError
    from .errors import EvolutionError as EvolutionError
    from .errors import SeedFSAError as SeedFSAError
    from .evaluation import EvalLimits as EvalLimits
    from .evaluation import Faults as Faults
    from .evaluation import Job as Job
    from .evaluation import evaluate_genome as evaluate_genome
    from .genome import Genome as Genome
    from .genome import GenomeCompiler as GenomeCompiler
    from .genome import Node as Node
    from .genome import SkillChoice as SkillChoice
    from .genome import SkillSet as SkillSet
    from .holds import check_fresh as check_fresh
    from .holds import describe_fresh as describe_fresh
    from .operators import add_node as add_node
    from .operators import change_start as change_start
    from .operators import crossover as crossover
    from .operators import delete_node as delete_node
    from .operators import fix_start as fix_start
    from .operators import initialize as initialize
    from .operators import mutate as mutate
    from .operators import mutate_genes as mutate_genes
    from .operators import mutate_node as mutate_node
    from .plan import task_preset as task_preset
    from .pool import ProcessEvaluator as ProcessEvaluator
    from .ray_backend import RayEvaluator as RayEvaluator
    from .result import EvolutionResult as EvolutionResult
    from .result import GenerationRecord as GenerationRecord
    from .rundir import RunDir as RunDir
    from .rundir import draw_fsa as draw_fsa
    from .rundir import plot_history as plot_history
    from .serial import SerialEvaluator as SerialEvaluator
    from .simplify import merge_duplicates as merge_duplicates
    from .simplify import simplify as simplify
else:
    import lazy_loader

    # Each public name is imported with its module when it is first used, so that importing
    # the package (the command line's --help does) stays cheap. The table repeats the imports
    # above, which only the type checker runs; a test keeps the two equal. lazy_loader also
    # keeps the function ``simplify`` from being replaced by the module
    # ``skillcompose.evolve.simplify``
    # when that is imported.
    _EXPORTS = {
        "algorithm": "evolve",
        "backends": "BACKENDS make_evaluator",
        "config": "PRESETS EvolutionConfig preset_settings",
        "errors": "CheckpointError EvolutionConfigError EvolutionError SeedFSAError",
        "evaluation": "EvalLimits Faults Job evaluate_genome",
        "genome": "Genome GenomeCompiler Node SkillChoice SkillSet",
        "holds": "check_fresh describe_fresh",
        "operators": ("add_node change_start crossover delete_node fix_start initialize mutate "
                      "mutate_genes mutate_node"),
        "plan": "task_preset",
        "pool": "ProcessEvaluator",
        "ray_backend": "RayEvaluator",
        "result": "EvolutionResult GenerationRecord",
        "rundir": "RunDir draw_fsa plot_history",
        "serial": "SerialEvaluator",
        "simplify": "merge_duplicates simplify",
    }
    __getattr__, __dir__, __all__ = lazy_loader.attach(
        __name__, submod_attrs={module: names.split() for module, names in _EXPORTS.items()}
    )
