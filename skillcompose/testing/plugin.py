"""The pytest plugin: fixtures over :mod:`skillcompose.testing`, and golden-trace updates.

Installed with the package (entry point ``pytest11``), so every pytest run in an environment
that holds skillcompose has it. It loads nothing heavy until a fixture is used.

Which task and skills a test's fixtures use: the test's marker
``@pytest.mark.skillcompose(task="pkg.my_task", settings={"p_fail": 0.1}, skills=[...],
backend="sim")``, else the configuration (``skillcompose_task = pkg.my_task p_fail=0.1``,
``skillcompose_skills``, ``skillcompose_backend`` in ``[tool.pytest.ini_options]``), else a
fixture of the same name that you define (a ``conftest.py`` fixture ``skillcompose_task``
returning a :class:`~skillcompose.task.Task` wins over both).

Fixtures:

- ``skillcompose_task``: the task (:func:`~skillcompose.task.load_task`).
- ``skillcompose_registry``: a registry of the skill modules, else the task's.
- ``skillcompose_blackboard``: ``make(seed=0)``, the world the episode of ``seed`` starts
  from (the task's ``setup``).
- ``skillcompose_runner``: a :class:`~skillcompose.testing.TaskRunner` on the task:
  ``runner(fsa, seeds)``, ``runner.assert_success_rate(fsa, 0.95)``, ...
- ``skillcompose_golden``: ``golden(run, name=None)`` compares a traced run with the file
  ``golden/<test module>/<test>[-<name>].trace`` beside the test module;
  ``pytest --skillcompose-update-golden`` writes the files instead.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from ..blackboard import Blackboard
    from ..executor import RunResult
    from ..registry import Registry
    from ..task import Task
    from .episodes import Episode
    from .runner import TaskRunner

__all__ = ["GoldenTraces"]

UPDATE_OPTION = "--skillcompose-update-golden"
_WRITTEN = pytest.StashKey[list[Path]]()
"""The golden files this session wrote (the session's config holds the list)."""


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("skillcompose", "skillcompose: testing skills and FSAs")
    group.addoption(UPDATE_OPTION, action="store_true", default=False,
                    dest="skillcompose_update_golden",
                    help="write the golden traces the skillcompose_golden fixture checks, "
                    "instead of comparing runs with them")
    parser.addini("skillcompose_task", "the task of the skillcompose fixtures: a module "
                  "(make_task) and its settings, e.g. `pkg.my_task p_fail=0.1`", default="")
    parser.addini("skillcompose_skills", "skill modules of the skillcompose_registry "
                  "fixture (default: the task's skills)", type="linelist", default=[])
    parser.addini("skillcompose_backend", "the backend the skillcompose fixtures run "
                  "(default: the task's)", default="")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "skillcompose(task=None, settings=None, skills=(), backend=None): the "
        "task (a module with make_task, and its settings), skill modules and backend of "
        "this test's skillcompose fixtures")
    config.stash[_WRITTEN] = []


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter, exitstatus: int,
                            config: pytest.Config) -> None:
    written = config.stash.get(_WRITTEN, [])
    if written:
        terminalreporter.write_sep("-", f"skillcompose: {len(written)} golden trace(s) "
                                   "written")
        for path in written:
            terminalreporter.write_line(_relative(path, config.rootpath))


@dataclass(frozen=True)
class _Choice:
    """The task, skills and backend that a test's fixtures use."""

    task: str | None
    settings: dict[str, Any] = field(default_factory=dict)
    skills: tuple[str, ...] = ()
    backend: str | None = None


def _choice(request: pytest.FixtureRequest) -> _Choice:
    """The test's marker over the configuration's ``skillcompose_*`` settings."""
    config = request.config
    marker = request.node.get_closest_marker("skillcompose")
    given: dict[str, Any] = dict(marker.kwargs) if marker is not None else {}
    unknown = sorted(set(given) - {"task", "settings", "skills", "backend"})
    if unknown or (marker is not None and marker.args):
        pytest.fail("@pytest.mark.skillcompose takes the keywords task=, settings=, skills= "
                    f"and backend=, got {unknown or list(marker.args if marker else ())}",
                    pytrace=False)
    settings = dict(given.get("settings") or {})
    task = given.get("task")
    if task is None:  # the configuration's task, its settings under the marker's
        words = str(config.getini("skillcompose_task") or "").split()
        if words:
            from ..task import parse_settings

            task, settings = words[0], {**parse_settings(words[1:]), **settings}
    skills = given.get("skills", config.getini("skillcompose_skills"))
    return _Choice(task, settings, (skills,) if isinstance(skills, str) else tuple(skills),
                   given.get("backend", config.getini("skillcompose_backend") or None))


@pytest.fixture
def skillcompose_task(request: pytest.FixtureRequest) -> Task:
    """The task of this test (its marker, else the configuration's ``skillcompose_task``)."""
    from ..task import load_task

    choice = _choice(request)
    if not choice.task:
        pytest.fail("no task for the skillcompose fixtures: mark the test "
                    "@pytest.mark.skillcompose(task='pkg.my_task'), set skillcompose_task in "
                    "the pytest configuration, or define a fixture skillcompose_task",
                    pytrace=False)
    return load_task(choice.task, **choice.settings)


@pytest.fixture
def skillcompose_registry(request: pytest.FixtureRequest) -> Registry:
    """The registry of this test's skill modules, else its task's."""
    from ..registry import DEFAULT_BACKEND, Registry

    choice = _choice(request)
    if choice.skills:
        return Registry.from_modules(choice.skills, backend=choice.backend or DEFAULT_BACKEND)
    task: Task = request.getfixturevalue("skillcompose_task")
    return task.registry


@pytest.fixture
def skillcompose_runner(request: pytest.FixtureRequest,
                        skillcompose_task: Task) -> TaskRunner:
    """Runs FSAs on this test's task, with its backend (see the module's docstring)."""
    from .runner import TaskRunner

    return TaskRunner(skillcompose_task, _choice(request).backend)


@pytest.fixture
def skillcompose_blackboard(skillcompose_task: Task) -> Callable[..., Blackboard]:
    """``make(seed=0)``: the world the episode of ``seed`` starts from."""
    from .episodes import episode_world

    def make(seed: int = 0) -> Blackboard:
        return episode_world(skillcompose_task, seed)

    return make


class GoldenTraces:
    """``golden(run, name=None)``: compare a traced run (an episode, or a ``RunResult``)
    with its golden file, or write the file under ``--skillcompose-update-golden``."""

    def __init__(self, folder: Path, test: str, update: bool, written: list[Path]) -> None:
        self.folder = folder
        self.test = test
        self.update = update
        self._written = written

    def path(self, name: str | None = None) -> Path:
        """The golden file of this test (and ``name``, for a second trace of one test)."""
        stem = _safe(self.test) + (f"-{_safe(name)}" if name else "")
        return self.folder / f"{stem}.trace"

    def __call__(self, run: Episode | RunResult, name: str | None = None) -> None:
        __tracebackhide__ = True
        from .golden import assert_golden_trace

        path = self.path(name)
        if assert_golden_trace(run, path, update=self.update,
                               hint=f"rerun pytest with {UPDATE_OPTION} to rewrite it"):
            self._written.append(path)


@pytest.fixture
def skillcompose_golden(request: pytest.FixtureRequest) -> GoldenTraces:
    """Golden traces of this test, in ``golden/<test module>/`` beside it."""
    module = Path(request.path)
    return GoldenTraces(module.parent / "golden" / module.stem, request.node.name,
                        bool(request.config.getoption("skillcompose_update_golden")),
                        request.config.stash.get(_WRITTEN, []))


def _safe(name: str) -> str:
    """``name`` as a file name: letters, digits, ``_ . -``."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("._") or "trace"


def _relative(path: Path, root: Path) -> str:
    try:
        return str(path.relative_to(root))
    except ValueError:
        return str(path)
