"""skillcompose: write robot skills, compose them into FSAs, run and evolve them.

The public API; examples and user code import from here::

    from skillcompose import skill, Param, Blackboard, Registry, FSA, State
    from skillcompose import compile_fsa, load_fsa, save_fsa
"""

from __future__ import annotations

from typing import TYPE_CHECKING

__version__ = "0.1.0"

if TYPE_CHECKING:
    from .activation import RUNNING as RUNNING
    from .activation import Activation as Activation
    from .blackboard import DELETED as DELETED
    from .blackboard import Access as Access
    from .blackboard import Blackboard as Blackboard
    from .blackboard import diff as diff
    from .errors import BlackboardAccessError as BlackboardAccessError
    from .errors import BlackboardKeyError as BlackboardKeyError
    from .errors import BlackboardTypeError as BlackboardTypeError
    from .errors import FSAFileError as FSAFileError
    from .errors import FSAValidationError as FSAValidationError
    from .errors import ParamError as ParamError
    from .errors import Problem as Problem
    from .errors import RegistryError as RegistryError
    from .errors import SkillcomposeError as SkillcomposeError
    from .errors import SkillDefinitionError as SkillDefinitionError
    from .errors import SkillProtocolError as SkillProtocolError
    from .errors import UndeclaredOutcomeError as UndeclaredOutcomeError
    from .errors import UnknownSkillError as UnknownSkillError
    from .executor import CompiledFSA as CompiledFSA
    from .executor import FSARun as FSARun
    from .executor import RunResult as RunResult
    from .executor import TraceStep as TraceStep
    from .executor import compile_fsa as compile_fsa
    from .executor import run_fsa as run_fsa
    from .executor import run_ticking as run_ticking
    from .executor import summarize as summarize
    from .executor import trial_rngs as trial_rngs
    from .executor import trial_seeds as trial_seeds
    from .fsa import DEFAULT_STEP_LIMIT as DEFAULT_STEP_LIMIT
    from .fsa import DEFAULT_TERMINALS as DEFAULT_TERMINALS
    from .fsa import ERROR as ERROR
    from .fsa import FSA as FSA
    from .fsa import PREEMPTED as PREEMPTED
    from .fsa import TIMEOUT as TIMEOUT
    from .fsa import State as State
    from .fsafile import dumps_fsa as dumps_fsa
    from .fsafile import load_fsa as load_fsa
    from .fsafile import loads_fsa as loads_fsa
    from .fsafile import save_fsa as save_fsa
    from .nested import FSASkill as FSASkill
    from .nested import fsa_skill as fsa_skill
    from .params import Choice as Choice
    from .params import Param as Param
    from .params import ParamSpec as ParamSpec
    from .registry import Registry as Registry
    from .skill import Skill as Skill
    from .skill import SkillSpec as SkillSpec
    from .skill import skill as skill
    from .task import Task as Task
    from .task import TaskError as TaskError
    from .task import TaskRef as TaskRef
    from .task import Trial as Trial
    from .task import load_task as load_task
    from .task import trials as trials
else:
    import lazy_loader

    # Each public name is imported with its module when it is first used (``from
    # skillcompose import FSA`` imports skillcompose.fsa), so that importing one module of the
    # package (``skillcompose --help`` imports skillcompose.cli) does not load the whole runtime
    # and numpy. The table repeats the imports above, which only the type checker runs; a
    # test keeps the two equal. lazy_loader also keeps the decorator ``skill`` from being
    # replaced by the module ``skillcompose.skill`` when that is imported.
    _EXPORTS = {
        "activation": "RUNNING Activation",
        "blackboard": "DELETED Access Blackboard diff",
        "errors": ("BlackboardAccessError BlackboardKeyError BlackboardTypeError FSAFileError "
                   "FSAValidationError ParamError Problem RegistryError SkillcomposeError "
                   "SkillDefinitionError SkillProtocolError UndeclaredOutcomeError "
                   "UnknownSkillError"),
        "executor": ("CompiledFSA FSARun RunResult TraceStep compile_fsa run_fsa run_ticking "
                     "summarize trial_rngs trial_seeds"),
        "fsa": "DEFAULT_STEP_LIMIT DEFAULT_TERMINALS ERROR FSA PREEMPTED TIMEOUT State",
        "fsafile": "dumps_fsa load_fsa loads_fsa save_fsa",
        "nested": "FSASkill fsa_skill",
        "params": "Choice Param ParamSpec",
        "registry": "Registry",
        "skill": "Skill SkillSpec skill",
        "task": "Task TaskError TaskRef Trial load_task trials",
    }
    __getattr__, _, __all__ = lazy_loader.attach(
        __name__, submod_attrs={module: names.split() for module, names in _EXPORTS.items()}
    )
    __all__ += ["__version__"]

    def __dir__() -> list[str]:
        return sorted(set(globals()) | set(__all__))
