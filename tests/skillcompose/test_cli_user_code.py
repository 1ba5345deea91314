"""User code that misbehaves meets the command line: a skill, a task's make_task or world
setup, a skills module's register() or a module being imported that exits, raises a
BaseException that is not an Exception, prints, or returns what is not an outcome. Each is
one clear line (or, for a skill during `run`, a run ended in error) with the documented
status, and with --json standard output holds the document only."""

from __future__ import annotations

import contextlib
import io
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from skillcompose import FSA, Registry, State, compile_fsa, skill
from skillcompose.cli import main
from skillcompose.task import skill_fault, trials

ROOT = Path(__file__).resolve().parents[2]
TOY_FSA = str(ROOT / "tests" / "evolve" / "data" / "toy_solution.yaml")

STOPS = {  # what a skill, make_task or a module does, and how the error names it
    "sys.exit(0)": "SystemExit: 0 (sys.exit() was called",
    "raise SystemExit(3)": "SystemExit: 3 (sys.exit() was called",
    "raise GeneratorExit": "GeneratorExit",
    "raise Weird('not an Exception')": "Weird: not an Exception",
}
SKILLS = """\
import sys
from typing import Literal
from skillcompose import skill

class Weird(BaseException):
    pass

@skill()
def stops(bb, rng) -> Literal["success"]:
    {stop}

@skill()
def interrupts(bb, rng) -> Literal["success"]:
    raise KeyboardInterrupt

@skill()
def lister(bb, rng) -> Literal["success"]:
    return ["success"]

@skill()
def chatty(bb, rng) -> Literal["success"]:
    print("chatty ran")
    return "success"
"""


def cli(*args: str) -> tuple[int, str, str]:
    """Exit status, standard output and standard error of ``skillcompose ARGS``."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(args))
        except SystemExit as exc:  # argparse's usage errors (and nothing else)
            code = exc.code if isinstance(exc.code, int) else -1
    return code, out.getvalue(), err.getvalue()


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def _skills(tmp_path: Path, stop: str = "sys.exit(0)") -> str:
    path = tmp_path / "user_skills.py"
    path.write_text(SKILLS.format(stop=stop))
    return str(path)


def _fsa(tmp_path: Path, skill_name: str) -> str:
    path = tmp_path / f"{skill_name}.yaml"
    path.write_text(f"format: 1\nstart: A\nstates: {{A: {{skill: {skill_name}, "
                    "transitions: {success: success}}}\n")
    return str(path)


def _module(tmp_path: Path, name: str, source: str) -> str:
    path = tmp_path / name
    path.write_text(textwrap.dedent(source))
    return str(path)


# -- #6, #7: a skill that exits or raises a BaseException ends its run in error -------------
@pytest.mark.parametrize("stop", STOPS)
def test_a_skill_that_exits_ends_its_runs_in_error(tmp_path: Path, stop: str) -> None:
    fsa, skills = _fsa(tmp_path, "Stops"), _skills(tmp_path, stop)
    code, out, err = cli("run", fsa, "--skills", skills, "--trials", "4")
    assert code == 1, err  # as for a skill that raises: every run ended in error
    assert out.splitlines()[1].split() == ["error", "4", "100.00%"]
    assert f"4 run(s) ended in error; the first (run 0) in state A: {STOPS[stop]}" in err
    assert "Traceback" not in err and "_skillcompose_user_" not in err
    assert err.strip().splitlines()[-1] == \
        f"skillcompose run: error: every run of {fsa} ended in error"
    code, out, err = cli("run", fsa, "--skills", skills, "--trials", "4", "--json")
    doc = json.loads(out)
    assert code == 1 and doc["outcomes"] == {"error": 4} and doc["errors"]["count"] == 4
    assert doc["errors"]["first"]["state"] == "A"
    assert doc["errors"]["first"]["error"].startswith(STOPS[stop])


def test_a_skill_that_exits_with_propagate_stops_with_its_traceback(tmp_path: Path) -> None:
    fsa, skills = _fsa(tmp_path, "Stops"), _skills(tmp_path)
    with pytest.raises(RuntimeError, match=r"a skill stopped the run: SystemExit: 0") as info:
        main(["run", fsa, "--skills", skills, "--propagate"])
    assert isinstance(info.value.__cause__, SystemExit)


def test_a_skill_raising_keyboard_interrupt_is_still_a_ctrl_c(tmp_path: Path) -> None:
    code, out, err = cli("run", _fsa(tmp_path, "Interrupts"), "--skills", _skills(tmp_path))
    assert (code, out, err) == (130, "", "interrupted\n")


def test_a_skill_that_exits_leaves_a_finished_run_saying_where() -> None:
    @skill(outcomes=("success",))
    def leave(bb: object, rng: object) -> str:
        sys.exit(5)

    @skill(outcomes=("success",))
    def go(bb: object, rng: object) -> str:
        return "success"

    fsa = FSA({"A": State("Go", {}, {"success": "B"}),
               "B": State("Leave", {}, {"success": "success"})}, "A")
    compiled = compile_fsa(fsa, Registry([go, leave]))
    run = compiled.start(None, 0, trace=True)
    with pytest.raises(SystemExit):  # the exception goes on to the caller...
        run.run()
    result = run.result  # ...and the run has ended in error, in the state that exited
    assert (result.outcome, result.steps, result.last_state) == ("error", 2, "B")
    assert isinstance(result.error, SystemExit) and result.trace is not None
    assert [(s.state, s.outcome) for s in result.trace] == [("A", "success"), ("B", "error")]
    (trial,) = trials(compiled, 0, 1, catch=skill_fault)  # the trial keeps that end
    assert trial.result.last_state == "B" and trial.result.steps == 2
    assert not skill_fault(KeyboardInterrupt()) and not skill_fault(ValueError())


# -- #6, #7: make_task, an import and register() that exit: status 2, one line --------------
@pytest.mark.parametrize("stop", STOPS)
def test_make_task_that_exits_is_one_line_and_status_2(tmp_path: Path, stop: str) -> None:
    task = _module(tmp_path, "exits_task.py", f"""\
        import sys
        class Weird(BaseException):
            pass
        def make_task(**settings):
            {stop}
        """)
    for command in (["skills", "--task", task], ["validate", TOY_FSA, "--task", task],
                    ["run", TOY_FSA, "--task", task],
                    ["robustness", TOY_FSA, "--task", task, "--reps", "1"],
                    ["evolve", task, "--generations", "1", "--quiet"]):
        code, out, err = cli(*command)
        assert (code, out) == (2, ""), err
        line = one_line(err)
        called = "make_task(p_fail=0.0)" if command[0] == "robustness" else "make_task()"
        assert line.startswith(f"skillcompose {command[0]}: error: task {task}: {called} "
                               f"raised {task}:5: {STOPS[stop]}"), line


@pytest.mark.parametrize("stop", STOPS)
def test_a_module_that_exits_when_imported_is_one_line_and_status_2(
    tmp_path: Path, stop: str
) -> None:
    module = _module(tmp_path, "exits_at_import.py", f"""\
        import sys
        class Weird(BaseException):
            pass
        {stop}
        """)
    for command in (["validate", TOY_FSA, "--skills", module], ["skills", "--task", module]):
        code, out, err = cli(*command)
        assert (code, out) == (2, ""), err
        line = one_line(err)
        assert f"cannot import {module}: {module}:4: {STOPS[stop]}" in line, line


@pytest.mark.parametrize("source, expected", [
    ("def register(registry):\n    raise RuntimeError('register failed')\n",
     "skills module {path}: register(registry) raised {path}:2: RuntimeError: register failed;"
     " fix its register()"),
    ("import sys\ndef register(registry):\n    sys.exit(0)\n",
     "skills module {path}: register(registry) raised {path}:3: SystemExit: 0 (sys.exit()"),
    ("def register():\n    pass\n",
     "skills module {path}: register() cannot be called as register(registry); define it as "
     "`def register(registry): registry.add(...)`"),
    ("def register(registry, extra):\n    pass\n",
     "skills module {path}: register(registry, extra) cannot be called as register(registry)"),
    ("x = 1\n",
     "skills module {path} defines no skills: decorate functions with @skill, or define "
     "register(registry)"),
])
def test_a_skills_module_whose_register_fails_is_named_with_status_2(
    tmp_path: Path, source: str, expected: str
) -> None:
    path = _module(tmp_path, "my_skills.py", source)
    code, out, err = cli("skills", "--skills", path)
    assert (code, out) == (2, ""), err
    line = one_line(err)
    assert line.startswith(f"skillcompose skills: error: {expected.format(path=path)}"), line
    assert "_skillcompose_user_" not in line and "unexpected" not in line


# -- #11: --set values the task cannot use ---------------------------------------------------
def test_a_set_value_the_world_setup_cannot_use_names_the_setting(tmp_path: Path) -> None:
    code, out, err = cli("run", TOY_FSA, "--task", "examples.toy_task", "--set", "p_fail=abc")
    assert (code, out) == (2, ""), err
    line = one_line(err)
    assert line.startswith("skillcompose run: error: task examples.toy_task: setting up the "
                           "world raised "), line
    assert "toy_task.py:" in line and "ValueError: could not convert string to float: 'abc'" \
        in line
    assert line.endswith("(settings: p_fail='abc'); check the value given with --set p_fail")
    code, _, err = cli("robustness", TOY_FSA, "--task", "examples.toy_task", "--set",
                       "goal=abc", "--p-fail", "0", "--reps", "2")
    assert code == 2 and one_line(err).endswith("check the value given with --set goal"), err


def test_a_set_value_make_task_rejects_names_the_setting() -> None:
    code, out, err = cli("skills", "--task", "examples.toy_task", "--set", "speed=3")
    assert (code, out) == (2, ""), err
    assert one_line(err).endswith("unexpected keyword argument 'speed'; check the value given "
                                  "with --set speed")


@pytest.mark.parametrize("value", ["1e400", "-1e999", "inf", "-Infinity", "nan"])
@pytest.mark.parametrize("command", ["run", "evolve"])
def test_a_set_value_that_is_not_a_finite_number_is_refused(value: str, command: str) -> None:
    argv = ["run", TOY_FSA, "--task", "examples.toy_task"] if command == "run" else \
        ["evolve", "examples.toy_task"]
    code, out, err = cli(*argv, "--set", f"goal={value}")
    assert (code, out) == (2, ""), err
    assert one_line(err) == (
        f"skillcompose {command}: error: argument --set: goal: '{value}' is not a finite "
        "number; give a number within about ±1.8e308 (no inf, no nan) "
        f"(see skillcompose {command} --help)")


def test_runs_scoring_inf_and_warnings_leave_no_raw_warning(tmp_path: Path) -> None:
    skills = _module(tmp_path, "warns.py", """\
        import warnings
        from typing import Literal
        import numpy as np
        from skillcompose import skill

        @skill()
        def breaks(bb, rng) -> Literal["success"]:
            warnings.warn("first line\\nsecond line")
            np.float64(0.0) / np.float64(0.0)  # a numpy RuntimeWarning
            raise ValueError("broken")
        """)
    fsa = _fsa(tmp_path, "Breaks")
    code, out, err = cli("run", fsa, "--task", "examples.toy_task", "--skills", skills)
    assert code == 1  # every run ended in error: fitness inf, its std nan
    assert "fitness mean inf  std nan" in out
    warned = [line for line in err.splitlines() if "Warning" in line]
    assert len(warned) == 2, err  # each on one line, saying where
    assert warned[0] == ("skillcompose run: warning: UserWarning: first line\\nsecond line "
                         f"({skills}:8)")
    assert warned[1].startswith("skillcompose run: warning: RuntimeWarning: invalid value "
                                "encountered in scalar divide (")
    assert "_methods.py" not in err and "x = um." not in err


# -- #16: a skill returning what cannot be an outcome ----------------------------------------
def test_a_skill_returning_a_list_is_an_undeclared_outcome(tmp_path: Path) -> None:
    code, _, err = cli("run", _fsa(tmp_path, "Lister"), "--skills", _skills(tmp_path))
    assert code == 1
    assert ("in state A: UndeclaredOutcomeError: state A: skill Lister returned ['success'], "
            "which is not one of its declared outcomes ['success']; return a declared outcome"
            ) in err
    assert "unhashable" not in err


@pytest.mark.parametrize("value, shown", [
    (["success"], "['success']"), ({"a": 1}, "{'a': 1}"), (np.zeros(3), "array([0., 0., 0.])"),
    (list(range(1000)), "[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, "
                        "19, 20, 21..."),
])
def test_unhashable_and_huge_returns_get_the_undeclared_message(value: object,
                                                                 shown: str) -> None:
    @skill(outcomes=("success",))
    def odd(bb: object, rng: object):  # type: ignore[no-untyped-def]  # returns anything
        return value

    fsa = FSA({"A": State("Odd", {}, {"success": "success"})}, "A")
    result = compile_fsa(fsa, Registry([odd])).run()
    assert result.outcome == "error"
    assert str(result.error) == (
        f"state A: skill Odd returned {shown}, which is not one of its declared outcomes "
        "['success']; return a declared outcome or add it to the skill's outcomes")


# -- #8: --json: standard output holds the document only ------------------------------------
NOISY_TASK = """\
import atexit
import os
from dataclasses import replace
from typing import Literal

from examples import toy_task
from skillcompose import skill

print("printed at import")
os.write(1, b"fd 1 at import\\n")
atexit.register(lambda: (print("printed at exit"), os.write(1, b"fd 1 at exit\\n")))


@skill()
def chatty(bb, rng) -> Literal["success"]:
    print("printed by a skill")
    os.write(1, b"fd 1 by a skill\\n")
    return "success"


def make_task(**settings):
    print("printed by make_task")
    task = toy_task.make_task(**settings)
    task.registry.add(chatty)
    setup = task.setup

    def noisy_setup(rng):
        os.write(1, b"fd 1 by setup\\n")  # as C code writing to standard output would
        return setup(rng)

    return replace(task, setup=noisy_setup)
"""


@pytest.mark.parametrize("command", ["run", "skills", "validate", "evolve"])
def test_json_output_holds_only_the_document_when_user_code_prints(
    tmp_path: Path, command: str
) -> None:
    task = _module(tmp_path, "noisy_task.py", NOISY_TASK)
    fsa = tmp_path / "chatty.yaml"
    fsa.write_text(Path(TOY_FSA).read_text().replace(
        "    transitions: {success: Wait_2}",
        "    transitions: {success: Chat}\n  Chat:\n    skill: Chatty\n"
        "    transitions: {success: Wait_2}"))
    argv = {
        "run": ["run", str(fsa), "--task", task, "--trials", "2"],
        "skills": ["skills", "--task", task],
        "validate": ["validate", str(fsa), "--task", task],
        "evolve": ["evolve", task, "--population", "6", "--initial-nodes", "3",
                   "--generations", "1", "--workers", "2", "--backend", "process",
                   "--check-trials", "2", "--simplify-trials", "2", "-q"],
    }[command]
    proc = subprocess.run([sys.executable, "-m", "skillcompose", *argv, "--json"],
                          capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)  # the whole of standard output is the document
    assert doc["command"] == command
    err = proc.stderr
    assert "printed at import" in err and "fd 1 at import" in err
    assert "printed by make_task" in err
    if command in ("run", "evolve"):  # user code ran: in this process, or in pool workers
        assert "printed by a skill" in err or command == "evolve"
        assert "fd 1 by setup" in err
    if command == "run":
        assert err.count("printed by a skill") == 2 and err.count("fd 1 by a skill") == 2
    assert "printed at exit" in err and "fd 1 at exit" in err  # after the document: not


def test_json_keeps_the_document_on_a_python_level_standard_output(tmp_path: Path) -> None:
    """In a program (a notebook, a test) whose sys.stdout is not file descriptor 1: the
    document goes there, prints of user code go to sys.stderr."""
    skills = _skills(tmp_path)
    code, out, err = cli("run", _fsa(tmp_path, "Chatty"), "--skills", skills, "--json")
    assert code == 0 and json.loads(out)["outcomes"] == {"success": 1}
    assert err == "chatty ran\n"


def test_a_sweep_counts_a_skill_that_exits_as_runs_in_error(tmp_path: Path) -> None:
    task = _module(tmp_path, "exits_in_sweep.py", """\
        import sys
        from typing import Literal
        from examples import toy_task
        from skillcompose import skill

        @skill()
        def quits(bb, rng) -> Literal["success"]:
            sys.exit(0)

        def make_task(**settings):
            task = toy_task.make_task(**settings)
            task.registry.add(quits)
            return task
        """)
    code, out, err = cli("robustness", _fsa(tmp_path, "Quits"), "--task", task,
                         "--p-fail", "0:1:2", "--reps", "3")
    # one line, as `run` gives (and no raw RuntimeWarning for the inf fitness)
    assert code == 1 and err.count("\n") == 1, err
    assert err.startswith("skillcompose robustness: error: every run of ")
    rows = [line.split() for line in out.strip().splitlines()]
    assert rows[0][-1] == "error_rate" and [r[-1] for r in rows[1:]] == ["1", "1"]


def test_settings_that_are_not_finite_numbers_are_refused_in_python() -> None:
    from skillcompose.task import TaskError, parse_settings

    assert parse_settings(["p_fail=0.5", "name=inference"]) == {"p_fail": 0.5,
                                                                "name": "inference"}
    with pytest.raises(TaskError, match=r"'goal=1e400': '1e400' is not a finite number"):
        parse_settings(["goal=1e400"])


def test_an_entry_point_that_fails_names_itself(monkeypatch: pytest.MonkeyPatch) -> None:
    from importlib import metadata

    from skillcompose.errors import RegistryError

    class Broken:
        name, value = "broken", "broken_pkg.skills:register"

        def __init__(self, loaded: object) -> None:
            self.loaded = loaded

        def load(self) -> object:
            if self.loaded is None:
                sys.exit(2)
            return self.loaded

    def register(registry: Registry) -> None:
        raise RuntimeError("no robot")

    for loaded, message in ((None, "cannot import it: "), (register, "register(registry) "
                                                           "raised ")):
        monkeypatch.setattr(metadata, "entry_points", lambda group, _l=loaded: [Broken(_l)])
        with pytest.raises(RegistryError) as info:
            Registry().load_entry_points()
        assert str(info.value).startswith(
            "entry point broken = broken_pkg.skills:register (group skillcompose.skills): "
            + message)
