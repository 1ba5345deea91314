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
