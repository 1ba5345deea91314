"""Vector parameters (a network's weights): declaration, registry, files and validation."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import pytest

from skillcompose import (
    FSA,
    Blackboard,
    FSAValidationError,
    Param,
    ParamError,
    Registry,
    State,
    compile_fsa,
    dumps_fsa,
    load_fsa,
    loads_fsa,
    save_fsa,
    skill,
)
from skillcompose.errors import RegistryError

Weights = Annotated[tuple[float, ...], Param(-3.0, 3.0, size=4, doc="a tiny network")]


@skill(writes=("out",))
def weigh(
    bb: Blackboard, rng: np.random.Generator, *, w: Weights = (0.0, 0.0, 0.0, 0.0),
    gain: Annotated[float, Param(0.0, 2.0)] = 1.0,
) -> Literal["success", "failure"]:
    bb["out"] = gain * sum(w)
    return "success" if sum(w) >= 0 else "failure"


def _registry() -> Registry:
    return Registry([weigh])


TEXT = """\
format: 1
start: W
states:
  W:
    skill: Weigh
    params:
      w: [0.5, -1.0, 2.5, 0.0]   # my tuned weights
      gain: 1.5
    transitions: {success: success, failure: failure}
"""


def test_the_decorator_reads_a_vector_parameter() -> None:
    spec = weigh.spec.param("w")
    assert spec.size == 4 and spec.genes == 4 and (spec.low, spec.high) == (-3.0, 3.0)
    assert spec.describe_range() == "4 floats, each in [-3, 3]"
    assert spec.check([1, 2, 3, -3]) == (1.0, 2.0, 3.0, -3.0)
    assert spec.from_genes([0.0, 0.5, 1.0, 0.25]) == (-3.0, 0.0, 3.0, -1.5)
    assert spec.to_genes((-3.0, 0.0, 3.0, -1.5)) == [0.0, 0.5, 1.0, 0.25]
    assert weigh.spec.param("gain").genes == 1


@pytest.mark.parametrize(
    ("value", "words"),
    [
        ([1.0, 2.0], "got a list of 2; give exactly 4 numbers"),
        ([1.0, 2.0, 3.0, 9.0], "item 3 = 9.0 is outside; set it between -3 and 3"),
        ([1.0, "x", 0.0, 0.0], "item 1 = 'x' is not a finite number"),
        ([1.0, float("nan"), 0.0, 0.0], "item 1 = nan is not a finite number"),
        ([True, 0.0, 0.0, 0.0], "item 0 = True is not a finite number"),
        (1.0, "write a list such as"),
        ("1,2,3,4", "write a list such as"),
    ],
)
def test_bad_vectors_are_refused_with_the_reason(value: object, words: str) -> None:
    with pytest.raises(ParamError, match="expected 4 floats, each in") as err:
        weigh.spec.param("w").check(value)
    assert words in str(err.value)


def test_a_vector_needs_a_tuple_annotation_and_a_size() -> None:
    with pytest.raises(ParamError, match="size must be a whole number"):
        @skill
        def bad(bb: Blackboard, rng: np.random.Generator, *,
                w: Annotated[tuple[float, ...], Param(0, 1, size=0)] = ()) -> Literal["ok"]:
            return "ok"
    with pytest.raises(ParamError, match=r"tuple\[float, \.\.\.\]"):
        @skill
        def bad2(bb: Blackboard, rng: np.random.Generator, *,
                 w: Annotated[float, Param(0, 1, size=3)] = 0.0) -> Literal["ok"]:
            return "ok"


def test_a_twin_with_another_length_is_refused() -> None:
    @skill(name="Weigh", backend="kinematic")
    def other(
        bb: Blackboard, rng: np.random.Generator, *,
        w: Annotated[tuple[float, ...], Param(-3.0, 3.0, size=5)] = (0.0,) * 5,
        gain: Annotated[float, Param(0.0, 2.0)] = 1.0,
    ) -> Literal["success", "failure"]:
        return "success"

    registry = _registry()
    with pytest.raises(RegistryError, match=r"w: 5 floats.*every backend of a skill needs"):
        registry.add(other)


def test_a_file_with_a_vector_runs_and_round_trips_with_its_comments(tmp_path: Path) -> None:
    fsa = loads_fsa(TEXT, "w.yaml")
    assert fsa.states["W"].params["w"] == (0.5, -1.0, 2.5, 0.0)
    registry = _registry()
    bb = Blackboard()
    result = compile_fsa(fsa, registry).run(bb, 0)
    assert result.outcome == "success" and bb["out"] == pytest.approx(3.0)
    path = tmp_path / "w.yaml"
    path.write_text(TEXT)
    edited = load_fsa(path).with_params("W", gain=0.5)
    save_fsa(edited, path, registry=registry)
    text = path.read_text()
    assert "# my tuned weights" in text  # the person's comment stays
    assert "w: [0.5, -1.0, 2.5, 0.0]" in text
    assert load_fsa(path).states["W"].params == {"w": (0.5, -1.0, 2.5, 0.0), "gain": 0.5}
    edited = load_fsa(path).with_params("W", w=(1.0, 1.0, 1.0, -1.0))
    save_fsa(edited, path, registry=registry)
    assert load_fsa(path).states["W"].params["w"] == (1.0, 1.0, 1.0, -1.0)


def test_a_new_file_writes_one_list_with_its_range_in_a_comment() -> None:
    fsa = FSA({"W": State("Weigh", {"w": (0.25, -0.5, 1.0, 2.0)},
                          {"success": "success", "failure": "failure"})}, "W")
    text = dumps_fsa(fsa, registry=_registry())
    line = next(ln for ln in text.splitlines() if ln.strip().startswith("w:"))
    assert line.strip().startswith("w: [0.25, -0.5, 1.0, 2.0]")
    assert "# 4 floats, each in [-3, 3]" in line
    assert loads_fsa(text).states["W"].params["w"] == (0.25, -0.5, 1.0, 2.0)


@pytest.mark.parametrize(
    ("value", "column", "words"),
    [
        ("[0.5, -1.0]", 10, "got a list of 2"),
        ("[0.5, -1.0, 2.5, 7.0]", 10, "item 3 = 7.0 is outside"),
        ("[0.5, [1], 2.5, 7.0]", 10, "must be a single value"),
    ],
)
def test_validation_errors_carry_file_line_and_fix(value: str, column: int, words: str) -> None:
    text = TEXT.replace("[0.5, -1.0, 2.5, 0.0]", value)
    with pytest.raises(FSAValidationError) as err:
        compile_fsa(loads_fsa(text, "w.yaml"), _registry())
    msg = str(err.value)
    assert f"w.yaml:7:{column}" in msg and "state W" in msg and words in msg
