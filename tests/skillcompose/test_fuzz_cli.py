"""Fuzzing the command line: whatever the arguments, the command runs, or stops with one
line naming what is wrong, exit status 2 for usage errors and 1 for failures; never a
traceback, never an "unexpected" error, within a time bound.

Each subcommand starts from a small valid command line that is then mutated: values are
replaced by hostile ones (negative, huge, not numbers, nan, paths that are files, directories
or missing, module names that are not), options are dropped, repeated or left without a
value. ``SKILLCOMPOSE_FUZZ_EXAMPLES`` raises the number of examples.
"""

from __future__ import annotations

import contextlib
import io
import os
import tempfile
import time
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from skillcompose.cli import main

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = str(ROOT / "examples" / "pour_water_reference.fsa.yaml")
TOY_FSA = str(ROOT / "tests" / "evolve" / "data" / "toy_solution.yaml")
PLACES = Path(tempfile.mkdtemp(prefix="skillcompose-fuzz-cli-"))
(PLACES / "a_dir").mkdir()
(PLACES / "a_file.txt").write_text("not yaml: [")
(PLACES / "garbage.yaml").write_bytes(b"\xff\xfe\x00format: 1\n" + b"[" * 5000)
(PLACES / "hostile.yaml").write_text(
    "format: !!int 0x\nstart: A\nstep_limit: 1000000000000\nmeta: [&a 1, &a 2, *a, !!bool x]\n"
    "states: {A: {skill: X, transitions: {ok: " + "[" * 300 + "}}}\n"
)

EXAMPLES = max(10, int(os.environ.get("SKILLCOMPOSE_FUZZ_EXAMPLES", "60")) // 3)
SECONDS = 30.0
FUZZ = settings(max_examples=EXAMPLES, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

NUMBERS = ["-1", "0", "1", "2", "3", "-0", "+2", "1.5", "1e3", "nan", "inf", "-inf", "",
           " ", "x", "0x10", "1_000", "10**12", "1000000000000", "9" * 5000,
           str(2**63), str(2**63 - 1), "٣", "--", "-5e-324"]
PATHS = [str(PLACES / "a_dir"), str(PLACES / "a_dir") + "/", str(PLACES / "a_file.txt"),
         str(PLACES / "a_file.txt" / "x.png"), str(PLACES / "missing" / "deeper" / "x.png"),
         str(PLACES / "out.svg"), str(PLACES / "out.csv"), str(PLACES / "x.txt"), "",
         "/proc/skillcompose/x.png", str(PLACES / "garbage.yaml"),
         str(PLACES / "hostile.yaml"), "-"]
MODULES = [".name", "a..b", "os", "os.path", "examples", "examples.toy_task",
           "no_such_module_at_all", "examples.no_such", "skillcompose", "x y", "1abc",
           str(PLACES / "a_file.txt"), str(PLACES / "a_dir"), "tests.skillcompose.demo_skills",
           str(PLACES / "missing.py"), REFERENCE]
WORDS = ["kinmatic", "sim", "default", "serial", "process", "ray", "p_fail", "p fail",
         "p_fail=0.1", "p_fail=nan", "p_fail=1e999", "=", "trials=0", "0:1:3", "0:1:0",
         "0:1:100000000", "0,0.5", "nan", ",", "1:2", "paper", "robust", "é", "\x00"]

VALUES = {
    "number": st.sampled_from(NUMBERS),
    "path": st.sampled_from(PATHS),
    "module": st.sampled_from(MODULES),
    "word": st.sampled_from(WORDS),
}
# option -> kind of value it takes (None: a flag)
OPTIONS: dict[str, dict[str, str | None]] = {
    "run": {"--seed": "number", "--trials": "number", "--task": "module",
            "--skills": "module", "--set": "word", "--backend": "word"},
    "validate": {"--task": "module", "--skills": "module", "--set": "word",
                 "--backend": "word"},
    "show": {"-o": "path", "--mermaid": None, "--no-params": None},
    "skills": {"--task": "module", "--skills": "module", "--backend": "word"},
    "robustness": {"--task": "module", "--p-fail": "word", "--setting": "word",
                   "--reps": "number", "-o": "path", "--csv": "path", "--seed": "number",
                   "--workers": "number", "--set": "word", "--backend": "word",
                   "--step-limit": "number"},
    "evolve": {"--set": "word", "--generations": "number", "--population": "number",
               "--initial-nodes": "number", "--tournament": "number",
               "--param-sigma": "number", "--seed": "number", "--workers": "number",
               "--backend": "word", "--out": "path", "--trials": "number",
               "--elitism": "number", "--confirm": "number", "--cache-refresh": "number",
               "--checkpoint-every": "number", "--simplify-trials": "number",
               "--preset": "word", "--crn": None, "--cache": None, "--parsimony": None,
               "--no-simplify": None, "--seed-fsa": "path"},
}
# small valid command lines: mutated, they stay cheap to run
BASES = {
    "run": ["run", TOY_FSA, "--task", "examples.toy_task", "--trials", "2"],
    "validate": ["validate", REFERENCE, "--task", "examples.pour_water"],
    "show": ["show", REFERENCE, "-o", str(PLACES / "out.dot")],
    "skills": ["skills", "--task", "examples.pour_water"],
    "robustness": ["robustness", REFERENCE, "--task", "examples.pour_water", "--p-fail",
                   "0,0.5", "--reps", "2", "--workers", "1"],
    "evolve": ["evolve", "examples.toy_task", "--generations", "1", "--population", "4",
               "--initial-nodes", "3", "--backend", "serial", "--quiet", "--no-simplify",
               "--out", str(PLACES / "run")],
}
CHEAP = {"evolve": {"--generations", "--population", "--initial-nodes", "--trials",
                    "--confirm", "--cache-refresh", "--simplify-trials"},
         "run": {"--trials"}, "robustness": {"--reps", "--p-fail", "--workers"}}


@st.composite
def command_lines(draw: st.DrawFn) -> list[str]:
    command = draw(st.sampled_from(sorted(BASES)))
    args = list(BASES[command])
    options = OPTIONS[command]
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["set", "set", "add", "drop", "positional", "bare"]))
        if op in ("set", "add"):
            name = draw(st.sampled_from(sorted(options)))
            kind = options[name]
            if kind is None:
                args.append(name)
                continue
            value = draw(VALUES[kind])
            if name in CHEAP.get(command, ()) and value.lstrip("+").isdigit() and \
                    len(value) < 20 and int(value) > 4:
                value = str(draw(st.integers(-2, 4)))  # valid and large would only be slow
            if op == "set" and name in args and args.index(name) + 1 < len(args):
                args[args.index(name) + 1] = value
            else:
                args += [name, value] if draw(st.booleans()) else [f"{name}={value}"]
        elif op == "drop" and len(args) > 1:
            del args[draw(st.integers(1, len(args) - 1))]
        elif op == "positional" and command != "skills":
            value = draw(st.one_of(VALUES["path"], VALUES["module"]))
            if len(args) > 1:
                args[1] = value
            else:
                args.append(value)
        elif op == "bare":
            args.append(draw(st.sampled_from(sorted(options))))  # an option without value
    return args


@FUZZ
@given(command_lines())
def test_fuzz_command_lines(args: list[str]) -> None:
    out, err = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(args)
        except SystemExit as exc:  # argparse's usage errors
            code = exc.code if isinstance(exc.code, int) else -1
    elapsed = time.perf_counter() - t0
    text = err.getvalue()
    assert elapsed < SECONDS, f"{elapsed:.1f} s"
    assert code in (0, 1, 2), (code, text)
    assert "Traceback" not in text, text
    assert "error: unexpected " not in text, text  # every failure is foreseen and named
    if code:
        lines = text.strip().splitlines()
        assert lines and "error:" in lines[0], text
        if "invalid FSA" not in lines[0]:  # an invalid file lists its problems
            assert len(lines) == 1, text
