"""One import name: the wheel installs ``skillcompose`` and nothing else, and a folder a
user named is on the import path for the one import it was named for."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from skillcompose.errors import RegistryError
from skillcompose.registry import import_target

ROOT = Path(__file__).resolve().parents[2]


def _tracked(root: Path) -> list[str]:
    done = subprocess.run(["git", "ls-files", "pyproject.toml", "README.md", "skillcompose",
                           "evolve", "robots", "skills"], cwd=root, capture_output=True,
                          text=True, check=True)
    return done.stdout.split()


def test_the_wheel_holds_only_skillcompose(tmp_path: Path) -> None:
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs a git checkout to know the project's files")
    source = tmp_path / "source"
    for name in _tracked(ROOT):  # a copy, so that the build writes nothing into the checkout
        (source / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, source / name)
    out = tmp_path / "wheel"
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", "--verbose", "--no-deps",
                            "--no-build-isolation", "--wheel-dir", str(out), str(source)],
                           capture_output=True, text=True)
    assert built.returncode == 0, built.stderr[-2000:]
    # setuptools warns of what a later version will refuse (a license table, a data folder
    # missing from the packages): the build must not depend on it
    warned = [line.strip() for line in (built.stdout + built.stderr).splitlines()
              if "BuildBackendWarning" in line and "Editable installation" not in line]
    assert warned == [], warned
    (wheel,) = out.glob("skillcompose-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        tops = {n.split("/", 1)[0] for n in names}
        dist_info = next(t for t in tops if t.endswith(".dist-info"))
        top_level = archive.read(f"{dist_info}/top_level.txt").decode().split() \
            if f"{dist_info}/top_level.txt" in names else ["skillcompose"]
    assert tops == {"skillcompose", dist_info}, tops
    assert top_level == ["skillcompose"]
    for sub in ("evolve", "robots", "skills", "view"):
        assert f"skillcompose/{sub}/__init__.py" in names
        assert f"skillcompose/{sub}/py.typed" in names
    assert "skillcompose/robots/data/reachability_rbf_v2.npz" in names
    assert "skillcompose/schema/fsa.schema.json" in names


def test_the_generic_names_are_not_importable() -> None:
    code = ("import importlib.util, sys; sys.path[:] = [p for p in sys.path if p not in "
            "('', '.')]; print([n for n in ('evolve', 'robots', 'skills', "
            "'skillcompose_view') if importlib.util.find_spec(n)])")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, cwd="/")
    assert done.stdout.strip() == "[]"


def test_a_dotted_task_from_the_current_folder_leaves_the_path_as_it_was(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "mytask_for_path_test.py").write_text("VALUE = 1\n", encoding="utf-8")
    (tmp_path / "winreg_like_for_path_test.py").write_text(
        "raise SystemExit('imported from the current folder')\n", encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", ".", str(tmp_path))])
    before = list(sys.path)
    try:
        module = import_target("mytask_for_path_test")
        assert module.VALUE == 1
        assert sys.path == before
        with pytest.raises(ModuleNotFoundError):  # a later import does not see the folder
            __import__("winreg_like_for_path_test")
    finally:
        sys.modules.pop("mytask_for_path_test", None)


def test_a_task_file_imports_the_modules_beside_it_for_its_own_import_only(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = tmp_path / "received"
    folder.mkdir()
    (folder / "helper_beside_for_path_test.py").write_text("X = 7\n", encoding="utf-8")
    (folder / "task_file.py").write_text(
        "from helper_beside_for_path_test import X\nVALUE = X\n", encoding="utf-8")
    before = list(sys.path)
    try:
        module = import_target(str(folder / "task_file.py"))
        assert module.VALUE == 7
        assert sys.path == before
    finally:
        sys.modules.pop("helper_beside_for_path_test", None)


def test_examples_import_from_the_checkout_wherever_the_command_runs(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", [p for p in sys.path
                                      if p not in ("", ".", str(ROOT), str(tmp_path))])
    for name in [m for m in sys.modules if m == "examples" or m.startswith("examples.")]:
        monkeypatch.delitem(sys.modules, name)
    before = list(sys.path)
    module = import_target("examples.toy_task")
    assert Path(str(module.__file__)).resolve().is_relative_to(ROOT / "examples")
    assert sys.path == before


def test_a_missing_module_is_still_one_line(tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    before = list(sys.path)
    with pytest.raises(RegistryError, match="importable from the current directory"):
        import_target("no_such_module_for_path_test")
    assert sys.path == before


def test_a_task_file_inside_a_package_imports_its_package(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`skillcompose evolve examples/kinematic_pour.py` (a path, from any folder): a file in a
    package imports as `python -m` would import it, by its dotted name."""
    package = tmp_path / "mypkg_for_path_test"
    package.mkdir()
    (package / "__init__.py").write_text("", encoding="utf-8")
    (package / "base.py").write_text("VALUE = 3\n", encoding="utf-8")
    (package / "task.py").write_text("from mypkg_for_path_test import base\n"
                                     "VALUE = base.VALUE\n", encoding="utf-8")
    monkeypatch.chdir(tmp_path.parent)
    before = list(sys.path)
    try:
        module = import_target(str(package / "task.py"))
        assert module.VALUE == 3 and module.__name__ == "mypkg_for_path_test.task"
        assert sys.path == before
    finally:
        for name in [m for m in sys.modules if m.startswith("mypkg_for_path_test")]:
            del sys.modules[name]
    examples = import_target(str(ROOT / "examples" / "kinematic_pour.py"))
    assert hasattr(examples, "make_task")
