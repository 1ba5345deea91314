"""The command line with bad arguments: one-line errors naming the argument, exit status 2
for usage errors and 1 for failures, never a traceback unless asked for."""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from skillcompose.cli import main

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = str(ROOT / "examples" / "pour_water_reference.fsa.yaml")


def cli(*args: str) -> tuple[int, str, str]:
    """Exit status, standard output and standard error of ``skillcompose ARGS``."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(args))
        except SystemExit as exc:  # argparse's usage errors
            code = exc.code if isinstance(exc.code, int) else -1
    return code, out.getvalue(), err.getvalue()


def usage_error(*args: str, naming: str) -> str:
    """The one line ``skillcompose ARGS`` fails with, exit status 2, naming ``naming``."""
    t0 = time.perf_counter()
    code, _, err = cli(*args)
    assert time.perf_counter() - t0 < 5.0
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert naming in lines[0], lines[0]
    return lines[0]


# -- 6. tracebacks -------------------------------------------------------------------------
def test_negative_seed_is_a_usage_error() -> None:
    line = usage_error("run", REFERENCE, "--task", "examples.pour_water", "--seed", "-1",
                       naming="--seed")
    assert "from 0 to" in line and "'-1'" in line


@pytest.mark.parametrize("flag", ["--seed", "--trials"])
@pytest.mark.parametrize("value", ["1.5", "nan", "x", "9" * 5000, ""])
def test_run_numbers_must_be_whole(flag: str, value: str) -> None:
    usage_error("run", REFERENCE, "--task", "examples.pour_water", flag, value, naming=flag)


def _outputs(tmp_path: Path) -> dict[str, str]:
    a_file = tmp_path / "a_file.txt"
    a_file.write_text("x")
    (tmp_path / "a_dir").mkdir(exist_ok=True)
    return {
        "file as directory": str(a_file / "out.{}"),
        "directory as file": str(tmp_path / "a_dir"),
        "directory with a slash": str(tmp_path / "a_dir") + "/",
    }


@pytest.mark.parametrize("case", ["file as directory", "directory as file",
                                  "directory with a slash"])
def test_show_output_must_be_a_writable_file(tmp_path: Path, case: str) -> None:
    out = _outputs(tmp_path)[case].format("svg")
    usage_error("show", REFERENCE, "-o", out, naming="-o/--output")


def test_show_output_needs_a_drawing_suffix(tmp_path: Path) -> None:
    line = usage_error("show", REFERENCE, "-o", str(tmp_path / "x.txt"), naming="-o/--output")
    assert ".svg" in line


@pytest.mark.parametrize("case", ["file as directory", "directory as file"])
def test_robustness_csv_must_be_a_writable_file(tmp_path: Path, case: str) -> None:
    out = _outputs(tmp_path)[case].format("csv")
    usage_error("robustness", REFERENCE, "--task", "examples.pour_water", "--reps", "2",
                "--p-fail", "0", "--csv", out, naming="--csv")


@pytest.mark.parametrize("case", ["file as directory", "a file"])
def test_evolve_out_must_be_a_directory(tmp_path: Path, case: str) -> None:
    out = _outputs(tmp_path)["file as directory"].format("d")
    if case == "a file":
        out = str(tmp_path / "a_file.txt")
    usage_error("evolve", "examples.toy_task", "--out", out, naming="--out")


def test_an_output_that_fails_when_written_is_one_line_and_status_1(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import skillcompose.draw

    def refuse(*args: object, **kwargs: object) -> Path:
        raise PermissionError(13, "Permission denied", str(tmp_path / "x.png"))

    monkeypatch.setattr(skillcompose.draw, "render", refuse)
    code, _, err = cli("show", REFERENCE, "-o", str(tmp_path / "x.png"))
    assert code == 1 and "Traceback" not in err
    assert err.strip() == f"skillcompose show: error: {tmp_path / 'x.png'}: Permission denied"
    with pytest.raises(PermissionError):  # asked for: the traceback
        main(["--traceback", "show", REFERENCE, "-o", str(tmp_path / "x.png")])


def test_an_unexpected_error_is_one_line_and_status_1(monkeypatch: pytest.MonkeyPatch) -> None:
    import skillcompose.fsafile

    def broken(*args: object) -> None:
        raise ZeroDivisionError("division by zero")

    # the command imports the reader when it runs
    monkeypatch.setattr(skillcompose.fsafile, "load_fsa", broken)
    code, _, err = cli("validate", REFERENCE)
    assert code == 1 and len(err.strip().splitlines()) == 1
    assert "unexpected ZeroDivisionError: division by zero" in err and "--traceback" in err


@pytest.mark.parametrize("task", [".name", "a..b", "-x", "os.", "x y", "no/such/file.py"])
def test_task_names_are_checked_when_parsed(task: str) -> None:
    usage_error("run", REFERENCE, "--task", task, naming="--task")
    usage_error("robustness", REFERENCE, "--task", task, naming="--task")


@pytest.mark.parametrize(
    "source, expected",
    [
        ("import no_such_module_anywhere\n", "ModuleNotFoundError: No module named"),
        ("def make_task(:\n", "SyntaxError"),
        ("x = 1 / 0\n", "bad_task.py:1: ZeroDivisionError: division by zero"),
        ("def make_task(**settings):\n    raise RuntimeError('no world')\n",
         "bad_task.py:2: RuntimeError: no world"),
        ("def make_task(**settings):\n    return 3\n", "returned int, not Task"),
    ],
)
def test_a_task_that_fails_to_load_is_one_line(tmp_path: Path, source: str,
                                                expected: str) -> None:
    path = tmp_path / "bad_task.py"
    path.write_text(source)
    for command in (["run", REFERENCE, "--task", str(path)],
                    ["evolve", str(path), "--generations", "1", "--quiet"],
                    ["robustness", REFERENCE, "--task", str(path), "--reps", "1"]):
        code, _, err = cli(*command)
        assert code == 2, err
        assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
        assert expected in err and "bad_task" in err


def test_skills_modules_that_fail_to_import_are_one_line(tmp_path: Path) -> None:
    path = tmp_path / "bad_skills.py"
    path.write_text("raise ImportError('needs a robot')\n")
    code, _, err = cli("skills", "--skills", str(path))
    assert code == 2 and "bad_skills.py:1: ImportError: needs a robot" in err
    assert len(err.strip().splitlines()) == 1


# -- 7. importing task modules ---------------------------------------------------------------
def test_a_task_file_imports_the_modules_beside_it(tmp_path: Path) -> None:
    home = tmp_path / "mytasks"
    home.mkdir()
    (home / "helper_for_my_task.py").write_text("P_FAIL = 0.0\n")
    (home / "my_task.py").write_text(textwrap.dedent(
        """\
        from helper_for_my_task import P_FAIL
        from examples import toy_task

        def make_task(**settings):
            return toy_task.make_task(p_fail=P_FAIL, **settings)
        """
    ))
    fsa = ROOT / "tests" / "evolve" / "data" / "toy_solution.yaml"
    code, out, err = cli("run", str(fsa), "--task", str(home / "my_task.py"), "--trials", "3")
    assert code == 0, err
    assert "3 run(s)" in out


@pytest.mark.slow
def test_examples_import_from_any_directory(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run(
        [sys.executable, "-m", "skillcompose", "run", REFERENCE, "--task",
         "examples.pour_water", "--trials", "2"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120, env=env,
    )
    assert proc.returncode == 0, proc.stderr
    assert "2 run(s)" in proc.stdout


# -- 8. values accepted silently ---------------------------------------------------------------
def test_unknown_backend_names_the_known_ones() -> None:
    line = usage_error("run", REFERENCE, "--task", "examples.pour_water", "--backend",
                       "kinmatic", naming="--backend 'kinmatic'")
    assert "sim" in line
    line = usage_error("validate", REFERENCE, "--task", "examples.pour_water", "--backend",
                       "kinmatic", naming="--backend 'kinmatic'")
    line = usage_error("robustness", REFERENCE, "--task", "examples.pour_water", "--backend",
                       "kinmatic", "--reps", "1", naming="--backend 'kinmatic'")
    assert "sim" in line


@pytest.mark.parametrize(
    "flag, value",
    [
        ("--workers", "0"), ("--workers", "-1"), ("--param-sigma", "nan"),
        ("--param-sigma", "inf"), ("--param-sigma", "-0.1"), ("--param-sigma", "1e999"),
        ("--simplify-trials", "0"), ("--simplify-trials", "-1"),
        ("--trials", "1000000000000"), ("--trials", "0"), ("--population", "1"),
        ("--generations", "-1"), ("--seed", "-1"), ("--elitism", "-1"),
        ("--checkpoint-every", "0"), ("--backend", "kinmatic"), ("--tournament", "0"),
        ("--initial-nodes", "0"), ("--confirm", "-2"), ("--cache-refresh", "x"),
        ("--set", "p_fail"), ("--set", "=3"),
    ],
)
def test_evolve_arguments_are_checked_when_parsed(tmp_path: Path, flag: str,
                                                   value: str) -> None:
    usage_error("evolve", "examples.toy_task", "--out", str(tmp_path / "run"), flag, value,
                naming=flag)
    assert not (tmp_path / "run").exists()  # nothing ran


@pytest.mark.parametrize(
    "flag, value",
    [
        ("--p-fail", "0:1:100000000"), ("--p-fail", "0:1:0"), ("--p-fail", "nan,0.5"),
        ("--p-fail", "0:inf:3"), ("--p-fail", "0:1:" + "9" * 5000), ("--p-fail", ","),
        ("--reps", "0"), ("--reps", "10000000000"), ("--workers", "0"), ("--seed", "-3"),
        ("--step-limit", "0"), ("--step-limit", "1000000000000"), ("--setting", "p fail"),
    ],
)
def test_robustness_arguments_are_bounded(flag: str, value: str) -> None:
    usage_error("robustness", REFERENCE, "--task", "examples.pour_water", flag, value,
                naming=flag)


def test_run_trials_are_bounded() -> None:
    usage_error("run", REFERENCE, "--task", "examples.pour_water", "--trials",
                "1000000000000", naming="--trials")


def test_valid_arguments_still_run(tmp_path: Path) -> None:
    code, out, err = cli("robustness", REFERENCE, "--task", "examples.pour_water",
                         "--p-fail", "0,0.5", "--reps", "3", "--workers", "1",
                         "--csv", str(tmp_path / "new" / "t.csv"))
    assert code == 0, err
    assert (tmp_path / "new" / "t.csv").is_file()
    code, out, err = cli("run", REFERENCE, "--task", "examples.pour_water", "--backend", "sim",
                         "--seed", str(2**63 - 1), "--trials", "2")
    assert code == 0, err
    assert "backend sim" in out
