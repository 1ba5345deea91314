"""The tutorial's code runs: every ```python block of docs/guide/tutorial.md, in order, in one
namespace, in an empty folder (as a reader would run them)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TUTORIAL = ROOT / "docs" / "guide" / "tutorial.md"


def blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


@pytest.mark.slow  # evolves the tutorial's task with the default preset: a few seconds
def test_the_tutorial_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                           capsys: pytest.CaptureFixture[str]) -> None:
    code = blocks(TUTORIAL.read_text(encoding="utf-8"))
    assert len(code) >= 6
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {"__name__": "tutorial"}
    for k, block in enumerate(code, start=1):
        exec(compile(block, f"{TUTORIAL.name} block {k}", "exec"), namespace)
    out = capsys.readouterr().out
    assert "['Dock', 'Drive', 'Look', 'Turn']" in out
    assert (tmp_path / "charger.yaml").is_file() and (tmp_path / "charger-edited.yaml").is_file()
    assert "the success rate holds at 95 %" in out
    assert "below the required 95 %" in out  # the hand edit broke it, and the test says so
    assert "docked on the stepped backend:" in out


def test_the_tutorial_has_its_code_blocks() -> None:
    code = blocks(TUTORIAL.read_text(encoding="utf-8"))
    for block in code:
        compile(block, "tutorial", "exec")  # every block is Python


def test_every_task_field_has_a_meaning_in_the_docstring() -> None:
    """The reference's Task table (docs/reference/generate.py) takes each field's meaning
    from the docstring's bullets."""
    import dataclasses

    from skillcompose.task import Task

    doc = Task.__doc__ or ""
    missing = [f.name for f in dataclasses.fields(Task) if f.name != "ref" and
               f"``{f.name}``" not in doc and f"``{f.name}(" not in doc]
    assert not missing, f"Task fields without a meaning in its docstring: {missing}"
