"""The pytest plugin: installed with the package, light at start-up, its fixtures configured by
a marker or the configuration, and success-rate assertions as a user's tests see them."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest

from . import toy

pytest_plugins = ["pytester"]

RUN = ("-p", "no:cacheprovider")


def test_the_plugin_is_installed_as_an_entry_point() -> None:
    found = {ep.name: ep.value for ep in metadata.entry_points(group="pytest11")}
    assert found.get("skillcompose") == "skillcompose.testing.plugin"


def test_loading_the_plugin_loads_nothing_heavy() -> None:
    code = ("import sys, skillcompose.testing.plugin; print(sorted(m for m in ('numpy', "
            "'hypothesis', 'skillcompose.task', 'skillcompose.executor', 'ruamel.yaml') "
            "if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == "[]"


def test_the_lazy_name_table_equals_the_imports_the_type_checker_reads() -> None:
    package = importlib.import_module("skillcompose.testing")  # its names are lazy
    tree = ast.parse(Path(str(package.__file__)).read_text("utf-8"))
    typed = {(str(a.asname), str(node.module)) for node in ast.walk(tree)
             if isinstance(node, ast.ImportFrom) and node.level == 1 for a in node.names}
    table = {(name, module) for module, names in package._EXPORTS.items()
             for name in names.split()}
    assert typed == table
    assert set(package.__all__) == {name for name, _ in table}
    for name in package.__all__:
        assert getattr(package, name) is not None


def test_the_option_is_in_the_help(pytester: pytest.Pytester) -> None:
    result = pytester.runpytest(*RUN, "--help")
    result.stdout.fnmatch_lines(["*--skillcompose-update-golden*"])


def test_a_0999_fsa_passes_and_a_090_fsa_fails_with_its_interval(
        pytester: pytest.Pytester) -> None:
    pytester.makefile(".yaml", once=toy.ONCE)
    pytester.makepyfile(test_rates=f'''
        from pathlib import Path
        import pytest
        from skillcompose.task import load_task
        from skillcompose.testing import assert_success_rate

        FSA = Path(__file__).with_name("once.yaml")

        def test_0999():
            task = load_task("examples.toy_task", p_fail={toy.P_FAIL_0999})
            check = assert_success_rate(FSA, task, at_least=0.95)
            print("episodes", check.estimate.episodes, "of at most", check.max_episodes)

        @pytest.mark.skillcompose(task="examples.toy_task", settings={{"p_fail": {toy.P_FAIL_090}}})
        def test_090(skillcompose_runner):
            skillcompose_runner.assert_success_rate(FSA, 0.95)
    ''')
    result = pytester.runpytest(*RUN, "-s")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines([
        "*episodes 90 of at most 1440*",  # the early stop: the first look decided
        "*def test_090(skillcompose_runner):",
        ">       skillcompose_runner.assert_success_rate(FSA, 0.95)",  # the user's line
        "E   *SuccessRateError: FSA toy_once on task toy_fetch: the success rate is not shown "
        "to reach 95 % (one-sided lower bound at 95 % confidence)",
        "E   *observed: 90.8 % of 360 fresh episodes (95 % bounds 86.7–94.0 %): below the "
        "required 95 %",
        "E   *episodes: 360 (seeds 0–359), stopped early (at most 1,440): the answer was clear",
        "E   *first failing seed: 5",
        "E   *seed 5: failure after 3 step(s), fitness 1.61938 (not at the target)",
        "E   *   1  Find (FindBlock) -> success -> Pick",
        "E   *        block_seen: ∅ => True",
        "E   *   3  Carry (Carry) -> failure -> failure",
        "E   *ended: failure after 3 step(s)",
        "E   *rerun: skillcompose run */once.yaml --task examples.toy_task --set p_fail=0.05 "
        "--seed 5 --trace",
    ])


def test_the_fixtures_follow_the_configuration_and_the_marker(
        pytester: pytest.Pytester) -> None:
    pytester.makeini("[pytest]\nskillcompose_task = examples.toy_task p_fail=0.25\n")
    pytester.makefile(".yaml", once=toy.ONCE)
    pytester.makepyfile(test_fixtures='''
        from pathlib import Path
        import pytest

        FSA = Path(__file__).with_name("once.yaml")

        def test_configured(skillcompose_task, skillcompose_registry,
                            skillcompose_blackboard, skillcompose_runner):
            assert skillcompose_task.name == "toy_fetch"
            assert skillcompose_task.settings["p_fail"] == 0.25
            assert "Carry" in skillcompose_registry
            world = skillcompose_blackboard(3)
            assert world["p_fail"] == 0.25
            assert world.to_dict() == skillcompose_runner.world(3).to_dict()
            episodes = skillcompose_runner(FSA, range(4))
            assert [e.seed for e in episodes] == [0, 1, 2, 3]
            assert all(e.trace is not None and e.blackboard is not None for e in episodes)
            skillcompose_runner.assert_outcome(FSA, 0, episodes[0].outcome)

        @pytest.mark.skillcompose(settings={"p_fail": 0.5})
        def test_settings_over_the_configured_task(skillcompose_task):
            assert skillcompose_task.settings["p_fail"] == 0.5

        @pytest.mark.skillcompose(skills=["examples.toy_task"], backend="default")
        def test_skills(skillcompose_registry):
            assert sorted(skillcompose_registry.names()) == [
                "Carry", "FindBlock", "PickBlock", "PutDown", "Wait"]

        @pytest.mark.skillcompose(tasks="examples.toy_task")
        def test_a_misspelt_marker(skillcompose_task):
            pass
    ''')
    result = pytester.runpytest(*RUN)
    result.assert_outcomes(passed=3, errors=1)
    result.stdout.fnmatch_lines(["*@pytest.mark.skillcompose takes the keywords task=, "
                                 "settings=, skills= and backend=, got *tasks*"])


def test_a_test_without_a_task_is_told_how_to_give_one(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_none='''
        def test_needs_a_task(skillcompose_runner):
            pass
    ''')
    result = pytester.runpytest(*RUN)
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*no task for the skillcompose fixtures: mark the test "
                                 "@pytest.mark.skillcompose(task='pkg.my_task'), set "
                                 "skillcompose_task in the pytest configuration, or define a "
                                 "fixture skillcompose_task"])


def test_a_fixture_of_ones_own_gives_the_task(pytester: pytest.Pytester) -> None:
    pytester.makeconftest('''
        import pytest
        from skillcompose.task import load_task

        @pytest.fixture(scope="session")
        def skillcompose_task():
            return load_task("examples.toy_task", p_fail=0.0)
    ''')
    pytester.makefile(".yaml", once=toy.ONCE)
    pytester.makepyfile(test_own='''
        from pathlib import Path

        def test_always(skillcompose_runner):
            check = skillcompose_runner.assert_success_rate(
                Path(__file__).with_name("once.yaml"), 0.99)
            assert check.estimate.successes == check.estimate.episodes
    ''')
    pytester.runpytest(*RUN).assert_outcomes(passed=1)
