"""Golden traces: a run kept as text, compared as a diff, rewritten on request."""

from __future__ import annotations

from collections import namedtuple
from pathlib import Path

import numpy as np
import pytest

from skillcompose import DELETED
from skillcompose.testing import (
    GoldenTraceError,
    assert_golden_trace,
    golden_text,
    golden_value,
    run_episode,
)

from . import toy

pytest_plugins = ["pytester"]

Point = namedtuple("Point", "x y")


def test_values_are_shown_in_full_with_floats_rounded_and_no_addresses() -> None:
    assert golden_value(0.1 + 0.2) == "0.3"
    assert golden_value(np.float64(0.7)) == "0.7"
    assert golden_value(np.float32(0.7)) == "0.699999988079"  # a float32's own value
    assert golden_value((np.int64(2), [1.0000000000001, True])) == "(2, [1.0, True])"
    assert golden_value(np.array([0.5, 1 / 3])) == "array([0.5, 0.333333333333])"
    assert golden_value(Point(1.0, 2)) == "Point(x=1.0, y=2)"
    assert golden_value({"a": "x" * 100}) == repr({"a": "x" * 100})  # not cut short
    assert golden_value(object()) == "<object object>"
    assert golden_value(DELETED) == "∅"
    assert golden_value("two\nlines") == "'two\\nlines'"


def test_the_trace_of_an_episode() -> None:
    text = golden_text(run_episode(toy.once(), toy.task(0.1), 3))
    assert text.splitlines()[0] == "# FSA toy_once, task toy_fetch, seed 3, backend default"
    assert "   3  Carry (Carry) -> success -> Put\n        gripper_m: ∅ => 0.7\n" in text
    assert text.endswith("ended: success after 4 step(s)\nfitness: 0.0\n")


def test_an_untraced_run_has_no_golden_trace() -> None:
    with pytest.raises(TypeError, match="a golden trace needs a traced run"):
        golden_text(run_episode(toy.once(), toy.task(0.1), 3, trace=False))


def test_compare_update_and_diff(tmp_path: Path) -> None:
    path = tmp_path / "golden" / "once.trace"
    episode = run_episode(toy.once(), toy.task(0.1), 3)
    with pytest.raises(GoldenTraceError, match="does not exist; pass update=True"):
        assert_golden_trace(episode, path)
    assert assert_golden_trace(episode, path, update=True)  # written, folders too
    assert not assert_golden_trace(episode, path, update=True)  # the same: not rewritten
    assert not assert_golden_trace(episode, path)
    edited = toy.once().with_params("Carry", distance=0.5)
    changed = run_episode(edited, toy.task(0.1), 3)
    with pytest.raises(GoldenTraceError) as info:
        assert_golden_trace(changed, path)
    message = str(info.value)
    assert message.startswith(f"the run differs from its golden trace {path}; if the change "
                              "is intended, pass update=True to rewrite it")
    lines = message.split("\n")
    assert "-        gripper_m: ∅ => 0.7" in lines and "+        gripper_m: ∅ => 0.5" in lines
    assert " ended: success after 4 step(s)" in lines  # the same: context
    assert lines[-2:] == ["-fitness: 0.0", "+fitness: 0.2"]


def test_a_changed_fsa_shows_as_a_diff_and_is_updated_on_request(
        pytester: pytest.Pytester) -> None:
    pytester.makefile(".yaml", once=toy.ONCE)
    pytester.makepyfile(test_once='''
        from pathlib import Path
        import pytest

        @pytest.mark.skillcompose(task="examples.toy_task", settings={"p_fail": 0.1})
        def test_seed_3(skillcompose_runner, skillcompose_golden):
            fsa = Path(__file__).with_name("once.yaml")
            skillcompose_golden(skillcompose_runner.episode(fsa, 3))
    ''')
    golden = pytester.path / "golden" / "test_once" / "test_seed_3.trace"
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*GoldenTraceError: golden trace golden/test_once/"
                                 "test_seed_3.trace does not exist; rerun pytest with "
                                 "--skillcompose-update-golden to rewrite it. This run:"])
    assert not golden.exists()

    result = pytester.runpytest("-p", "no:cacheprovider", "--skillcompose-update-golden")
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines(["*skillcompose: 1 golden trace(s) written*",
                                 "golden/test_once/test_seed_3.trace"])
    assert golden.read_text(encoding="utf-8") == golden_text(
        run_episode(toy.once(), toy.task(0.1), 3))
    pytester.runpytest("-p", "no:cacheprovider").assert_outcomes(passed=1)

    edited = toy.ONCE.replace("distance: 0.7", "distance: 0.5")  # a hand edit
    pytester.makefile(".yaml", once=edited)
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([
        "E   *GoldenTraceError: the run differs from its golden trace golden/test_once/"
        "test_seed_3.trace; if the change is intended, rerun pytest with "
        "--skillcompose-update-golden to rewrite it and review the file's diff",
        "E   *--- golden/test_once/test_seed_3.trace (stored)",
        "E   *+++ this run",
        "E   *-        gripper_m: ∅ => 0.7",
        "E   *-        block_m: 0.* => 0.7",
        "E   *+        gripper_m: ∅ => 0.5",
        "E   *+        block_m: 0.* => 0.5",
        "E   *-fitness: 0.0",
        "E   *+fitness: 0.2",
    ])
    pytester.runpytest("-p", "no:cacheprovider", "--skillcompose-update-golden"
                       ).assert_outcomes(passed=1)
    assert "gripper_m: ∅ => 0.5" in golden.read_text(encoding="utf-8")
    pytester.runpytest("-p", "no:cacheprovider").assert_outcomes(passed=1)
