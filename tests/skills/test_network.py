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


def test_the_layered_network_is_the_formula() -> None:
    rng = np.random.default_rng(1)
    w = rng.uniform(-3, 3, 38)
    x = rng.uniform(-1, 1, 5)
    first = w[:18].reshape(3, 6)
    second = w[18:].reshape(5, 4)
    hidden = 1 / (1 + np.exp(-(first[:, :5] @ x + first[:, 5])))
    expected = 1 / (1 + np.exp(-(second[:, :3] @ hidden + second[:, 3])))
    out = LayeredNetwork(w)(x, np.random.default_rng(0))
    assert np.allclose(out, expected)
    assert np.array_equal(out, LayeredNetwork(w)(x, np.random.default_rng(99)))  # no draws


def test_the_wider_layered_network_has_twelve_hidden_units() -> None:
    rng = np.random.default_rng(3)
    w = rng.uniform(-3, 3, 137)
    x = rng.uniform(-1, 1, 5)
    first = w[:72].reshape(12, 6)
    second = w[72:].reshape(5, 13)
    hidden = 1 / (1 + np.exp(-(first[:, :5] @ x + first[:, 5])))
    expected = 1 / (1 + np.exp(-(second[:, :12] @ hidden + second[:, 12])))
    out = make_network("layered-12", w.tolist())(x, np.random.default_rng(0))
    assert np.allclose(out, expected)
    with pytest.raises(ValueError, match="a layered 5-12-5 network has 137 weights, got 38"):
        make_network("layered-12", w[:38].tolist())


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
