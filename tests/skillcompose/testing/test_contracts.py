"""check_skill: a skill run on generated inputs against its declaration; the strategies it
draws them from."""

from __future__ import annotations

import contextlib
from collections.abc import Generator
from typing import Annotated, Any, Literal

import hypothesis
import hypothesis.strategies as st
import numpy as np
import pytest

from skillcompose import Blackboard, Param, skill
from skillcompose.skill import Skill
from skillcompose.testing import (
    SkillContractError,
    check_skill,
    skill_blackboards,
    skill_params,
)
from skillcompose.testing.contracts import ViolationKind

from . import toy

pytest_plugins = ["pytester"]


@skill
def tune(
    bb: Blackboard, rng: np.random.Generator, *,
    gain: Annotated[float, Param(0.5, 2.0, unit="m")] = 1.0,
    rate: Annotated[float, Param(1e-3, 1.0, scale="log")] = 0.1,
    tries: Annotated[int, Param(1, 5)] = 2,
    careful: bool = False,
    arm: Literal["left", "right"] = "left",
    weights: Annotated[tuple[float, ...], Param(-3, 3, size=4)] = (0.0,) * 4,
) -> Literal["success"]:
    return "success"


@hypothesis.given(skill_params(tune))
def test_the_parameters_drawn_are_within_their_declared_ranges(params: dict[str, Any]) -> None:
    assert tune.spec.resolve_params(params) == params  # each valid, each of its kind


def test_the_bounds_of_a_range_are_drawn() -> None:
    seen: list[float] = []

    @skill(reads=("x",))
    def probe(bb: Blackboard, rng: np.random.Generator, *,
              gain: Annotated[float, Param(0.0, 2.0)] = 1.0) -> Literal["success"]:
        seen.append(gain)
        return "success"

    check_skill(probe, values={"x": 1.0}, examples=50)
    assert {0.0, 2.0} <= set(seen)


def test_the_blackboards_hold_the_declared_reads() -> None:
    task = toy.task(0.1)
    strategy = skill_blackboards(toy.task(0.1).registry.resolve("PickBlock"),
                                 world=task.setup, values={"block_seen": st.booleans()})

    @hypothesis.given(strategy)
    def check(contents: dict[str, Any]) -> None:
        assert set(contents) == {"block_seen", "p_fail", "holding"}  # holding: from the world
        assert contents["p_fail"] == 0.1 and isinstance(contents["block_seen"], bool)

    check()


def test_a_read_without_values_is_refused_in_one_line() -> None:
    pick = toy.task(0.1).registry.resolve("PickBlock")
    with pytest.raises(ValueError) as info:
        check_skill(pick)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("skill PickBlock reads 'block_seen', 'p_fail', for which no "
                              "values are known: give values={'block_seen': ")


def test_a_typed_read_is_drawn_from_its_type() -> None:
    @skill(reads={"speed": float, "name": str, "count": int})
    def typed(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
        assert isinstance(bb["speed"], float) and isinstance(bb["name"], str)
        return "success"

    assert check_skill(typed, examples=20).ok


def test_the_toy_skills_keep_their_contracts() -> None:
    task = toy.task(0.1)
    for name in ("FindBlock", "PickBlock", "Carry", "PutDown", "Wait"):
        report = check_skill(task.registry.resolve(name), world=task.setup,
                             values={"block_seen": st.booleans()}, examples=30)
        assert report.ok and report.examples == 30, report.describe()


def test_the_same_seed_gives_the_same_report() -> None:
    @skill(reads=("x",))
    def coin(bb: Blackboard, rng: np.random.Generator) -> Literal["heads", "tails"]:
        return "heads" if rng.random() < 0.5 else "tails"

    first = check_skill(coin, values={"x": st.floats()}, seed=3, examples=40)
    assert first == check_skill(coin, values={"x": st.floats()}, seed=3, examples=40)


# -- each violation, caught --------------------------------------------------------------------
_state = {"calls": 0}


@skill(reads=("x",), writes=("y",))
def reads_a_secret(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    with contextlib.suppress(Exception):  # the error caught: still an undeclared read
        bb["secret"]
    return "success"


@skill(reads=("x",), writes=("y",))
def writes_too_much(bb: Blackboard, rng: np.random.Generator, *,
                    gain: Annotated[float, Param(0.0, 2.0)] = 1.0) -> Literal["success"]:
    bb["y"] = bb["x"] * gain
    if gain > 1.5:
        bb["z"] = gain
    return "success"


@skill(reads=("x",))
def says_maybe(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    return "maybe" if bb["x"] > 0 else "success"  # type: ignore[return-value]


@skill(reads=("x",))
def remembers(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    _state["calls"] += 1  # state kept between runs
    return "success" if _state["calls"] % 2 else "failure"


@skill(reads=("x",))
def divides(bb: Blackboard, rng: np.random.Generator, *,
            tries: Annotated[int, Param(0, 3)] = 1) -> Literal["success", "failure"]:
    return "success" if 1 / tries < 1 else "failure"


@skill(reads=("x",), writes={"y": float})
def writes_text(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    bb["y"] = "fast"
    return "success"


@pytest.mark.parametrize(("bad", "kind", "says"), [
    (reads_a_secret, "undeclared read", "read blackboard key 'secret', which it does not "
     "declare (reads: ['x']); add it to reads=(...)"),
    (writes_too_much, "undeclared write", "wrote blackboard key 'z', which it does not "
     "declare (writes: ['y']); add it to writes=(...)"),
    (says_maybe, "undeclared outcome", "returned 'maybe', which is not one of its declared "
     "outcomes ['success', 'failure']"),
    (remembers, "differs for the same seed", "returned 'success', then 'failure' when run "
     "twice on the same input and seed"),
    (divides, "raised", "raised ZeroDivisionError: division by zero (test_contracts.py:"),
    (writes_text, "wrong type", "skill WritesText wrote str to blackboard key 'y', which is "
     "typed float"),
])
def test_each_violation_is_caught(bad: Skill, kind: ViolationKind, says: str) -> None:
    with pytest.raises(SkillContractError) as info:
        check_skill(bad, values={"x": st.floats(-1, 1)}, examples=40)
    (violation,) = info.value.report.violations
    assert violation.kind == kind and says in violation.message
    assert f"- {kind}: {says}" in str(info.value)
    assert f"the first: {bad.impl.__name__}(Blackboard({{'x': " in str(info.value)


@skill(reads=("x",))
def waits(bb: Blackboard, rng: np.random.Generator) -> Generator[str, None,
                                                              Literal["success"]]:
    yield "running"
    bb["done"] = True
    return "success"


def test_a_long_running_skill_is_run_to_its_end() -> None:
    with pytest.raises(SkillContractError, match="undeclared write: wrote blackboard key "
                       "'done'"):
        check_skill(waits, values={"x": 0}, examples=5)


def test_check_skill_in_a_pytest_run_reports_each_violation(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_skills='''
        from typing import Annotated, Literal
        import hypothesis.strategies as st
        from skillcompose import Param, skill
        from skillcompose.testing import check_skill

        calls = [0]

        @skill(reads=("x",), writes=("y",))
        def sloppy(bb, rng, *, gain: Annotated[float, Param(0.0, 2.0)] = 1.0
                   ) -> Literal["success", "failure"]:
            calls[0] += 1
            try:
                bb["secret"]
            except Exception:
                pass
            bb["y"] = bb["x"] * gain
            if gain > 1.9:
                bb["z"] = 1
            if gain < 0.1:
                return "maybe"
            if 1.0 < gain < 1.2:
                raise ZeroDivisionError("boom")
            return "success" if calls[0] % 2 else "failure"

        @skill(reads=("x",), writes=("y",))
        def tidy(bb, rng, *, gain: Annotated[float, Param(0.0, 2.0)] = 1.0
                 ) -> Literal["success"]:
            bb["y"] = bb["x"] * gain
            return "success"

        def test_sloppy():
            check_skill(sloppy, values={"x": st.floats(-1, 1)})

        def test_tidy():
            check_skill(tidy, values={"x": st.floats(-1, 1)})
    ''')
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines([
        "*SkillContractError: skill Sloppy broke its contract on 100 generated input(s)*",
        "E   *- undeclared read: read blackboard key 'secret', *",
        "E   *- undeclared write: wrote blackboard key 'z', *",
        "E   *- undeclared outcome: returned 'maybe', *",
        "E   *- raised: raised ZeroDivisionError: boom (test_skills.py:*",
        "E   *- differs for the same seed: *",
    ])
