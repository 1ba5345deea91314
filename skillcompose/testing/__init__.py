"""Testing skills and FSAs: statistical assertions, skill contract checks, golden traces.

::

    from skillcompose.testing import assert_success_rate, assert_outcome, check_skill

    def test_the_fsa_holds():
        assert_success_rate("best.yaml", load_task("my_task"), at_least=0.95)

The pytest plugin (:mod:`skillcompose.testing.plugin`, active when the package is
installed) adds fixtures over the same functions and ``--skillcompose-update-golden``; see
docs/testing.md. Nothing here imports pytest; ``hypothesis`` is imported when a skill check
builds its strategies.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .assertions import CheckFailed as CheckFailed
    from .assertions import OutcomeError as OutcomeError
    from .assertions import RateCheck as RateCheck
    from .assertions import SuccessRateError as SuccessRateError
    from .assertions import assert_outcome as assert_outcome
    from .assertions import assert_success_rate as assert_success_rate
    from .assertions import check_success_rate as check_success_rate
    from .contracts import ContractReport as ContractReport
    from .contracts import SkillContractError as SkillContractError
    from .contracts import Violation as Violation
    from .contracts import ViolationKind as ViolationKind
    from .contracts import check_skill as check_skill
    from .contracts import skill_blackboards as skill_blackboards
    from .contracts import skill_params as skill_params
    from .episodes import Episode as Episode
    from .episodes import FSALike as FSALike
    from .episodes import compile_for as compile_for
    from .episodes import episode_world as episode_world
    from .episodes import run_episode as run_episode
    from .episodes import run_episodes as run_episodes
    from .golden import GoldenTraceError as GoldenTraceError
    from .golden import assert_golden_trace as assert_golden_trace
    from .golden import golden_text as golden_text
    from .golden import golden_value as golden_value
    from .runner import TaskRunner as TaskRunner
else:
    import lazy_loader

    # Imported on first use, as the package's own names are: the pytest plugin imports this
    # package at every pytest start-up, which should load neither numpy nor the runtime.
    _EXPORTS = {
        "assertions": ("CheckFailed OutcomeError RateCheck SuccessRateError assert_outcome "
                       "assert_success_rate check_success_rate"),
        "contracts": ("ContractReport SkillContractError Violation ViolationKind check_skill "
                      "skill_blackboards skill_params"),
        "episodes": "Episode FSALike compile_for episode_world run_episode run_episodes",
        "golden": "GoldenTraceError assert_golden_trace golden_text golden_value",
        "runner": "TaskRunner",
    }
    __getattr__, __dir__, __all__ = lazy_loader.attach(
        __name__, submod_attrs={module: names.split() for module, names in _EXPORTS.items()}
    )
