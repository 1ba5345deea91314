"""skillcompose: write robot skills, compose them into FSAs, run and evolve them.

The public API; examples and user code import from here::

    from skillcompose import skill, Param, Blackboard, Registry, FSA, State
    from skillcompose import compile_fsa, load_fsa, save_fsa
"""

from __future__ import annotations

from .activation import RUNNING, Activation
from .blackboard import DELETED, Access, Blackboard, diff
from .errors import (
    BlackboardAccessError,
    BlackboardKeyError,
    BlackboardTypeError,
    FSAFileError,
    FSAValidationError,
    ParamError,
    Problem,
    RegistryError,
    SkillcomposeError,
    SkillDefinitionError,
    SkillProtocolError,
    UndeclaredOutcomeError,
    UnknownSkillError,
)
from .executor import (
    CompiledFSA,
    FSARun,
    RunResult,
    TraceStep,
    compile_fsa,
    run_fsa,
    run_ticking,
    summarize,
    trial_rngs,
    trial_seeds,
)
from .fsa import (
    DEFAULT_STEP_LIMIT,
    DEFAULT_TERMINALS,
    ERROR,
    FSA,
    PREEMPTED,
    TIMEOUT,
    State,
)
from .fsafile import dumps_fsa, load_fsa, loads_fsa, save_fsa
from .nested import FSASkill, fsa_skill
from .params import Choice, Param, ParamSpec
from .registry import Registry
from .skill import Skill, SkillSpec, skill
from .task import Task, TaskError, TaskRef, Trial, load_task, trials

__version__ = "0.1.0"

__all__ = [
    "DEFAULT_STEP_LIMIT",
    "DEFAULT_TERMINALS",
    "DELETED",
    "ERROR",
    "FSA",
    "PREEMPTED",
    "RUNNING",
    "TIMEOUT",
    "Access",
    "Activation",
    "Blackboard",
    "BlackboardAccessError",
    "BlackboardKeyError",
    "BlackboardTypeError",
    "Choice",
    "CompiledFSA",
    "FSAFileError",
    "FSARun",
    "FSASkill",
    "FSAValidationError",
    "Param",
    "ParamError",
    "ParamSpec",
    "Problem",
    "Registry",
    "RegistryError",
    "RunResult",
    "Skill",
    "SkillDefinitionError",
    "SkillProtocolError",
    "SkillSpec",
    "SkillcomposeError",
    "State",
    "Task",
    "TaskError",
    "TaskRef",
    "TraceStep",
    "Trial",
    "UndeclaredOutcomeError",
    "UnknownSkillError",
    "__version__",
    "compile_fsa",
    "diff",
    "dumps_fsa",
    "fsa_skill",
    "load_fsa",
    "load_task",
    "loads_fsa",
    "run_fsa",
    "run_ticking",
    "save_fsa",
    "skill",
    "summarize",
    "trial_rngs",
    "trial_seeds",
    "trials",
]
