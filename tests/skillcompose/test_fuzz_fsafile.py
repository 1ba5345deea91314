"""Fuzzing the FSA file reader: whatever the text, it is read, or refused with a located
error of the project's own, in bounded time.

Inputs start from the example FSA files and are mutated at the level of YAML structure
(lines, nesting, keys), scalars (numbers of any size, dates, special words), tags and
anchors, and raw bytes. Each test runs a small number of examples by default; set
``SKILLCOMPOSE_FUZZ_EXAMPLES`` (e.g. 20000) for a longer campaign, and pytest's
``--hypothesis-seed`` for another seed.
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from skillcompose import FSAFileError, dumps_fsa, load_fsa, loads_fsa
from skillcompose.errors import SkillcomposeError

ROOT = Path(__file__).resolve().parents[2]
SEED_FILES = sorted(
    [*ROOT.glob("examples/*.yaml"), *ROOT.glob("docs/results/*.yaml"),
     *ROOT.glob("tests/evolve/data/*.yaml")]
)
SEEDS = [p.read_text(encoding="utf-8") for p in SEED_FILES]
SEEDS.append(
    "format: 1\nstart: A\nstep_limit: 5\nterminals: [success, failure]\n"
    "states:\n  A: {skill: X, params: {p: 1.5, q: true, r: left}, transitions: {ok: B}}\n"
    "  B:\n    skill: Y\n    time_limit: 2.0\n    transitions:\n      ok: success\n"
    "      bad: A\nmeta: {fitness: 0.5, lineage: [1, 2], note: text}\n"
)

EXAMPLES = int(os.environ.get("SKILLCOMPOSE_FUZZ_EXAMPLES", "60"))
# a hang guard per test, not a measure: a file at the size limit takes about 0.3 s on a quiet
# machine (benchmarks/bench_runtime.py measures speed)
pytestmark = pytest.mark.timeout(300)
FUZZ = settings(max_examples=EXAMPLES, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

TAGS = ["!!str", "!!int", "!!float", "!!bool", "!!null", "!!seq", "!!map", "!!binary",
        "!!timestamp", "!!set", "!!omap", "!!python/object:os.system",
        "!!python/name:builtins.eval", "!", "!custom", "!<tag:yaml.org,2002:int>",
        "!!merge", "!!value"]
WORDS = [".inf", "-.inf", ".nan", ".NaN", "1:30", "190:20:30", "0x", "0b", "0o", "0X1F",
         "0x_", "-_", "+", "-", "_", "~", "null", "yes", "no", "on", "off", "y", "n",
         "True", "FALSE", "2001-13-45", "2001-02-28", "2001-12-14t21:59:43.10-05:00",
         "1e400", "-1e400", "1e-400", "1_000", "0o17", "017", "0b101", "=", "<<", "!", "&",
         "*", "''", '""', '"\\x00\\u0007"', "'it''s'", "|\n  block\n", ">-\n  folded\n",
         "? complex", "- item", "[]", "{}", "[1, [2, [3]]]", "{a: 1, a: 2}", "# comment",
         "a: b: c", "\t", "\x00", "\x07", "\ufeff", "\u2028", "é", "\U0001f916",
         "9" * 5000, "1" + "0" * 400, "0." + "0" * 400 + "1", "-" + "9" * 19, "9" * 19]
SNIPPETS = [
    *TAGS, "&a ", "*a", "&a [1] ", "<<: *a\n", "%YAML 1.1\n---\n", "%YAML 1.2\n---\n",
    "%YAML 2.0\n---\n", "%TAG !e! tag:example.com,2000:\n---\n", "---\n", "...\n",
    "\n- ", ": ", "? ", "#", "'", '"', "[", "]", "{", "}", ",", "\n  ", "\n\t", "|",
    "meta: {a: 1}\n", "states: {}\n", "step_limit: 1000000000000\n", "format: 1\n",
]

scalars = st.one_of(
    st.sampled_from(WORDS),
    st.integers(-(10**30), 10**30).map(str),
    st.floats().map(repr),
    st.from_regex(r"[-+]?(0[xob])?[0-9a-fA-F_.eE:]{0,12}", fullmatch=True),
    st.text(max_size=12),
)
tagged = st.tuples(st.sampled_from(["", "", "", *(t + " " for t in TAGS)]), scalars).map(
    "".join
)


def _flow(tree: object) -> str:
    if isinstance(tree, list):
        return "[" + ", ".join(_flow(x) for x in tree) + "]"
    if isinstance(tree, dict):
        return "{" + ", ".join(f"{k}: {_flow(v)}" for k, v in tree.items()) + "}"
    return str(tree)


trees = st.recursive(
    tagged,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4),
        st.dictionaries(st.one_of(tagged, st.sampled_from(["a", "b", "skill", "params"])),
                        inner, max_size=4),
    ),
    max_leaves=25,
)


def _value_spans(text: str) -> list[tuple[int, int]]:
    """Where the values after `key: ` are on each line."""
    return [m.span(1) for m in re.finditer(r":[ \t]+([^\n#]*)", text)]


@st.composite
def mutated_files(draw: st.DrawFn) -> str:
    text = draw(st.sampled_from(SEEDS))
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(
            ["value", "value", "snippet", "lines", "nest", "tree", "chars", "indent"]
        ))
        if op == "value":
            spans = _value_spans(text)
            if spans:
                a, b = draw(st.sampled_from(spans))
                text = text[:a] + draw(st.one_of(tagged, trees.map(_flow))) + text[b:]
        elif op == "snippet":
            i = draw(st.integers(0, len(text)))
            text = text[:i] + draw(st.sampled_from(SNIPPETS)) + text[i:]
        elif op == "lines":
            lines = text.splitlines(keepends=True)
            if lines:
                i = draw(st.integers(0, len(lines) - 1))
                j = draw(st.integers(i, min(len(lines), i + 6)))
                how = draw(st.sampled_from(["delete", "duplicate", "move"]))
                chunk = lines[i:j]
                del lines[i:j]
                if how != "delete":
                    k = draw(st.integers(0, len(lines)))
                    lines[k:k] = chunk * (2 if how == "duplicate" else 1)
                text = "".join(lines)
        elif op == "nest":
            spans = _value_spans(text)
            if spans:
                a, b = draw(st.sampled_from(spans))
                n = draw(st.one_of(st.integers(0, 40), st.integers(0, 3000)))
                kind = draw(st.sampled_from(["[", "{a: ", "block", "- "]))
                if kind == "block":
                    body = "".join("\n" + "  " * (k + 1) + "k:" for k in range(n)) + " 1"
                elif kind == "- ":
                    body = "- " * n + "1"
                else:
                    close = "]" if kind == "[" else "}"
                    body = kind * n + text[a:b] + close * draw(st.sampled_from([n, 0, n // 2]))
                text = text[:a] + body + text[b:]
        elif op == "tree":
            text = text + "meta: " + _flow(draw(trees)) + "\n"
        elif op == "chars":
            i = draw(st.integers(0, len(text)))
            text = text[:i] + draw(st.text(max_size=6)) + text[i:]
        elif op == "indent":
            lines = text.splitlines(keepends=True)
            if lines:
                i = draw(st.integers(0, len(lines) - 1))
                lines[i] = draw(st.sampled_from(["", " ", "   ", "\t"])) + lines[i].lstrip()
                text = "".join(lines)
    return text


def _check(read: object, *args: object) -> None:
    """``read(*args)`` returns an FSA or raises FSAFileError with every problem located;
    An FSA it returns is written and read back."""
    try:
        fsa = read(*args)  # type: ignore[operator]
    except FSAFileError as exc:
        assert isinstance(exc, SkillcomposeError)
        assert exc.problems
        for p in exc.problems:
            assert p.line is not None and p.column is not None, str(exc)
            assert p.line >= 1 and p.column >= 1
        assert len(str(exc).splitlines()) <= 22
    else:
        loads_fsa(dumps_fsa(fsa))


def test_seed_files_are_valid() -> None:
    assert len(SEED_FILES) >= 3
    for text in SEEDS:
        loads_fsa(text)


@FUZZ
@given(mutated_files())
def test_fuzz_mutated_example_files(text: str) -> None:
    _check(loads_fsa, text, "fuzz.yaml")


@FUZZ
@given(st.sampled_from(SEEDS), trees, st.sampled_from(["meta", "format", "states", "start",
                                                       "step_limit", "terminals", "name"]))
def test_fuzz_generated_values_under_each_key(seed: str, tree: object, key: str) -> None:
    text = re.sub(rf"(?m)^{key}:.*$", "", seed) + f"{key}: {_flow(tree)}\n"
    _check(loads_fsa, text, "fuzz.yaml")


@FUZZ
@given(st.sampled_from(SEEDS), st.lists(st.tuples(st.floats(0, 1), st.binary(max_size=6)),
                                        min_size=1, max_size=5))
def test_fuzz_raw_bytes(seed: str, edits: list[tuple[float, bytes]]) -> None:
    data = bytearray(seed.encode())
    for where, chunk in edits:
        i = int(where * len(data))
        data[i:i + len(chunk) // 2] = chunk
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "fuzz.yaml"
        path.write_bytes(bytes(data))
        _check(load_fsa, path)


@pytest.mark.parametrize("n", [10, 33, 300, 3000, 30000])
@pytest.mark.parametrize("open_, close", [("[", "]"), ("{a: ", "}"), ("[", ""), ("{", "")])
def test_deep_brackets_anywhere(n: int, open_: str, close: str) -> None:
    for seed in SEEDS[:2]:
        spans = _value_spans(seed)
        for a, b in (spans[0], spans[len(spans) // 2], spans[-1]):
            _check(loads_fsa, seed[:a] + open_ * n + "1" + close * n + seed[b:], "deep.yaml")


# -- what evolution writes, the reader reads back --------------------------------------------
_BOUNDS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),  # subnormals, huge magnitudes, inf, nan
    st.floats(-1e3, 1e3),
    st.integers(-2**52, 2**52),
    st.integers(-2**70, 2**70),
    st.sampled_from([0, 1, -1, 2**49, -2**49, 2**49 + 1, 2**63 - 1, 5e-324, -5e-324,
                     2.2250738585072014e-308, 1.7976931348623157e308, -1.7976931348623157e308]),
)
_GENES = st.floats(0.0, 1.0) | st.sampled_from([0.0, 1.0, 0.5, 5e-324, 1 - 2**-53])


@FUZZ
@given(_BOUNDS, _BOUNDS, st.sampled_from(["int", "float", "vector", "log"]),
       st.lists(_GENES, min_size=3, max_size=3))
def test_fuzz_what_evolution_writes_the_reader_reads(
    a: float, b: float, kind: str, genes: list[float],
) -> None:
    """A declaration is refused in one line naming the skill and the parameter, or every value
    evolution can give it is written, read back as itself and passes the skill's check."""
    from skillcompose import FSA, ParamError, Registry, Skill, SkillSpec, State
    from skillcompose.params import Param, make_param_spec

    low, high = (a, b) if not (b < a) else (b, a)
    size = 3 if kind == "vector" else None
    base = {"int": int, "float": float, "vector": tuple, "log": float}[kind]
    decl = Param(low, high, scale="log" if kind == "log" else "linear", size=size)
    default = (low,) * 3 if size else low
    if kind != "int" and isinstance(low, int):
        default = (float(low),) * 3 if size else float(low)  # may overflow: refused below
    try:
        spec = make_param_spec("x", base, decl, default, "Knob")
    except ParamError as exc:
        assert str(exc).startswith("skill Knob") and "'x'" in str(exc) and "\n" not in str(exc)
        return
    value = spec.from_genes(genes[:spec.genes])
    registry = Registry([Skill(SkillSpec("Knob", ("success",), (spec,)),
                               lambda bb, rng, x: "success")])
    fsa = FSA({"Knob_1": State("Knob", {"x": value}, {"success": "success"})}, "Knob_1")
    back = loads_fsa(dumps_fsa(fsa, registry), "best.yaml").validate(registry)
    assert back.states["Knob_1"].params["x"] == value
    if kind == "int":  # whole numbers go through the genes exactly
        assert spec.from_genes(spec.to_genes(value)) == value
