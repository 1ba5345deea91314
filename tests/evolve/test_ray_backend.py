"""The Ray backend gives the same run as the serial one (needs the optional `ray` extra)."""

from __future__ import annotations

import pytest

from evolve import EvolutionConfig, evolve
from skillcompose.task import load_task

pytestmark = [pytest.mark.slow, pytest.mark.private_network]  # Ray listens: see conftest


def test_ray_backend_equals_serial() -> None:
    ray = pytest.importorskip("ray")
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
