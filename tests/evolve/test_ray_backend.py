"""The Ray backend gives the same run as the serial one (needs the optional `ray` extra)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, NamedTuple

import pytest

from skillcompose.evolve import EvolutionConfig, evolve
from skillcompose.task import load_task

pytestmark = [pytest.mark.slow, pytest.mark.private_network]  # Ray listens: see conftest


def test_ray_backend_equals_serial() -> None:
    """evolve starts a local Ray of its own (none running: the shared one of
    tests/evolve/conftest.py is stopped) and gives the serial run."""
    ray = pytest.importorskip("ray")
    if ray.is_initialized():
        ray.shutdown()
    task = load_task("examples.toy_task", p_fail=0.2)
    cfg = EvolutionConfig(population=60, trials=3, generations=6, initial_nodes=10,
                          common_random_numbers=True, elitism=1)
    try:
        serial = evolve(task, cfg, seed=3, backend="serial", simplify_result=False)
        on_ray = evolve(task, cfg, seed=3, backend="ray", workers=2, simplify_result=False)
    finally:
        if ray.is_initialized():
            ray.shutdown()
    assert [(r.best, r.mean, r.median, r.best_size) for r in serial.history] == \
        [(r.best, r.mean, r.median, r.best_size) for r in on_ray.history]
    assert serial.best_fsa == on_ray.best_fsa


def test_the_ray_tests_run_where_nothing_can_reach_them() -> None:
    """The ``private_network`` marker (tests/conftest.py) runs a test where loopback is the
    only interface: what a local Ray listens on there serves this machine alone."""
    import socket

    assert [name for _, name in socket.if_nameindex()] == ["lo"]


class _Counted(NamedTuple):
    """A Ray evaluator of 2 actors for 64 toy jobs, the serial fitnesses, and the sizes of
    the chunks sent (each chunk's jobs as they are packed)."""

    evaluator: Any
    jobs: list[Any]
    serial: list[float]
    sizes: list[int]


@pytest.fixture
def counted(monkeypatch: pytest.MonkeyPatch, local_ray: Any) -> Iterator[_Counted]:
    import numpy as np

    import skillcompose.evolve.ray_backend as ev_mod
    from skillcompose.evolve import Job, RayEvaluator, SerialEvaluator, SkillSet, initialize

    task = load_task("examples.toy_task", p_fail=0.2)
    skills = SkillSet.from_task(task)
    rng = np.random.default_rng(0)
    jobs = [Job.of(initialize(skills, rng, 8), 0, (1, 0, i), 2) for i in range(64)]
    sizes: list[int] = []
    pack = ev_mod._pack

    def packed(chunk: list[Job]) -> bytes:
        sizes.append(len(chunk))
        return pack(chunk)

    monkeypatch.setattr(ev_mod, "_pack", packed)
    evaluator = RayEvaluator(task, skills, workers=2)
    try:
        yield _Counted(evaluator, jobs, SerialEvaluator(task, skills).evaluate(jobs), sizes)
    finally:
        evaluator.close()
    assert local_ray.is_initialized()  # the evaluator left the Ray it was given running


def test_a_generation_is_cut_in_batches_of_one_chunk_per_actor(
    counted: _Counted, monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Factoring: each batch gives every actor an equal chunk of a half share of what is
    left (``chunks_per_worker`` 2), none under the floor; a generation with less work than
    the floor per actor goes out in one even chunk per actor."""
    import skillcompose.evolve.ray_backend as ev_mod

    evaluator, jobs, serial, sizes = counted
    assert evaluator.evaluate(jobs) == serial  # untimed: an eighth of a share at least
    assert sum(sizes) == 64 and sizes[:2] == [16, 16]
    sizes.clear()
    # timed: 64 toy jobs are less work than the floor (made so whatever the machine's load)
    monkeypatch.setattr(ev_mod, "_MIN_CHUNK_S", 1e9)
    assert evaluator.evaluate(jobs) == serial
    assert sizes == [32, 32]
    monkeypatch.setattr(ev_mod, "_MIN_CHUNK_S", 0.0)
    sizes.clear()
    assert evaluator.evaluate(jobs) == serial
    assert sorted(sizes, reverse=True) == [16, 16, 8, 8, 4, 4, 2, 2, 2, 2]


def test_a_generation_given_as_it_is_bred_goes_out_as_it_comes(
    counted: _Counted, monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Streaming: jobs handed over by a generator with their expected number reach the
    actors while the generator still runs (evolve() breeds that way), in chunks of a
    quarter of each actor's share of the expected jobs, and the fitnesses are the serial
    ones; a list goes out by factoring, as before."""
    evaluator, jobs, serial, sizes = counted
    sent_before: list[int] = []  # chunks sent when each job was handed over

    def bred() -> Iterator[Any]:
        for job in jobs:
            sent_before.append(len(sizes))
            yield job

    assert evaluator.evaluate(bred(), expected=64) == serial
    # a chunk of 8 sent as each 8 jobs come, until both actors hold two; what comes back
    # meanwhile, and what is left at the end, depends on timing
    assert sum(sizes) == 64 and sizes[:4] == [8] * 4
    assert sent_before[:33] == [0] * 8 + [1] * 8 + [2] * 8 + [3] * 8 + [4]
    sizes.clear()
    import skillcompose.evolve.ray_backend as ev_mod

    # whole: factoring, of less work than the floor (made so whatever the machine's load)
    floor = ev_mod._MIN_CHUNK_S
    monkeypatch.setattr(ev_mod, "_MIN_CHUNK_S", 1e9)
    assert evaluator.evaluate(jobs, expected=64) == serial
    assert sizes == [32, 32]
    monkeypatch.setattr(ev_mod, "_MIN_CHUNK_S", floor)
    assert evaluator.evaluate(iter(()), expected=64) == []  # a generation all cached
    assert evaluator.evaluate(bred(), expected=100) == serial  # fewer than expected

    def broken() -> Iterator[Any]:  # breeding raises half-way, chunks in flight
        yield from jobs[::-1][:40]  # other jobs at those positions
        raise RuntimeError("breeding failed")

    with pytest.raises(RuntimeError, match="breeding failed"):
        evaluator.evaluate(broken(), expected=64)
    assert evaluator.evaluate(jobs) == serial  # nothing of the broken one mixed in
    evaluator.groups = 2  # islands: the whole generation first
    sent_before.clear()
    sizes.clear()
    assert evaluator.evaluate(bred(), expected=64) == serial
    assert max(sent_before) == 0


def test_jobs_take_a_direct_connection_and_fall_back_to_rays_calls(
    counted: _Counted, monkeypatch: pytest.MonkeyPatch,
) -> None:
    """By default each actor's chunks go over a connection of its own; when the driver
    cannot connect to a live actor, it says so once and the jobs go through Ray's calls,
    with the same fitnesses."""
    import skillcompose.evolve.ray_backend as ev_mod
    from skillcompose.evolve import RayEvaluator, SkillSet

    evaluator, jobs, serial, _ = counted
    assert evaluator.direct
    assert [a.conn is not None for a in evaluator._actors] == [True, True]
    assert evaluator.evaluate(jobs) == serial
    evaluator.close(keep_ray=True)  # its CPUs, for the next

    def refused(address: tuple[str, int], key: bytes) -> Any:
        raise ConnectionRefusedError(111, "Connection refused")

    monkeypatch.setattr(ev_mod, "connect", refused)
    with pytest.warns(RuntimeWarning, match=r"could not connect to a Ray actor at .*"
                      r"Connection refused.*through Ray's calls instead"):
        fallback = RayEvaluator(evaluator.task, SkillSet.from_task(evaluator.task), workers=2)
    try:
        assert not fallback.direct and [a.conn for a in fallback._actors] == [None, None]
        assert fallback.evaluate(jobs) == serial
        assert fallback.evaluate(iter(jobs), expected=len(jobs)) == serial
    finally:
        fallback.close()
