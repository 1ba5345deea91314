"""Hostile FSA files: each is read or refused with a located error, quickly.

One test per cause: deep nesting, tagged and out-of-range scalars, values the old second
parse choked on, unbounded error lists, unbounded step limits and file sizes.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from skillcompose import FSA, FSAFileError, FSAValidationError, State, loads_fsa
from skillcompose.fsa import MAX_STEP_LIMIT
from skillcompose.fsafile import MAX_DEPTH, MAX_FILE_BYTES, MAX_STATES, MAX_VALUES, load_fsa

VALID = textwrap.dedent(
    """\
    format: 1
    start: A
    states:
      A:
        skill: X
        params: {p: 1}
        transitions: {ok: success}
    """
)


pytestmark = pytest.mark.timeout(60)
"""A hang guard, not a measure: the causes these tests keep out took minutes (10 s of
scanning, a minute of parsing twice); a file at the limits loads in about 0.3 s on a quiet
2-core machine. Speed itself is measured by benchmarks/bench_runtime.py, not by tests."""


def _refused(text: str) -> FSAFileError:
    """The error a text is refused with; every problem located."""
    with pytest.raises(FSAFileError) as info:
        loads_fsa(text, "bad.yaml")
    err = info.value
    assert err.problems
    for p in err.problems:
        assert p.line is not None and p.column is not None, p
    return err


def _only(text: str) -> str:
    return str(_refused(text))


# -- 1. nesting --------------------------------------------------------------------------
@pytest.mark.parametrize("levels", [MAX_DEPTH + 1, 500, 2000, 20_000])
def test_deep_flow_nesting_is_a_located_error_fast(levels: int) -> None:
    text = VALID + "meta: {a: " + "[" * levels + "]" * levels + "}\n"
    message = _only(text)
    assert "bad.yaml:8:" in message and "nested" in message


@pytest.mark.parametrize("levels", [MAX_DEPTH + 1, 250, 2000])
def test_deep_block_nesting_is_a_located_error_fast(levels: int) -> None:
    meta = "".join("\n" + "  " * (i + 1) + f"k{i}:" for i in range(levels))
    message = _only(VALID + "meta:" + meta + " 1\n")
    assert "nested" in message and "bad.yaml:" in message


def test_nesting_within_the_limit_is_read() -> None:
    depth = MAX_DEPTH - 3  # the top level and meta count too
    fsa = loads_fsa(VALID + "meta: {a: " + "[" * depth + "1" + "]" * depth + "}\n")
    value = fsa.meta["a"]
    for _ in range(depth - 1):
        value = value[0]
    assert value == [1]


def test_brackets_inside_text_do_not_count_as_nesting() -> None:
    fsa = loads_fsa(VALID + "meta: {note: '" + "[" * 60 + "'}\n")
    assert fsa.meta["note"] == "[" * 60


# -- 2. scalars --------------------------------------------------------------------------
@pytest.mark.parametrize(
    "value, expected",
    [
        ("!!int x", "not a whole number"),
        ("!!int 0x", "not a whole number"),
        ("!!int 0b", "not a whole number"),
        ("!!int 0X1F", "not a whole number"),
        ("!!float x", "not a number"),
        ("!!float ._", "not a number"),
        ("!!bool maybe", "not true or false"),
        ("!!null x", "not empty"),
        ("-_", "quote it"),
        ("1" + "0" * 4300, "out of range"),
        ("1" + "0" * 400, "out of range"),
        ("-0x" + "f" * 17, "out of range"),
        ("1e400", "too large"),
        ("-1.5e999", "too large"),
        ("!!binary aGVsbG8=", "YAML tag"),
        ("!!timestamp 2001-01-01", "YAML tag"),
        ("!custom 3", "YAML tag"),
        ("!!seq {a: 1}", "YAML tag"),
        ("!!map a", "YAML tag"),
        ("2001-13-45", "not a valid date"),
    ],
)
def test_bad_scalars_are_located_errors(value: str, expected: str) -> None:
    texts = {
        "1:9": VALID.replace("format: 1", f"format: {value}"),
        "6:17": VALID.replace("{p: 1}", f"{{p: {value}}}"),
        "8:12": VALID + f"meta: {{a: [{value}]}}\n",
    }
    for where, text in texts.items():
        message = _only(text)
        assert expected in message, message
        assert f"bad.yaml:{where}:" in message, message


def test_yaml_1_1_documents_are_refused_with_a_fix() -> None:
    message = _only("%YAML 1.1\n---\n" + VALID.replace("format: 1", "format: 1:30"))
    assert "bad.yaml:1:1:" in message and "%YAML 1.1" in message and "1.2" in message


def test_yaml_1_2_directive_is_fine() -> None:
    assert loads_fsa("%YAML 1.2\n---\n" + VALID).states["A"].params == {"p": 1}


def test_core_tags_convert_with_checks() -> None:
    text = VALID.replace("{p: 1}", "{a: !!int '0x1f', b: !!float 2, c: !!bool true, "
                                   "d: !!str 12, e: !!int -1_000, f: 0o17}")
    params = loads_fsa(text).states["A"].params
    assert params == {"a": 31, "b": 2.0, "c": True, "d": "12", "e": -1000, "f": 15}
    assert type(params["b"]) is float and type(params["c"]) is bool


def test_numbers_at_the_limits_are_read() -> None:
    text = VALID.replace("{p: 1}", "{a: 9223372036854775807, b: -9223372036854775808, "
                                   "c: 1.7e308, d: .inf, e: -.inf, f: 1e-400}")
    params = loads_fsa(text).states["A"].params
    assert params["a"] == 2**63 - 1 and params["b"] == -(2**63)
    assert params["c"] == 1.7e308 and params["d"] == float("inf") and params["f"] == 0.0


# -- 3. one parse, inside the error handling ---------------------------------------------
@pytest.mark.parametrize(
    "meta, expected",
    [
        ("meta: {a: !!bool maybe}\n", "bad.yaml:8:11: meta.a: 'maybe' is not true or false"),
        ("meta: {a: 1, a: 2}\n", "bad.yaml:8:14: meta: key 'a' appears twice"),
        ("meta: {a: {b: 1, b: 1}}\n", "key 'b' appears twice"),
        ("meta: {1: x, 1.0: y}\n", "appears twice"),
        ("meta: {[a]: 1}\n", "keys must be"),
        ("meta: {a: 2001-02-30}\n", "not a valid date"),
    ],
)
def test_meta_values_are_checked_like_the_rest(meta: str, expected: str) -> None:
    message = _only(VALID + meta)
    assert expected in message, message


def test_meta_dates_and_plain_values_survive() -> None:
    fsa = loads_fsa(VALID + "meta: {when: 2024-05-01, ok: true, n: ~, eq: '='}\n")
    assert fsa.meta == {"when": "2024-05-01", "ok": True, "n": None, "eq": "="}


def _many_states(n: int) -> str:
    lines = ["format: 1", "start: S0", "states:"]
    for i in range(n):
        lines.append(f"  S{i}:\n    skill: MoveToObject\n    params:\n      approach: 0.1"
                     f"\n    transitions:\n      success: S{(i + 1) % n}\n      failure: failure")
    return "\n".join(lines) + "\n"


def test_a_file_at_the_state_limit_loads_fast(tmp_path: Path) -> None:
    text = _many_states(MAX_STATES)
    assert len(text.encode()) < MAX_FILE_BYTES
    path = tmp_path / "big.yaml"
    path.write_text(text)
    fsa = load_fsa(path)
    assert len(fsa.states) == MAX_STATES


@pytest.mark.parametrize("megabytes", [0.6, 1.4, 5.0])
def test_a_file_of_megabytes_is_answered_at_once(tmp_path: Path, megabytes: float) -> None:
    text = _many_states(int(megabytes * 1e6 / 125))
    path = tmp_path / "huge.yaml"
    path.write_text(text)
    with pytest.raises(FSAFileError) as info:
        load_fsa(path)
    assert "at most" in str(info.value) and f"{path}:" in str(info.value)
    _refused(text)


@pytest.mark.parametrize("item, values", [("1", 1), ("[1]", 2), ("{a: 1}", 3),
                                          ("[[[[[[[[1]]]]]]]]", 9)])
def test_too_many_values_is_one_located_error_fast(item: str, values: int) -> None:
    n = MAX_VALUES // values + 1
    text = VALID + "meta: {a: [" + ", ".join([item] * n) + "]}\n"
    if len(text) < MAX_FILE_BYTES:
        message = _only(text)
        assert f"more than {MAX_VALUES} values" in message and "bad.yaml:8:" in message
    few = VALID + "meta: {a: [" + ", ".join([item] * (n // 2)) + "]}\n"
    loads_fsa(few)


def test_too_many_states_is_one_located_error() -> None:
    text = "format: 1\nstart: S0\nstates:\n" + "".join(
        f"  S{i}: {{skill: X, transitions: {{ok: success}}}}\n" for i in range(MAX_STATES + 1)
    )
    assert len(text) < MAX_FILE_BYTES
    err = _refused(text)
    assert len(err.problems) == 1
    assert f"at most {MAX_STATES}" in str(err) and "bad.yaml:3:1:" in str(err)


# -- 4. bounded error lists --------------------------------------------------------------
def test_many_errors_print_the_first_ones_and_a_count() -> None:
    text = "format: 1\nstart: S0\nstates:\n" + "".join(
        f"  S{i}: {{skil: X, transitions: {{ok: 3}}}}\n" for i in range(MAX_STATES)
    )
    err = _refused(text)
    lines = str(err).splitlines()
    assert len(lines) <= 25
    n = 3 * MAX_STATES  # unknown key, no skill, a target that is no name
    assert f"({n} problems; the first 20)" in lines[0]
    assert f"and {n - 20} more" in lines[-1]
    assert len(err.problems) == n  # all kept for programs


def test_validation_errors_are_bounded_too() -> None:
    states = {f"S{i}": State("X", {}, {"ok": "Nowhere"}) for i in range(500)}
    with pytest.raises(FSAValidationError) as info:
        FSA(states, "S0")
    assert len(str(info.value).splitlines()) <= 25


# -- 5. step_limit -----------------------------------------------------------------------
@pytest.mark.parametrize("limit", [str(MAX_STEP_LIMIT + 1), "1000000000000", "10**12"])
def test_step_limit_has_an_upper_bound(limit: str) -> None:
    message = _only(VALID + f"step_limit: {limit}\n")
    assert "step_limit" in message and str(MAX_STEP_LIMIT) in message


def test_step_limit_at_the_bound_is_read() -> None:
    assert loads_fsa(VALID + f"step_limit: {MAX_STEP_LIMIT}\n").step_limit == MAX_STEP_LIMIT


def test_fsa_model_bounds_step_limit() -> None:
    with pytest.raises(FSAValidationError, match="step_limit"):
        FSA({"A": State("X", {}, {"ok": "success"})}, "A", step_limit=10**12)


# -- raw bytes ---------------------------------------------------------------------------
def test_bad_bytes_are_located(tmp_path: Path) -> None:
    path = tmp_path / "bytes.yaml"
    path.write_bytes(VALID.encode() + b"meta: {a: \xff\xfe}\n")
    with pytest.raises(FSAFileError, match=rf"{path}:8:11: .*UTF-8"):
        load_fsa(path)


def test_control_characters_are_located() -> None:
    message = _only(VALID + "meta: {a: b\x07c}\n")
    assert "bad.yaml:8:12:" in message


def test_refused_anchors_raise_no_warnings() -> None:
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a warning would be printed around the CLI's one line
        message = _only(VALID + "meta: [&a 1, &a 2, &a 3]\n")
    assert message.count("YAML anchor &a is not allowed") == 3


def test_vector_parameters_of_many_states_fit_the_bounds() -> None:
    """70 states, each with a network of 112 weights (a recurrent MoveBase), are read."""
    import random

    from skillcompose import dumps_fsa

    rnd = random.Random(0)
    states = {
        f"MoveBase_{i}": State("MoveBase", {"weights": tuple(rnd.uniform(-5, 5)
                                                             for _ in range(112))},
                               {"success": f"MoveBase_{(i + 1) % 70}", "failure": "failure"})
        for i in range(70)
    }
    text = dumps_fsa(FSA(states, "MoveBase_0"))
    assert len(text.encode()) > 180_000
    assert len(loads_fsa(text).states) == 70


# -- control characters in the names a file defines ---------------------------------------------
@pytest.mark.parametrize(("escape", "char"), [
    ("\\e", "\x1b"), ("\\0", "\x00"), ("\\x7f", "\x7f"), ("\\x9b", "\x9b"),
    ("\\u202e", "\u202e"), ("\\u200b", "\u200b"), ("\\ufeff", "\ufeff"), ("\\a", "\x07"),
])
def test_a_state_name_with_a_control_character_is_one_located_line(
    escape: str, char: str,
) -> None:
    text = f'format: 1\nstart: "A{escape}B"\nstates:\n  "A{escape}B": {{skill: X, ' \
        'transitions: {ok: success}}\n'
    shown = repr(f"A{char}B")
    message = _only(text)
    assert message == (
        f"bad.yaml:4:3: state {shown[1:-1]}: state name {shown} holds a control character "
        f"(U+{ord(char):04X}), which would act on a terminal or a drawing instead of showing; "
        "rename the state without it"
    )
    assert message.isprintable()


@pytest.mark.parametrize(("text", "expected"), [
    ('format: 1\nstart: A\nstates: {A: {skill: "X\\x9b", transitions: {ok: success}}}\n',
     "bad.yaml:3:21: state A: skill name 'X\\x9b' holds a control character (U+009B), which "
     "would act on a terminal or a drawing instead of showing; write the skill name without "
     "it"),
    ('format: 1\nstart: A\nstates: {A: {skill: X, params: {"p\\u202e": 1}, transitions: '
     '{ok: success}}}\n',
     "bad.yaml:3:44: state A: parameter name 'p\\u202e' holds a control character (U+202E), "
     "which would act on a terminal or a drawing instead of showing; write the parameter "
     "name without it"),
    ('format: 1\nstart: A\nstates: {A: {skill: X, transitions: {"ok\\t": success}}}\n',
     "bad.yaml:3:46: state A: outcome 'ok\\t' holds a control character (U+0009), which "
     "would act on a terminal or a drawing instead of showing; write the outcome without it"),
])
def test_other_names_with_control_characters_are_refused(text: str, expected: str) -> None:
    assert _only(text) == expected


def test_a_state_name_with_a_control_character_is_refused_in_python_too() -> None:
    with pytest.raises(FSAValidationError) as refused:
        FSA({"A\x1b[2J": State("X", {}, {"ok": "success"})}, "A\x1b[2J")
    assert str(refused.value) == (
        "state A\\x1b[2J: state name 'A\\x1b[2J' holds a control character (U+001B), which "
        "would act on a terminal or a drawing instead of showing; rename the state without it"
    )


def test_printable_names_are_still_fine() -> None:
    fsa = loads_fsa('format: 1\nname: "Pour é 🤖"\nstart: "Grasp-é"\nstates:\n  "Grasp-é":'
                    ' {skill: X, params: {"p ü": 1}, transitions: {ok: success}}\n')
    assert fsa.start == "Grasp-é" and fsa.name == "Pour é 🤖"
