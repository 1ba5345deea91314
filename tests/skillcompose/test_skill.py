from __future__ import annotations

from typing import Annotated, Literal, cast

import numpy as np
import pytest

from skillcompose import (
    Blackboard,
    BlackboardAccessError,
    Param,
    ParamError,
    Skill,
    SkillDefinitionError,
    UndeclaredOutcomeError,
    skill,
)
from skillcompose.skill import camel_name
from tests.skillcompose import demo_skills


def test_decorator_reads_declaration() -> None:
    spec = demo_skills.move_to_object.spec
    assert spec.name == "MoveToObject"
    assert spec.outcomes == ("success", "failure")
    assert spec.reads == frozenset({"jug"})
    assert spec.writes == frozenset({"gripper"})
    approach = spec.param("approach")
    assert (approach.kind, approach.low, approach.high, approach.unit) == ("float", 0.05, 0.3, "m")
    assert approach.default == 0.1


def test_class_skill_kinds() -> None:
    grasp = cast(Skill, demo_skills.GraspObject)  # mypy ignores class decorators: it is a Skill
    spec = grasp.spec
    kinds = {p.name: p.kind for p in spec.params}
    assert kinds == {"force": "int", "arm": "choice", "careful": "bool"}
    assert spec.param("arm").choices == ("left", "right")


def test_param_as_annotation_is_accepted() -> None:
    @skill
    def wave(
        bb: Blackboard, rng: np.random.Generator, *,
        amp: Param(0.0, 2.0, unit="rad") = 1.0,  # type: ignore[valid-type]
    ) -> Literal["success"]:
        return "success"

    assert wave.spec.param("amp").unit == "rad"
    assert wave.spec.param("amp").kind == "float"


def test_camel_names() -> None:
    assert camel_name("move_to_object") == "MoveToObject"
    assert camel_name("MoveBase") == "MoveBase"
    assert camel_name("push") == "Push"


@pytest.mark.parametrize(
    "source, message",
    [
        ("def f(bb, rng, *, x=0.5) -> Literal['success']: ...", "has no range"),
        ("def f(bb, rng, *, x: Annotated[float, Param(0, 1)]) -> Literal['success']: ...",
         "needs a default"),
        ("def f(bb, rng, *, x: Annotated[float, Param(0, 1)] = 2.0) -> Literal['success']: ...",
         "expected float in [0, 1]"),
        ("def f(bb, rng): ...", "declare its outcomes"),
        ("def f(bb, rng, x) -> Literal['success']: ...", "keyword-only"),
        ("def f(bb, rng, **kw) -> Literal['success']: ...", "*args/**kwargs"),
        ("def f(bb, rng, *, x: Annotated[float, Param(2, 1)] = 1.5) -> Literal['ok']: ...",
         "low 2 is above high 1"),
        ("def f(bb, rng, *, x: Annotated[float, Param(0, 1, scale='log')] = 0.5)"
         " -> Literal['ok']: ...", "positive low bound"),
    ],
)
def test_bad_declarations_are_named(source: str, message: str) -> None:
    ns: dict[str, object] = {"Literal": Literal, "Annotated": Annotated, "Param": Param}
    exec(source, ns)
    f = ns["f"]
    assert callable(f)
    with pytest.raises((SkillDefinitionError, ParamError)) as info:
        skill(f)
    assert message in str(info.value)
    assert "skill F" in str(info.value)  # the skill is named


def test_a_class_without_call_or_start_says_what_to_define() -> None:
    class Plain:
        pass

    with pytest.raises(SkillDefinitionError, match="class Plain cannot be a skill: define"):
        skill(Plain)


def test_reads_given_as_a_string_is_an_error() -> None:
    with pytest.raises(SkillDefinitionError, match=r"reads=\('jug',\)"):
        skill(reads="jug", name="Bad", outcomes=("success",))(lambda bb, rng: "success")


def test_direct_call_checks_outcome_and_access() -> None:
    bb = Blackboard({"jug": (1.0, 0.0, 0.0)})
    assert demo_skills.move_to_object(bb, 0, p_fail=0.0) == "success"
    assert bb["gripper"] == pytest.approx((0.9, 0.0, 0.0))
    with pytest.raises(UndeclaredOutcomeError, match="Liar returned 'sucess'"):
        demo_skills.liar(Blackboard(), 0)
    with pytest.raises(BlackboardAccessError, match=r"Sneaky wrote .*'gripper'"):
        demo_skills.sneaky(Blackboard({"jug": 1}), 0)
    with pytest.raises(ParamError, match="approach"):
        demo_skills.move_to_object(bb, 0, approach=5.0)


def test_unit_interval_mapping_round_trips() -> None:
    rng = np.random.default_rng(0)
    grasp = cast(Skill, demo_skills.GraspObject)  # mypy ignores class decorators: it is a Skill
    for p in demo_skills.move_to_object.spec.params + grasp.spec.params:
        for x in rng.random(50):
            v = p.from_unit(float(x))
            p.check(v)
            assert p.from_unit(p.to_unit(v)) == v
    log = Param(0.01, 10.0, scale="log")
    from skillcompose.params import make_param_spec

    spec = make_param_spec("k", float, log, 1.0, "S")
    assert spec.from_unit(0.5) == pytest.approx(np.sqrt(0.01 * 10.0))


def test_local_names_in_the_bb_annotation_are_tolerated() -> None:
    from skillcompose import Blackboard as LocalBlackboard

    @skill
    def local(bb: LocalBlackboard, rng: np.random.Generator) -> Literal["success"]:
        return "success"

    assert local.spec.outcomes == ("success",)
    assert local(LocalBlackboard(), 0) == "success"


def test_declarations_that_could_only_fail_at_run_time_are_refused() -> None:
    async def waits(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
        return "success"

    with pytest.raises(SkillDefinitionError, match="skill waits: an async function is not a "
                       "skill"):
        skill(waits)

    def plain(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
        return "success"

    with pytest.raises(SkillDefinitionError, match=r"skill Plain: writes key 'a' has type 5, "
                       r"which is not a type"):
        skill(writes={"a": 5})(plain)
    with pytest.raises(SkillDefinitionError, match=r"skill Plain: reads=5: write the "
                       r"blackboard keys as a tuple"):
        skill(reads=5)(plain)  # type: ignore[call-overload]
    assert skill(writes={"a": float, "b": None}, reads=("c",))(plain).spec.key_types == {
        "a": float}
