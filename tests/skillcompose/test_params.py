"""The one check of parameters and time limits, and the places that report through it."""

from __future__ import annotations

import pytest

from skillcompose import (
    FSA,
    FSAFileError,
    FSAValidationError,
    ParamError,
    Registry,
    State,
    compile_fsa,
    loads_fsa,
)
from skillcompose.params import param_problems, time_limit_problem

FILE = """\
format: 1
start: Move
states:
  Move:
    skill: MoveToObject
    params: {approach: 0.9, speed: 2}
    transitions: {success: success, failure: failure}
    time_limit: 1.5
"""


def test_param_problems_gives_values_and_one_problem_per_bad_entry(registry: Registry) -> None:
    spec = registry.spec("MoveToObject")
    values, problems = param_problems(spec.name, spec.params, {"approach": 0.2, "p_fail": 1},
                                      "Move")
    assert values == {"approach": 0.2, "p_fail": 1.0} and problems == []
    assert type(values["p_fail"]) is float  # each value as its parameter's type
    values, problems = param_problems(spec.name, spec.params, {"approach": 0.9, "speed": 2},
                                      "Move")
    assert values == spec.defaults()  # bad values keep the defaults
    assert [(p.state, p.key) for p in problems] == [("Move", "approach"), ("Move", "speed")]
    assert problems[0].message.startswith("skill MoveToObject: parameter 'approach' = 0.9")
    assert problems[1].message == ("skill MoveToObject has no parameter 'speed'; its "
                                   "parameters are ['approach', 'p_fail']")


def test_the_model_the_reader_and_the_engine_say_the_same(registry: Registry) -> None:
    spec = registry.spec("MoveToObject")
    _, problems = param_problems(spec.name, spec.params, {"approach": 0.9, "speed": 2})
    fsa = loads_fsa(FILE, "move.yaml")
    with pytest.raises(FSAValidationError) as model:
        fsa.validate(registry)
    text = str(model.value)
    assert f"move.yaml:6:24: state Move: {problems[0].message}" in text  # placed by the file
    assert f"move.yaml:6:36: state Move: {problems[1].message}" in text
    with pytest.raises(ParamError) as resolve:
        spec.resolve_params({"approach": 0.9, "speed": 2}, "state Move")
    assert str(resolve.value) == "state Move: " + "; ".join(p.message for p in problems)

    bad = time_limit_problem(-1.0, "Move")
    assert bad is not None and time_limit_problem(1.5) is None
    assert time_limit_problem(True) is not None and time_limit_problem(float("nan")) is not None
    with pytest.raises(FSAFileError) as reader:
        loads_fsa(FILE.replace("1.5", "-1.0"), "move.yaml")
    assert str(reader.value) == f"move.yaml:8:17: {bad.render()}"
    with pytest.raises(FSAValidationError) as built:
        FSA({"Move": State("MoveToObject", {}, {"success": "success"}, -1.0)}, "Move")
    assert str(built.value) == bad.render()
    routes = {"success": "success", "failure": "failure"}
    compiled = compile_fsa(FSA({"Move": State("MoveToObject", {}, routes)}, "Move"), registry)
    with pytest.raises(ParamError, match=r"^time_limits: state Move: the limit must be a "
                       r"positive number of seconds, got -1\.0; write e\.g\. \{'Move': 2\.0\}$"):
        compiled.start(time_limits={"Move": -1.0})


# -- declarations whose values evolution could write but a file could not hold --------------
def _declare(annotation: str, default: str) -> None:
    """Declare a skill ``Knob`` with one parameter ``x`` of ``annotation`` = ``default``."""
    namespace: dict[str, object] = {}
    exec(  # the test builds a signature from text
        "from typing import Annotated, Literal\n"
        "from skillcompose import Choice, Param, skill\n"
        "@skill()\n"
        f"def knob(bb, rng, *, x: {annotation} = {default}) -> Literal['success']:\n"
        "    return 'success'\n",
        namespace,
    )


@pytest.mark.parametrize(("annotation", "default", "message"), [
    ("Annotated[int, Param(0, 10**30)]", "1",
     "skill Knob, parameter 'x': range [0, 1e+30] of a whole number goes beyond ±2**49 "
     "(562949953421312), the largest whole numbers evolution maps to its genes and back "
     "exactly; keep both bounds within it"),
    ("Annotated[int, Param(-2**63, 2**63 - 1)]", "1",
     "skill Knob, parameter 'x': range [-9.22337e+18, 9.22337e+18] of a whole number goes "
     "beyond ±2**49 (562949953421312), the largest whole numbers evolution maps to its genes "
     "and back exactly; keep both bounds within it"),
    ("Annotated[int, Param(0, 2**49 + 1)]", "1",
     "skill Knob, parameter 'x': range [0, 5.6295e+14] of a whole number goes beyond ±2**49"),
    ("Annotated[int, Param(1, 10**400)]", "1",
     "skill Knob, parameter 'x': the bounds must be finite numbers (every value of the range "
     "must be one that evolution can write and FSA files hold), got low 1, high a whole "
     "number of 401 digits; declare a finite range"),
    ("Annotated[float, Param(0.0, float('inf'))]", "1.0",
     "skill Knob, parameter 'x': the bounds must be finite numbers (every value of the range "
     "must be one that evolution can write and FSA files hold), got low 0, high inf; declare "
     "a finite range"),
    ("Annotated[tuple[float, ...], Param(float('-inf'), 0.0, size=3)]", "(0.0,) * 3",
     "skill Knob, parameter 'x': the bounds must be finite numbers"),
    ("Annotated[float, Param(float('nan'), 1.0)]", "0.5",
     "skill Knob, parameter 'x': the bounds must be finite numbers (every value of the range "
     "must be one that evolution can write and FSA files hold), got low nan, high 1; declare "
     "a finite range"),
    ("Annotated[float, Param(-1e308, 1e308)]", "0.0",
     "skill Knob, parameter 'x': range [-1e+308, 1e+308] spans more than the largest float "
     "(1.798e+308), so evolution cannot map it to [0, 1]; narrow it, or use scale='log' for "
     "a positive range"),
    ("Annotated[float, Param('0', 1.0)]", "0.5",
     "skill Knob, parameter 'x': the bounds must be numbers, got low '0', high 1.0; declare "
     "Param(low, high)"),
    ("Annotated[int, Choice(1, 2**64)]", "1",
     "skill Knob, parameter 'x': option 18446744073709551616 cannot be written to an FSA file "
     "and read back as itself; options are text without control characters, whole numbers "
     "within 64 bits, numbers other than NaN, true/false or None"),
    ("Annotated[float, Choice(0.5, float('nan'))]", "0.5",
     "skill Knob, parameter 'x': option nan cannot be written to an FSA file"),
    ("Literal['left', 'ri\\x85ght']", "'left'",
     "skill Knob, parameter 'x': option 'ri\\x85ght' cannot be written to an FSA file"),
    ("Literal['left', b'right']", "'left'",
     "skill Knob, parameter 'x': option b'right' cannot be written to an FSA file"),
])
def test_declarations_evolution_could_not_write_are_refused(
    annotation: str, default: str, message: str,
) -> None:
    with pytest.raises(ParamError) as refused:
        _declare(annotation, default)
    text = str(refused.value)
    assert text.startswith(message) and "\n" not in text


@pytest.mark.parametrize(("annotation", "default"), [
    ("Annotated[int, Param(-2**49, 2**49)]", "0"),
    ("Annotated[float, Param(-1e307, 1e307)]", "0.0"),
    ("Annotated[float, Param(5e-324, 1.7e308, scale='log')]", "1.0"),
    ("Annotated[float, Param(0.0, 5e-324)]", "0.0"),
    ("Annotated[float, Choice(None, True, -0.0, float('inf'), 2**63 - 1, 'é x')]", "None"),
])
def test_declarations_at_the_limits_are_accepted(annotation: str, default: str) -> None:
    _declare(annotation, default)


def test_a_registry_refuses_a_hand_built_spec_it_could_not_write() -> None:
    import numpy as np

    from skillcompose import Skill, SkillSpec
    from skillcompose.params import ParamSpec

    spec = SkillSpec("Knob", ("success",), params=(
        ParamSpec("x", "float", 0.0, low=0.0, high=float("inf")),))
    with pytest.raises(ParamError, match=r"^skill Knob, parameter 'x': the bounds must be "
                       r"finite numbers .* got low 0, high inf; declare a finite range$"):
        Registry([Skill(spec, lambda bb, rng: "success")])
    spec = SkillSpec("Knob", ("success",), params=(
        ParamSpec("x", "int", 0, low=0.0, high=float(2**60)),))
    with pytest.raises(ParamError, match=r"^skill Knob, parameter 'x': range \[0, "
                       r"1\.15292e\+18\] of a whole number goes beyond ±2\*\*49"):
        Registry().add(Skill(spec, lambda bb, rng: "success"))
    fine = SkillSpec("Knob", ("success",), params=(
        ParamSpec("x", "float", 0.0, low=np.float64(0.0), high=np.float64(1.0)),))
    assert len(Registry([Skill(fine, lambda bb, rng: "success")])) == 1


@pytest.mark.parametrize(("low", "high"), [(-2**49, 2**49), (0, 2**49), (-2**49, -2**49 + 7),
                                           (3, 2**49 - 5), (-(10**14), 10**14 + 1)])
def test_whole_numbers_within_the_limit_go_through_the_genes_exactly(low: int, high: int) -> None:
    import random

    from skillcompose.params import MAX_WHOLE_BOUND, Param, make_param_spec

    assert MAX_WHOLE_BOUND == 2**49
    spec = make_param_spec("x", int, Param(low, high), low, "Knob")
    draw = random.Random(low ^ high)
    values = [low, high, low + 1, high - 1, *(draw.randint(low, high) for _ in range(3000))]
    assert [spec.from_genes(spec.to_genes(v)) for v in values] == values


@pytest.mark.parametrize(("value", "fix"), [
    ('"0.6"', "(a number, not text): remove the quotes"),
    ("0.6 m", "(a number): write 0.6 alone, without 'm' (the unit is the skill's)"),
    ("0.6# m", "(a number): put a space before # to start a comment"),
    ("\u22120.6", "(a number): replace the sign \u2212 (U+2212) with the ASCII minus -"),
    ("near", "(a number)"),
    ("0,5", "(a number): write the decimal point as a point: 0.5"),
    ("1/2", "(a number)"),
    ("1.2.3", "(a number)"),
    ("\u20130.1", "(a number): replace the sign \u2013 (U+2013) with the ASCII minus -"),
    ("\uff10.1", "(a number)"),  # full-width digits: not ours to read
    ("5 %", "(a number): write 5 alone, without '%' (the unit is the skill's)"),
])
def test_text_where_a_number_goes_gets_the_fix_for_its_form(
    registry: Registry, value: str, fix: str,
) -> None:
    fsa = loads_fsa(f"format: 1\nstart: Move\nstates:\n  Move:\n    skill: MoveToObject\n"
                    f"    params:\n      approach: {value}\n"
                    "    transitions: {success: success, failure: failure}\n", "f.yaml")
    with pytest.raises(FSAValidationError) as err:
        fsa.validate(registry)
    assert str(err.value).endswith(f"expected float in [0.05, 0.3] m {fix}"), str(err.value)


def test_numpy_numbers_are_taken_as_python_ones(registry: Registry) -> None:
    """A script that computes a parameter with numpy gets it through, as a Python number
    (refused before as "(a number)")."""
    import numpy as np

    fsa = loads_fsa("format: 1\nstart: Move\nstates:\n  Move:\n    skill: MoveToObject\n"
                    "    params: {approach: 0.1}\n"
                    "    transitions: {success: success, failure: failure}\n")
    for value in (np.float64(0.2), np.float32(0.25), np.int64(0) + 0.1):
        fsa.with_params("Move", approach=value).validate(registry)
    with pytest.raises(FSAValidationError, match=r"np.int64\(7\) is not valid; expected "
                       r"float in \[0.05, 0.3\] m; set it between"):  # a number, out of range
        fsa.with_params("Move", approach=np.int64(7)).validate(registry)
    with pytest.raises(FSAValidationError, match=r"np.True_|True"):
        fsa.with_params("Move", approach=np.bool_(True)).validate(registry)
