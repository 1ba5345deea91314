"""A Task built by hand: each field is checked where the Task is made, and what its setup
and fitness give back is checked where a trial runs (one line each, naming the fix)."""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

import numpy as np
import pytest

from skillcompose import Blackboard, load_fsa
from skillcompose.task import Task, TaskError, load_task

ROOT_SOLUTION = "tests/evolve/data/toy_solution.yaml"


@pytest.fixture(scope="module")
def toy() -> Task:
    return load_task("examples.toy_task", p_fail=0.0)


@pytest.mark.parametrize(("change", "message"), [
    ({"trials": -1}, "trials = -1: expected a whole number from 1 to 1,000,000"),
    ({"trials": 0}, "trials = 0: expected a whole number from 1 to 1,000,000"),
    ({"trials": True}, "trials = True: expected a whole number from 1 to 1,000,000"),
    ({"step_limit": 10**9}, "step_limit = 1000000000: expected a whole number from 1 to"),
    ({"step_limit": 2.5}, "step_limit = 2.5: expected a whole number from 1 to 1,000,000"),
    ({"minimize": "no"}, "minimize = 'no': expected True or False"),
    ({"deterministic": 1}, "deterministic = 1: expected True or False"),
    ({"skills": "Carry"}, "skills = 'Carry': expected a tuple of skill names"),
    ({"terminals": "success"}, "terminals = 'success': expected a tuple of names"),
    ({"target": "0"}, "target = '0': expected a finite number"),
    ({"setup": None}, "setup = None: expected a function"),
])
def test_a_field_out_of_its_kind_is_refused_when_the_task_is_made(
    toy: Task, change: dict[str, Any], message: str,
) -> None:
    with pytest.raises(TaskError) as err:
        dataclasses.replace(toy, **change)
    assert str(err.value).startswith(f"task toy_fetch: {message}")


def test_numpy_whole_numbers_are_taken_as_python_ones(toy: Task) -> None:
    whole: dict[str, Any] = {"trials": np.int64(3), "step_limit": np.int32(30)}
    task = dataclasses.replace(toy, **whole)
    assert (task.trials, task.step_limit) == (3, 30) and type(task.trials) is int


@pytest.mark.parametrize(("change", "error"), [
    ({"setup": lambda rng: {"p_fail": 0.0}},
     "task examples.toy_task: the world setup returned {'p_fail': 0.0}, not a Blackboard; "
     "return one"),
    ({"fitness": lambda outcome, bb, steps: "low"},
     "task examples.toy_task: the fitness of task toy_fetch returned 'low', not a number; "
     "return a float"),
    ({"fitness": lambda outcome, bb, steps: math.nan},
     "task examples.toy_task: the fitness of task toy_fetch returned NaN; return a number"),
])
def test_what_setup_and_fitness_give_back_is_checked_as_a_trial_runs(
    toy: Task, change: dict[str, Any], error: str,
) -> None:
    """Evolution counts such an episode as a fault, with this as its first error (NaN was
    taken for the worst score without a word)."""
    task = dataclasses.replace(toy, **change)
    with pytest.raises(TaskError) as err:
        _run(task)
    assert str(err.value).startswith(error)


def _run(task: Task) -> list[float]:
    compiled = task.compile(load_fsa(ROOT_SOLUTION))
    return [trial.fitness for trial in task.guarded().each_trial(compiled, 0, 1)]


@pytest.mark.parametrize("value", [np.float64(0.25), np.array(0.25), 0.25, 1, np.int64(2)])
def test_a_fitness_float_takes_is_a_number(toy: Task, value: Any) -> None:
    """numpy scalars and 0-d arrays (what np.where gives) are numbers, as float() says."""
    from decimal import Decimal

    for v in (value, Decimal("0.25")):
        def fitness(outcome: str, bb: Blackboard, steps: int, v: Any = v) -> Any:
            return v

        assert _run(dataclasses.replace(toy, fitness=fitness)) == [float(v)]


def test_a_huge_fitness_and_numpy_truth_values() -> None:
    task = load_task("examples.toy_task", p_fail=0.0)
    huge = dataclasses.replace(task, fitness=lambda outcome, bb, steps: 10**400)
    with pytest.raises(TaskError, match=r"returned 1000.*, beyond ±1.8e308"):
        _run(huge)
    numpy_false: Any = np.bool_(False)
    assert dataclasses.replace(task, minimize=numpy_false).minimize is False
    assert dataclasses.replace(task, target=10**400).target == 10**400


def test_a_blackboard_from_setup_is_taken_as_it_is(toy: Task) -> None:
    assert isinstance(toy.setup(np.random.default_rng(0)), Blackboard)
    assert _run(toy) == [_run(toy)[0]]


def test_compiling_and_running_take_what_they_say(toy: Task) -> None:
    from skillcompose import compile_fsa, run_fsa

    with pytest.raises(TypeError, match="compile_fsa takes an FSA, got str; load the file with "
                       "load_fsa"):
        compile_fsa(ROOT_SOLUTION, toy.registry)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="compile_fsa takes a Registry, got NoneType"):
        compile_fsa(load_fsa(ROOT_SOLUTION), None)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="compile_fsa takes an FSA, got str"):
        run_fsa(ROOT_SOLUTION, toy.registry)  # type: ignore[arg-type]
    compiled = toy.compile(load_fsa(ROOT_SOLUTION))
    with pytest.raises(TypeError, match=r"a run takes a Blackboard \(or None\), got dict; "
                       r"wrap it: Blackboard"):
        compiled.run({"p_fail": 0.0})  # type: ignore[arg-type]


@pytest.mark.parametrize(("field", "value", "says"), [
    ("registry", None, "registry = None: expected a skillcompose.Registry"),
    ("backend", "nope", "backend = 'nope': no skill of its registry has it; choose one of"),
    ("target", math.inf, "target = inf: expected a finite number"),
    ("target", -math.inf, "target = -inf: expected a finite number"),
    ("error_fitness", "bad", "error_fitness = 'bad': expected a number"),
    ("error_fitness", math.nan, "error_fitness = nan: expected a number"),
    ("settings", [1], "settings = [1]: expected a mapping of setting names"),
    ("settings", {1: 2}, "settings = {1: 2}: expected a mapping"),
    ("success_rate", 1, "success_rate = 1: expected a rate between 0 and 1"),
])
def test_more_fields_are_checked_where_the_task_is_made(field: str, value: object,
                                                         says: str) -> None:
    task = load_task("examples.toy_task")
    fields = {"name": "t", "registry": task.registry, "setup": task.setup,
              "fitness": task.fitness, field: value}
    with pytest.raises(TaskError, match=re.escape(says)):
        Task(**fields)  # type: ignore[arg-type]
