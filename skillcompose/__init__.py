"""skillcompose: write robot skills, compose them into FSAs, run and evolve them.

The public API; examples and user code import from here::

    from skillcompose import skill, Param, Blackboard, Registry, FSA, State
    from skillcompose import compile_fsa, load_fsa, save_fsa
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
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

# Each public name and the module that defines it: the package imports that module when the
# name is first used (``from skillcompose import FSA`` imports skillcompose.fsa), so that
# importing one module of the package (``skillcompose --help`` imports skillcompose.cli)
# does not load the whole runtime and numpy.
_HOMES = {
    "Access": ".blackboard",
    "Activation": ".activation",
    "Blackboard": ".blackboard",
    "BlackboardAccessError": ".errors",
    "BlackboardKeyError": ".errors",
    "BlackboardTypeError": ".errors",
    "Choice": ".params",
    "CompiledFSA": ".executor",
    "DEFAULT_STEP_LIMIT": ".fsa",
    "DEFAULT_TERMINALS": ".fsa",
    "DELETED": ".blackboard",
    "ERROR": ".fsa",
    "FSA": ".fsa",
    "FSAFileError": ".errors",
    "FSARun": ".executor",
    "FSASkill": ".nested",
    "FSAValidationError": ".errors",
    "PREEMPTED": ".fsa",
    "Param": ".params",
    "ParamError": ".errors",
    "ParamSpec": ".params",
    "Problem": ".errors",
    "RUNNING": ".activation",
    "Registry": ".registry",
    "RegistryError": ".errors",
    "RunResult": ".executor",
    "Skill": ".skill",
    "SkillDefinitionError": ".errors",
    "SkillProtocolError": ".errors",
    "SkillSpec": ".skill",
    "SkillcomposeError": ".errors",
    "State": ".fsa",
    "TIMEOUT": ".fsa",
    "Task": ".task",
    "TaskError": ".task",
    "TaskRef": ".task",
    "TraceStep": ".executor",
    "Trial": ".task",
    "UndeclaredOutcomeError": ".errors",
    "UnknownSkillError": ".errors",
    "compile_fsa": ".executor",
    "diff": ".blackboard",
    "dumps_fsa": ".fsafile",
    "fsa_skill": ".nested",
    "load_fsa": ".fsafile",
    "load_task": ".task",
    "loads_fsa": ".fsafile",
    "run_fsa": ".executor",
    "run_ticking": ".executor",
    "save_fsa": ".fsafile",
    "skill": ".skill",
    "summarize": ".executor",
    "trial_rngs": ".executor",
    "trial_seeds": ".executor",
    "trials": ".task",
}

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
    """The package's module object. ``skill`` names both the decorator and the module
    ``skillcompose.skill``; importing that module would set the package's ``skill`` to the
    module, so a public name is never replaced by a submodule (``sys.modules`` keeps it)."""

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _HOMES and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
