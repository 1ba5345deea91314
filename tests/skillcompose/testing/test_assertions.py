"""assert_success_rate and assert_outcome: evolution's "solved" statement as a test, on the
episodes `skillcompose run --seed k` shows."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Literal

import numpy as np
import pytest

from skillcompose import Blackboard, Registry, loads_fsa, skill
from skillcompose.cli import main
from skillcompose.stats import SequentialRateTest
from skillcompose.task import Task
from skillcompose.testing import (
    OutcomeError,
    SuccessRateError,
    TaskRunner,
    assert_outcome,
    assert_success_rate,
    check_success_rate,
    run_episode,
)

from . import toy


def test_a_0999_fsa_passes_at_095_at_the_first_look() -> None:
    check = assert_success_rate(toy.once(), toy.task(toy.P_FAIL_0999), at_least=0.95)
    first_look = SequentialRateTest(0.95).schedule[0]
    assert check.passed and check.estimate.lower >= 0.95
    assert check.estimate.episodes == first_look == 90  # stopped early: the answer was clear
    assert check.max_episodes == 1440 > check.estimate.episodes
    assert check.first_failure is None


def test_a_090_fsa_fails_with_its_rate_its_interval_and_its_first_failing_seed() -> None:
    with pytest.raises(SuccessRateError) as info:
        assert_success_rate(toy.once(), toy.task(toy.P_FAIL_090), at_least=0.95)
    check = info.value.check
    est = check.estimate
    assert not check.passed and est.upper < 0.95  # clearly below: decided early
    assert est.episodes < check.max_episodes
    message = str(info.value)
    assert f"{100 * est.rate:.1f} % of {est.episodes} fresh episodes" in message
    assert f"95 % bounds {100 * est.lower:.1f}–{100 * est.upper:.1f} %" in message
    assert "below the required 95 %" in message
    assert f"episodes: {est.episodes} (seeds 0–{est.episodes - 1}), stopped early" in message
    failure = check.first_failure
    assert failure is not None and not failure.success and failure.trace is not None
    assert f"first failing seed: {failure.seed}\n" in message
    assert "ended: failure after" in message  # its trace
    # no seed before it failed
    assert all(e.success for e in TaskRunner(toy.task(toy.P_FAIL_090))(
        toy.once(), range(failure.seed), trace=False))


def test_the_same_seeds_give_the_same_verdict_and_the_rate_matches_the_test() -> None:
    task = toy.task(toy.P_FAIL_090)
    first = check_success_rate(toy.once(), task, 0.95)
    again = check_success_rate(toy.once(), task, 0.95)
    assert first.estimate == again.estimate and first.first_failure is not None
    assert again.first_failure is not None and first.first_failure.seed == again.first_failure.seed
    assert first.first_failure.trace == again.first_failure.trace
    other = check_success_rate(toy.once(), task, 0.95, seed=1000)
    assert other.seeds.start == 1000 and not other.passed
    # the statement is SequentialRateTest's, fed the same episodes
    test = SequentialRateTest(0.95)
    for episode in TaskRunner(task)(toy.once(), first.seeds, trace=False):
        test.add(episode.success)
    assert test.result() == first.estimate


def test_the_required_rate_defaults_to_the_tasks() -> None:
    task = dataclasses.replace(toy.task(toy.P_FAIL_0999), success_rate=0.99)
    check = assert_success_rate(toy.once(), task)
    assert check.estimate.required == 0.99
    assert check.estimate.episodes in SequentialRateTest(0.99).schedule


def test_too_few_episodes_to_show_the_rate_say_so() -> None:
    with pytest.raises(SuccessRateError) as info:
        assert_success_rate(toy.once(), toy.task(0.0), 0.95, max_episodes=10)
    assert "no episode failed, but 10 episodes cannot show a rate of 95 %; allow at " \
        "least 90 (max_episodes)" in str(info.value)


def test_a_deterministic_task_needs_one_episode() -> None:
    task = dataclasses.replace(toy.task(0.0), deterministic=True)
    assert assert_success_rate(toy.once(), task, 0.95).estimate.episodes == 1


def test_the_first_failing_seed_is_the_episode_skillcompose_run_shows(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "once.yaml"
    path.write_text(toy.ONCE, encoding="utf-8")
    with pytest.raises(SuccessRateError) as info:
        assert_success_rate(str(path), toy.task(toy.P_FAIL_090), 0.95)
    failure = info.value.check.first_failure
    assert failure is not None
    command = failure.rerun.split()
    assert command[:2] == ["skillcompose", "run"] and f"--seed {failure.seed}" in failure.rerun
    assert main(command[1:]) == 0
    shown = capsys.readouterr().out
    trace = failure.describe().split("\n")[1:-1]  # between the headline and the rerun line
    assert shown.startswith("\n".join(trace) + "\n")


def test_assert_outcome() -> None:
    task = toy.task(toy.P_FAIL_090)
    episode = assert_outcome(toy.once(), task, 0, "success")
    assert episode.blackboard is not None and episode.blackboard["placed"] is True
    failing = check_success_rate(toy.once(), task, 0.95).first_failure
    assert failing is not None
    with pytest.raises(OutcomeError) as info:
        assert_outcome(toy.once(), task, failing.seed, "success")
    assert str(info.value).startswith(
        f"FSA toy_once on task toy_fetch: expected 'success', got 'failure'\n"
        f"seed {failing.seed}: failure after")
    assert "-> failure -> failure" in str(info.value)


@skill
def explode(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    raise RuntimeError("boom")


def _exploding_task() -> Task:
    return Task(name="explodes", registry=Registry([explode]), setup=lambda rng: Blackboard(),
                fitness=lambda outcome, bb, steps: 0.0 if outcome == "success" else 1.0)


EXPLODING = """\
format: 1
name: explodes
start: Go
states:
  Go: {skill: Explode, transitions: {success: success}}
"""


def test_a_skill_that_raises_fails_its_episode_with_the_error_shown() -> None:
    task = _exploding_task()
    episode = assert_outcome(loads_fsa(EXPLODING), task, 0, "error")
    assert not episode.success and episode.fitness == task.worst
    with pytest.raises(SuccessRateError) as info:
        assert_success_rate(loads_fsa(EXPLODING), task, 0.95)
    assert "first failing seed: 0" in str(info.value)
    assert "state Go raised: RuntimeError: boom" in str(info.value)


def test_the_runner_world_is_the_world_the_episode_starts_from() -> None:
    runner = TaskRunner(toy.task(toy.P_FAIL_0999))
    episode = runner.episode(toy.once(), 3)
    assert episode.trace == run_episode(toy.once(), runner.task, 3).trace
    assert episode.trace is not None
    carried = next(step for step in episode.trace if step.skill == "Carry")
    assert runner.world(3)["block_m"] == carried.changes["block_m"][0]
    assert [e.seed for e in runner(toy.once(), [5, 2], trace=False)] == [5, 2]


@pytest.mark.parametrize("seed", [-1, 2**63, 1.5, True])
def test_a_seed_out_of_range_is_refused(seed: object) -> None:
    with pytest.raises(ValueError, match="expected a whole number from 0"):
        run_episode(toy.once(), toy.task(0.1), seed)  # type: ignore[arg-type]
