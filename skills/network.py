"""The neural networks whose weights an FSA state evolves (paper §4.2, MoveBase).

The paper's MoveBase "is executed based on a fully recurrent neural network with 5 inputs,
3 hidden neurons and 5 outputs" and needs "38 parameters". The two statements disagree, so
both topologies are offered and reported:

- ``"layered"``: inputs → 3 sigmoid hidden units → 5 sigmoid outputs, each unit with a
  bias: ``3·(5+1) + 5·(3+1) = 38`` weights, the paper's count. Deterministic.
- ``"recurrent"``: the authors' fully recurrent network (PyRecurrentNet): ``N = 5+3+5``
  neurons; the inputs are clamped, and every other neuron ``i`` is updated synchronously
  ``x_i ← sigmoid(b_i + Σ_j W_ij x_j)`` over all ``N`` neurons, 30 times, from a state drawn
  at random; the outputs are the last 5 neurons. ``(3+5)·(13+1) = 112`` weights. The
  random start is drawn from the run's generator, so the same seed gives the same outputs,
  and a second activation in the same run may answer differently (a retry can help).

Weights are parameters in ``[-3, 3]`` (the authors' ``-3 + 6p`` for a gene ``p`` in [0, 1]).
Networks are small, so a plain numpy implementation is fastest; an instance is cached per
weight vector because an FSA state calls the same network many times.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "HIDDEN",
    "N_HIDDEN",
    "N_INPUTS",
    "N_OUTPUTS",
    "RECURRENT_UPDATES",
    "TOPOLOGIES",
    "WEIGHT_RANGE",
    "LayeredNetwork",
    "Network",
    "RecurrentNetwork",
    "Topology",
    "make_network",
    "weight_count",
]

Topology = Literal["layered", "recurrent", "layered-12"]
TOPOLOGIES: tuple[Topology, ...] = ("layered", "recurrent", "layered-12")
N_INPUTS, N_HIDDEN, N_OUTPUTS = 5, 3, 5
HIDDEN: dict[Topology, int] = {"layered": N_HIDDEN, "recurrent": N_HIDDEN, "layered-12": 12}
"""Hidden units of each topology's network."""
RECURRENT_UPDATES = 30
WEIGHT_RANGE = (-3.0, 3.0)
FloatArray = NDArray[np.float64]


def weight_count(
    topology: Topology, n_in: int = N_INPUTS, n_hidden: int | None = None,
    n_out: int = N_OUTPUTS,
) -> int:
    """How many weights (biases included) a network of ``topology`` has (``n_hidden``
    defaults to the topology's own, :data:`HIDDEN`)."""
    if topology not in TOPOLOGIES:
        raise ValueError(f"unknown network topology {topology!r}; use one of {TOPOLOGIES}")
    if n_hidden is None:
        n_hidden = HIDDEN[topology]
    if topology == "recurrent":
        return (n_hidden + n_out) * (n_in + n_hidden + n_out + 1)
    return n_hidden * (n_in + 1) + n_out * (n_hidden + 1)


def _sigmoid(z: FloatArray) -> FloatArray:
    out: FloatArray = 1.0 / (1.0 + np.exp(-z))
    return out


class LayeredNetwork:
    """Inputs → sigmoid hidden layer → sigmoid outputs (weights then bias per unit)."""

    topology: Topology = "layered"

    def __init__(
        self, weights: Sequence[float] | FloatArray, n_in: int = N_INPUTS, n_hidden: int = N_HIDDEN,
        n_out: int = N_OUTPUTS,
    ) -> None:
        w = np.asarray(weights, dtype=np.float64)
        expected = weight_count("layered", n_in, n_hidden, n_out)
        if w.shape != (expected,):
            raise ValueError(f"a layered {n_in}-{n_hidden}-{n_out} network has {expected} "
                             f"weights, got {w.size}")
        first = w[: n_hidden * (n_in + 1)].reshape(n_hidden, n_in + 1)
        second = w[n_hidden * (n_in + 1):].reshape(n_out, n_hidden + 1)
        self.w1, self.b1 = first[:, :n_in].copy(), first[:, n_in].copy()
        self.w2, self.b2 = second[:, :n_hidden].copy(), second[:, n_hidden].copy()
        self.n_in, self.n_out = n_in, n_out

    def __call__(self, inputs: FloatArray, rng: np.random.Generator) -> FloatArray:
        """Outputs in (0, 1); ``rng`` is not used (the network is deterministic)."""
        hidden = _sigmoid(self.w1 @ inputs + self.b1)
        return _sigmoid(self.w2 @ hidden + self.b2)


class RecurrentNetwork:
    """The authors' fully recurrent network: clamped inputs, synchronous updates."""

    topology: Topology = "recurrent"

    def __init__(
        self, weights: Sequence[float] | FloatArray, n_in: int = N_INPUTS, n_hidden: int = N_HIDDEN,
        n_out: int = N_OUTPUTS, updates: int = RECURRENT_UPDATES,
    ) -> None:
        w = np.asarray(weights, dtype=np.float64)
        n = n_in + n_hidden + n_out
        expected = weight_count("recurrent", n_in, n_hidden, n_out)
        if w.shape != (expected,):
            raise ValueError(f"a fully recurrent {n_in}-{n_hidden}-{n_out} network has "
                             f"{expected} weights, got {w.size}")
        rows = w.reshape(n_hidden + n_out, n + 1)
        self.w, self.b = rows[:, :n].copy(), rows[:, n].copy()
        self.n_in, self.n_out, self.n = n_in, n_out, n
        self.updates = updates

    def __call__(self, inputs: FloatArray, rng: np.random.Generator) -> FloatArray:
        """Outputs in (0, 1) after ``updates`` synchronous updates from a random state."""
        state = np.empty(self.n)
        state[: self.n_in] = inputs
        state[self.n_in:] = rng.random(self.n - self.n_in)
        w, b, rest = self.w, self.b, state[self.n_in:]
        for _ in range(self.updates):
            rest[:] = _sigmoid(w @ state + b)
        return state[self.n - self.n_out:].copy()


Network = LayeredNetwork | RecurrentNetwork


@functools.lru_cache(maxsize=256)
def _cached(topology: Topology, weights: tuple[float, ...]) -> Network:
    if topology == "recurrent":
        return RecurrentNetwork(weights)
    return LayeredNetwork(weights, n_hidden=HIDDEN[topology])


def make_network(topology: Topology, weights: Sequence[float]) -> Network:
    """The network of ``topology`` with ``weights`` (5 inputs, :data:`HIDDEN` hidden units,
    5 outputs).

    Instances are immutable after construction and cached by weight vector.
    """
    if topology not in TOPOLOGIES:
        raise ValueError(f"unknown network topology {topology!r}; use one of {TOPOLOGIES}")
    key = weights if type(weights) is tuple else tuple(float(x) for x in weights)
    return _cached(topology, key)
