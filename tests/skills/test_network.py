"""The MoveBase networks: sizes per topology, determinism, outputs in range."""

from __future__ import annotations

import numpy as np
import pytest

from skillcompose.skills.network import (
    N_INPUTS,
    N_OUTPUTS,
    TOPOLOGIES,
    LayeredNetwork,
    RecurrentNetwork,
    make_network,
    weight_count,
)


def test_weight_counts() -> None:
    assert weight_count("layered") == 38  # the paper's count: 3*(5+1) + 5*(3+1)
    assert weight_count("recurrent") == 112  # the authors' net: (3+5) * (13+1)
    assert weight_count("layered", 2, 1, 1) == 1 * 3 + 1 * 2
    assert weight_count("layered-12") == 137  # 12*(5+1) + 5*(12+1): not the paper's
    with pytest.raises(ValueError, match="unknown network topology"):
        weight_count("convolutional")  # type: ignore[arg-type]


@pytest.mark.parametrize("topology", TOPOLOGIES)
def test_outputs_are_in_the_unit_interval_and_reproducible(topology: str) -> None:
    rng = np.random.default_rng(0)
    for _ in range(50):
        w = rng.uniform(-3, 3, weight_count(topology))  # type: ignore[arg-type]
        net = make_network(topology, w)  # type: ignore[arg-type]
        x = rng.uniform(-1, 1, N_INPUTS)
        a = net(x, np.random.default_rng(7))
        b = net(x, np.random.default_rng(7))
        assert a.shape == (N_OUTPUTS,)
        assert np.all((a > 0) & (a < 1))
        assert np.array_equal(a, b)  # the same generator state, the same answer


@pytest.mark.parametrize(("topology", "hidden"), [("layered", 3), ("layered-12", 12)])
def test_the_layered_networks_are_the_formula(topology: str, hidden: int) -> None:
    rng = np.random.default_rng(1)
    n1 = hidden * 6
    w = rng.uniform(-3, 3, n1 + 5 * (hidden + 1))
    x = rng.uniform(-1, 1, 5)
    first = w[:n1].reshape(hidden, 6)
    second = w[n1:].reshape(5, hidden + 1)
    z = 1 / (1 + np.exp(-(first[:, :5] @ x + first[:, 5])))
    expected = 1 / (1 + np.exp(-(second[:, :hidden] @ z + second[:, hidden])))
    net = make_network(topology, w.tolist())  # type: ignore[arg-type]
    out = net(x, np.random.default_rng(0))
    assert np.allclose(out, expected)
    assert np.array_equal(out, net(x, np.random.default_rng(99)))  # no draws
    if topology == "layered":
        assert np.array_equal(out, LayeredNetwork(w)(x, np.random.default_rng(0)))
    with pytest.raises(ValueError, match=f"a layered 5-{hidden}-5 network has {w.size} "
                       f"weights, got {w.size - 1}"):
        make_network(topology, w[:-1].tolist())  # type: ignore[arg-type]


def test_the_recurrent_network_updates_synchronously_from_a_random_state() -> None:
    rng = np.random.default_rng(2)
    w = rng.uniform(-3, 3, 112)
    x = rng.uniform(-1, 1, 5)
    net = RecurrentNetwork(w)
    gen = np.random.default_rng(5)
    state = np.concatenate([x, np.random.default_rng(5).random(8)])
    rows = w.reshape(8, 14)
    for _ in range(30):
        state[5:] = 1 / (1 + np.exp(-(rows[:, :13] @ state + rows[:, 13])))
    assert np.allclose(net(x, gen), state[8:])
    # weak self-coupling converges: every start gives the same answer
    calm = RecurrentNetwork(np.full(112, 0.01))
    a, b = calm(x, np.random.default_rng(1)), calm(x, np.random.default_rng(2))
    assert np.allclose(a, b, atol=1e-9)


def test_wrong_lengths_are_refused() -> None:
    with pytest.raises(ValueError, match="has 38 weights, got 37"):
        LayeredNetwork(np.zeros(37))
    with pytest.raises(ValueError, match="has 112 weights, got 38"):
        RecurrentNetwork(np.zeros(38))


def test_instances_are_cached_by_weights() -> None:
    w = tuple(np.linspace(-1, 1, 38))
    assert make_network("layered", w) is make_network("layered", list(w))
    assert make_network("layered", w) is not make_network("layered", w[::-1])
