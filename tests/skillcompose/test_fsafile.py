from __future__ import annotations

import json
import math
import re
import textwrap
import time
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skillcompose import (
    FSA,
    Blackboard,
    FSAFileError,
    FSAValidationError,
    Param,
    Registry,
    State,
    compile_fsa,
    dumps_fsa,
    load_fsa,
    loads_fsa,
    save_fsa,
    skill,
)
from skillcompose.fsafile import STATE_KEYS, TOP_LEVEL_KEYS

REFERENCE = Path(__file__).resolve().parents[2] / "examples" / "pour_water_reference.fsa.yaml"

HAND_WRITTEN = textwrap.dedent(
    """\
    # Pour water, by hand.
    format: 1
    name: pour   # the skill name when nested
    start: Recognise_1
    step_limit: 20
    states:
      # look first
      Recognise_1:
        skill: Recognise
        transitions: {success: Move_2}
      Move_2:
        skill: MoveToObject
        params:
          approach: 0.2   # m, closer is riskier
          p_fail: 0.1
        transitions:
          success: Grasp_3
          failure: Move_2   # retry
      Grasp_3:
        skill: GraspObject
        params: {force: 3, arm: right}
        transitions:
          success: success
          failure: Move_2
    """
)


def test_hand_edit_survives_load_modify_save(tmp_path: Path, registry: Registry) -> None:
    path = tmp_path / "pour.fsa.yaml"
    path.write_text(HAND_WRITTEN)
    fsa = load_fsa(path)
    edited = (
        fsa.with_params("Move_2", approach=0.15)
        .rename_state("Grasp_3", "Grab")
        .route("Grab", "failure", "Recognise_1")
    )
    save_fsa(edited, path, registry)
    text = path.read_text()
    for comment in ("# Pour water, by hand.", "# the skill name when nested", "# look first",
                    "# m, closer is riskier", "# retry"):
        assert comment in text
    assert re.search(r"approach: 0\.15 +# m, closer is riskier", text)
    assert "transitions: {success: Move_2}" in text  # flow style kept
    assert "Grab:" in text and "Grasp_3" not in text
    assert "success: Grab" in text
    # key order kept: the renamed state stays where it was
    assert text.index("Recognise_1:") < text.index("Move_2:") < text.index("Grab:")
    again = load_fsa(path)
    assert again == edited
    assert compile_fsa(again, registry).run(None, 0).outcome == "success"


def test_saving_an_unchanged_file_keeps_it_byte_for_byte(tmp_path: Path) -> None:
    path = tmp_path / "pour.fsa.yaml"
    path.write_text(HAND_WRITTEN)
    save_fsa(load_fsa(path), path)
    assert path.read_text() == HAND_WRITTEN


@pytest.mark.parametrize(("ends", "kept"), [("\r\n", "\r\n"), ("\r", "\n"), ("\n", "\n")])
def test_an_edited_file_keeps_one_kind_of_line_end(tmp_path: Path, ends: str, kept: str) -> None:
    """Windows line ends stay Windows line ends; lone carriage returns become "\\n"; never
    a mix (the comments used to keep theirs and the rest take "\\n")."""
    spaced = HAND_WRITTEN.replace("step_limit: 20\n", "step_limit: 20\n\n").replace(
        "  Move_2:\n", "\n  Move_2:\n")  # blank lines too
    path = tmp_path / "pour.fsa.yaml"
    path.write_bytes(spaced.replace("\n", ends).encode())
    save_fsa(load_fsa(path).with_params("Move_2", approach=0.15), path)
    data = path.read_bytes()
    lines = spaced.count("\n")
    assert data.count(kept.encode()) == lines and data.count(b"\r") == kept.count("\r") * lines
    plain = tmp_path / "plain.fsa.yaml"  # the same edit of the "\n" file: the same text
    plain.write_text(spaced)
    save_fsa(load_fsa(plain).with_params("Move_2", approach=0.15), plain)
    assert data.decode().replace("\r\n", "\n") == plain.read_text()
    assert b"approach: 0.15" in data and load_fsa(path).states["Move_2"].params["approach"] == 0.15


_names = st.from_regex(r"[A-Z][a-z]{0,6}_[0-9]{1,3}", fullmatch=True)
_values = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False, width=64),
    st.integers(-10**6, 10**6),
    st.booleans(),
    st.sampled_from(["left", "right", "yes", "no", "on", "null", "1.5", "a b"]),
)


@st.composite
def fsas(draw: st.DrawFn) -> FSA:
    names = draw(st.lists(_names, min_size=1, max_size=8, unique=True))
    terminals = ("success", "failure")
    targets = st.sampled_from(names + list(terminals))
    states = {}
    for n in names:
        outcomes = draw(st.lists(st.from_regex(r"[a-z]{1,8}", fullmatch=True),
                                 min_size=1, max_size=3, unique=True))
        params = draw(st.dictionaries(st.from_regex(r"[a-z]{1,6}", fullmatch=True), _values,
                                      max_size=3))
        states[n] = State(draw(_names), params, {o: draw(targets) for o in outcomes})
    meta = draw(st.dictionaries(st.sampled_from(["fitness", "generation", "note"]), _values,
                                max_size=3))
    return FSA(states, draw(st.sampled_from(names)), terminals,
               draw(st.integers(1, 500)), draw(st.sampled_from(["", "task_a"])), meta)


@pytest.mark.slow
@settings(max_examples=150, deadline=None)
@given(fsas())
def test_random_fsas_survive_save_and_load(fsa: FSA) -> None:
    text = dumps_fsa(fsa)
    back = loads_fsa(text)
    assert back == fsa
    for sname, state in fsa.states.items():  # types survive too (1 stays int, 1.0 float)
        for k, v in state.params.items():
            got = back.states[sname].params[k]
            assert type(got) is type(v)
            assert got == v or (isinstance(v, float) and math.isnan(v))
    assert loads_fsa(dumps_fsa(back)) == fsa  # saving a loaded file loses nothing either


def _error(text: str) -> str:
    with pytest.raises(FSAFileError) as info:
        loads_fsa(textwrap.dedent(text), "bad.yaml")
    return str(info.value)


_ONE = "format: 1\nstart: A\nstates:\n  A:\n    skill: X\n    transitions:\n      ok: success\n"


@pytest.mark.parametrize(
    "text, expected",
    [
        ("format: 1\nstart: A\nstates: {A: {skill: X, transitions: {ok: A}}\n",
         "bad.yaml:4:1: not valid YAML"),  # unclosed flow mapping
        ("", "the file is empty"),
        ("- a\n- b\n", "the top level must be a mapping"),
        ("format: 1\nstart: A\nstates:\n  A: !!python/object:os.system {skill: X}\n",
         "bad.yaml:4:6: YAML tag 'tag:yaml.org,2002:python/object:os.system' is not allowed"),
        ("format: 1\nstart: A\nstates:\n  A: &x {skill: X, transitions: {ok: success}}\n"
         "  B: *x\n", "not allowed in FSA files"),
        ("format: 1\nstates: {A: {skill: X, transitions: {ok: success}}}\n",
         "missing top-level key 'start'; add `start: <name of the first state>`"),
        ("format: 2\nstart: A\nstates: {A: {skill: X, transitions: {ok: success}}}\n",
         "bad.yaml:1:9: format 2 is not supported"),
        ("format: 1\nstart: A\nstep_limt: 3\nstates: {A: {skill: X, transitions: {ok: success}}}\n",
         "bad.yaml:3:1: the top level: unknown key 'step_limt'; did you mean 'step_limit'?"),
        ("format: 1\nstart: A\nstep_limit: -3\n"
         "states: {A: {skill: X, transitions: {ok: success}}}\n",
         "bad.yaml:3:13: step_limit must be a positive whole number, got -3"),
        ("format: 1\nstart: A\nstates:\n  A: {skill: X, transitions: {ok: success}}\n"
         "  A: {skill: Y, transitions: {ok: success}}\n",
         "bad.yaml:5:3: states: key 'A' appears twice (first on line 4)"),
        ("format: 1\nstart: A\nstates:\n  A:\n    skill: X\n",
         "bad.yaml:5:5: state A: missing key 'transitions'"),
        ("format: 1.0\nstart: A\nstates: {A: {skill: X, transitions: {ok: success}}}\n",
         "bad.yaml:1:9: format 1.0 is not supported; this version of skillcompose reads "
         "format 1; set `format: 1`"),
        # slips made by hand in the YAML itself, each with its own fix
        (_ONE + "---\nformat: 1\n", "bad.yaml:8:1: not valid YAML: but found another "
         "document; an FSA file holds one document: remove the `---` line (or the second FSA)"),
        (_ONE.replace("      ok: success\n", "      <<: {ok: success}\n"),
         "bad.yaml:7:7: states.A.transitions: merge keys (<<) are not allowed in FSA files; "
         "write the keys out in full"),
        (_ONE.replace("      ok: success\n", "      ok:success\n      no: failure\n"),
         "bad.yaml:8:9: not valid YAML: mapping values are not allowed here; put a space after "
         "each ':' that ends a key (`success: Grasp`)"),
        (_ONE.replace("  A:\n", "  A:\t# the state\n"), "bad.yaml:4:5: not valid YAML: found "
         "character '\\t' that cannot start any token; replace the tab with spaces"),
        (_ONE.replace("skill: X", "skill:\u00a0X"), "bad.yaml:6:16: not valid YAML: mapping "
         "values are not allowed here; a non-breaking space (U+00A0) is near here: replace it "
         "with a plain space"),
        # ... and no such fix where the slip is another one
        (_ONE.replace("start: A", "note: 12:30 start: now\nstart: A"), "bad.yaml:2:18: not "
         "valid YAML: mapping values are not allowed here; check indentation, colons and "
         "quotes near this line"),
        (_ONE.replace("start: A", "name: s  # the\u00a0name\nx: Find y: z\nstart: A"),
         "bad.yaml:3:10: not valid YAML: mapping values are not allowed here; check "
         "indentation, colons and quotes near this line"),
        ("format: 1\nstart: A\nterminals: [success, failure, success]\n"
         "states: {A: {skill: X, transitions: {ok: success}}}\n",
         "bad.yaml:3:1: terminal outcome 'success' is listed twice; keep one"),
        ("format: 1\nstart: A\nstates:\n  A:\n    skil: X\n    transitions: {ok: success}\n",
         "bad.yaml:5:5: state A: unknown key 'skil'; did you mean 'skill'?"),
        ("format: 1\nstart: A\nstates:\n  A:\n    skill: [X]\n    transitions: {ok: success}\n",
         "bad.yaml:5:12: state A: skill must be a name (text), got a list"),
        ("format: 1\nstart: A\nstates:\n  A:\n    skill: X\n    params: {v: [[1], 2]}\n"
         "    transitions: {ok: success}\n",
         "bad.yaml:6:17: state A: parameter 'v' must be a single value"),
        ("format: 1\nstart: A\nstates:\n  A:\n    skill: X\n    params: {v: {a: 1}}\n"
         "    transitions: {ok: success}\n",
         "bad.yaml:6:17: state A: parameter 'v' must be a single value"),
        ("format: 1\nstart: A\nstates:\n  A:\n    skill: X\n    transitions: {ok: 3}\n",
         "bad.yaml:6:23: state A: the target of outcome 'ok' must be a name (text), got int 3"),
        ("format: 1\nstart: A\nstates:\n  A:\n    skill: X\n    transitions: {ok: Bee}\n"
         "  B:\n    skill: X\n    transitions: {ok: success}\n",
         "bad.yaml:6:23: state A: outcome 'ok' goes to 'Bee', which is neither a state nor "
         "a terminal outcome"),
        ("format: 1\nstart: Q\nstates:\n  A:\n    skill: X\n    transitions: {ok: success}\n",
         "bad.yaml:2:8: start state 'Q' does not exist"),
        ("format: 1\nstart: A\nterminals: done\nstates:\n  A:\n    skill: X\n"
         "    transitions: {ok: done}\n", "terminals must be a list"),
    ],
)
def test_each_malformed_file_has_its_own_clear_error(text: str, expected: str) -> None:
    message = _error(text)
    assert expected in message
    assert "Traceback" not in message


def test_skill_errors_point_at_file_lines(tmp_path: Path, registry: Registry) -> None:
    path = tmp_path / "pour.fsa.yaml"
    path.write_text(HAND_WRITTEN.replace("approach: 0.2", "approach: 2.0")
                    .replace("failure: Move_2   # retry", "faliure: Move_2"))
    fsa = load_fsa(path)
    with pytest.raises(FSAValidationError) as info:
        compile_fsa(fsa, registry)
    text = str(info.value)
    assert f"{path}:14:17: state Move_2: skill MoveToObject: parameter 'approach'" in text
    assert f"{path}:18:16: state Move_2: 'faliure' is not an outcome" in text
    assert "outcome 'failure' of skill MoveToObject has no transition" in text


def test_missing_file() -> None:
    with pytest.raises(FSAFileError, match=r"no_such\.yaml: file not found"):
        load_fsa("no_such.yaml")


def test_schema_keys_equal_the_parser_keys() -> None:
    import skillcompose

    schema_path = Path(skillcompose.__file__).parent / "schema" / "fsa.schema.json"
    schema = json.loads(schema_path.read_text())
    assert tuple(schema["properties"]) == TOP_LEVEL_KEYS
    assert tuple(schema["$defs"]["state"]["properties"]) == STATE_KEYS


def test_schema_accepts_what_we_write(registry: Registry) -> None:
    jsonschema = pytest.importorskip("jsonschema")
    import skillcompose

    schema = json.loads(
        (Path(skillcompose.__file__).parent / "schema" / "fsa.schema.json").read_text()
    )
    from ruamel.yaml import YAML

    doc = YAML(typ="safe").load(HAND_WRITTEN)
    jsonschema.validate(doc, schema)
    doc["states"]["Move_2"]["colour"] = "red"
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(doc, schema)


@pytest.mark.timeout(60)  # a hang guard: the state hangs for good without its limit
def test_time_limit_in_a_file_stops_a_hanging_state(tmp_path: Path) -> None:
    @skill
    def hang(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
        time.sleep(3.0)  # a driver that never answers in time
        return "success"

    registry = Registry([hang])
    text = textwrap.dedent(
        """\
        format: 1
        start: Hang
        states:
          Hang:
            skill: Hang
            time_limit: 0.2   # s
            transitions: {success: success}
        """
    )
    fsa = loads_fsa(text, "hang.yaml")
    assert fsa.states["Hang"].time_limit == 0.2
    assert loads_fsa(dumps_fsa(fsa.with_params("Hang"))) == fsa  # survives a save
    compiled = compile_fsa(fsa, registry)
    result = compiled.run(None, 0)  # the skill hangs: only the file's limit ends the run
    assert result.outcome == "timeout"
    from skillcompose import run_ticking

    # every tick-wise entry point honours the file's limit too
    assert run_ticking(compiled).outcome == "timeout"
    with pytest.raises(FSAFileError, match=r"hang\.yaml:6:17: state Hang: time_limit must"):
        loads_fsa(text.replace("0.2", "-1"), "hang.yaml")


def test_a_loaded_fsa_holds_plain_data_only() -> None:
    """The model is format-neutral: a loaded FSA (renamed, too) holds no YAML library
    object in its own fields; the reader's nodes and the rename log sit in the file layer's
    handle (``FileOrigin``, the FSA's source), which the writer alone reads."""
    import pickle

    from skillcompose.fsa import Source
    from skillcompose.fsafile import FileOrigin

    path = Path(__file__).resolve().parents[2] / "examples" / "pour_water_reference.fsa.yaml"
    fsa = load_fsa(path).rename_state("Recognise", "Look")

    def modules(value: object) -> set[str]:
        found = {type(value).__module__}
        if isinstance(value, dict):
            for k, v in value.items():
                found |= modules(k) | modules(v)
        elif isinstance(value, (list, tuple)):
            for v in value:
                found |= modules(v)
        elif hasattr(value, "__dataclass_fields__"):
            own = Source if isinstance(value, FileOrigin) else value
            for name in own.__dataclass_fields__:
                found |= modules(getattr(value, name))
        return found

    assert not any(m.startswith("ruamel") for m in modules(fsa))
    assert isinstance(fsa.source, FileOrigin) and fsa.source.renames == {"Recognise": "Look"}
    text = dumps_fsa(fsa)
    assert dumps_fsa(pickle.loads(pickle.dumps(fsa))) == text  # a copy parses the text again
    assert "  Look:                     # store where the jug and the glass are" in text


def test_loads_fsa_takes_text() -> None:
    with pytest.raises(TypeError, match=r"loads_fsa takes the file's text \(str\), got bytes; "
                       r"decode it"):
        loads_fsa(b"format: 1\n")  # type: ignore[arg-type]


@pytest.mark.parametrize("text", ["x" + " " * 120 + "y", "a  b " * 40, " leading",
                                  "trailing ", "tab\tand  two spaces " * 10])
def test_strings_round_trip_exactly_through_save_and_load(text: str, tmp_path: Path) -> None:
    """A long string with a run of spaces used to be folded at them and read back with one
    space; every string comes back as it was, in a new file and in an edited one."""
    fsa = loads_fsa(REFERENCE.read_text(encoding="utf-8"))
    edited = fsa.replace(meta={**fsa.meta, "note": text, "deep": {"list": [text]}})
    back = save_fsa(edited, tmp_path / "a.yaml")
    assert load_fsa(tmp_path / "a.yaml").meta["note"] == text
    assert back.meta["deep"] == {"list": [text]}
    fresh = FSA({"A": State("X", transitions={"success": "success"})}, start="A",
                meta={"note": text})
    assert loads_fsa(dumps_fsa(fresh)).meta == {"note": text}


def test_dumps_and_save_say_what_they_take(tmp_path: Path) -> None:
    with pytest.raises(TypeError, match=r"dumps_fsa takes an FSA, got None"):
        dumps_fsa(None)  # type: ignore[arg-type]
    fsa = loads_fsa(REFERENCE.read_text(encoding="utf-8"))
    with pytest.raises(IsADirectoryError, match=r"is a folder: give save_fsa a file path"):
        save_fsa(fsa, tmp_path)


@pytest.mark.parametrize(("lines", "line", "says", "fix"), [
    (["  A:", "    skill: X", "     transitions: {ok: success}"], 6,
     "`transitions` is indented 5 spaces", "indent it by 4 spaces, like the key above it"),
    (["  A:", "    skill: X", "   transitions: {ok: success}"], 6,
     "`transitions` is indented 3 spaces", "indent it by 4 spaces, like the key above it"),
    (["  A:", "    skill: X", "    transitions:", "      ok: success", "     no: A"], 8,
     "`no` is indented 5 spaces", "indent it by 6 spaces, like the key above it"),
    (["  A:", " skill: X"], 5, "`skill` is indented 1 space",
     "indent it by 4 spaces, inside the key above it"),
])
def test_a_misaligned_key_is_named_at_its_line_with_the_indent_it_needs(
        lines: list[str], line: int, says: str, fix: str) -> None:
    text = "format: 1\nstart: A\nstates:\n" + "\n".join(lines) + "\n"
    with pytest.raises(FSAFileError) as info:
        loads_fsa(text, "bad.yaml")
    (problem,) = info.value.problems
    assert problem.line == line and says in problem.message and problem.fix == fix
    assert "block end" not in str(info.value)  # not the parser's own words


def test_an_unknown_parameter_gets_a_did_you_mean() -> None:
    registry = Registry()

    @skill
    def move(bb: Blackboard, rng: np.random.Generator, *,
             z: Annotated[float, Param(0.0, 1.0, unit="m")] = 0.5) -> Literal["success"]:
        return "success"

    registry.add(move)
    fsa = loads_fsa("format: 1\nstart: A\nstates:\n  A:\n    skill: Move\n    params: "
                    "{zz: 0.5}\n    transitions: {success: success}\n", "p.yaml")
    with pytest.raises(FSAValidationError, match=r"has no parameter 'zz'.*did you mean 'z'\?"):
        fsa.validate(registry)
