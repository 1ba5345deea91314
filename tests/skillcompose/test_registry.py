from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import pytest

from skillcompose import (
    FSA,
    Blackboard,
    Param,
    Registry,
    RegistryError,
    Skill,
    State,
    UnknownSkillError,
    compile_fsa,
    skill,
)
from tests.skillcompose import demo_skills


def _backend_pair() -> tuple[object, object]:
    @skill(name="Detect", backend="sim", writes=("seen",))
    def detect_sim(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
        bb["seen"] = "sim"
        return "success"

    @skill(name="Detect", backend="kinematic", writes=("seen",))
    def detect_kin(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
        bb["seen"] = "kinematic"
        return "success"

    return detect_sim, detect_kin


def test_backend_swap_on_one_fsa() -> None:
    sim, kin = _backend_pair()
    reg = Registry([sim, kin])  # type: ignore[list-item]
    fsa = FSA({"D": State("Detect", {}, {"success": "success", "failure": "failure"})}, "D")
    for backend in ("sim", "kinematic"):
        bb = Blackboard()
        result = compile_fsa(fsa, reg, backend).run(bb, 0)
        assert result.outcome == "success"
        assert bb["seen"] == backend
    with pytest.raises(UnknownSkillError, match=r"no 'real' implementation.*--backend"):
        compile_fsa(fsa, reg, "real")


def test_backends_must_share_a_signature() -> None:
    sim, _ = _backend_pair()

    @skill(name="Detect", backend="real")
    def detect_real(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
        return "success"

    reg = Registry([sim])  # type: ignore[list-item]
    with pytest.raises(RegistryError, match="same signature"):
        reg.add(detect_real)


@skill(name="Reach", backend="sim")
def _reach_sim(bb: Blackboard, rng: np.random.Generator, *,
               d: Annotated[float, Param(0.01, 1.0, unit="m")] = 0.5) -> Literal["success"]:
    return "success"


@skill(name="Reach", backend="cm")
def _reach_cm(bb: Blackboard, rng: np.random.Generator, *,
              d: Annotated[float, Param(0.01, 1.0, unit="cm")] = 0.5) -> Literal["success"]:
    return "success"


@skill(name="Reach", backend="log")
def _reach_log(bb: Blackboard, rng: np.random.Generator, *,
               d: Annotated[float, Param(0.01, 1.0, unit="m", scale="log")] = 0.5
               ) -> Literal["success"]:
    return "success"


@skill(name="Reach", backend="default")
def _reach_default(bb: Blackboard, rng: np.random.Generator, *,
                   d: Annotated[float, Param(0.01, 1.0, unit="m")] = 0.25) -> Literal["success"]:
    return "success"


@pytest.mark.parametrize("twin", [_reach_cm, _reach_log, _reach_default],
                         ids=["unit", "scale", "default"])
def test_twins_cannot_differ_in_unit_scale_or_default(twin: Skill) -> None:
    """One file must mean one thing on every backend."""
    with pytest.raises(RegistryError, match="same signature"):
        Registry([_reach_sim, twin])


def test_unknown_skill_suggests() -> None:
    reg = Registry.from_modules([demo_skills])
    with pytest.raises(UnknownSkillError, match="did you mean MoveToObject"):
        reg.spec("MoveToObjet")


def test_load_by_dotted_name_and_by_path(tmp_path: Path) -> None:
    reg = Registry()
    added = reg.load_module("tests.skillcompose.demo_skills")
    assert "GraspObject" in reg and len(added) == len(reg)
    f = tmp_path / "my_skills.py"
    f.write_text(
        "from typing import Literal\nfrom skillcompose import skill\n"
        "def register(registry):\n"
        "    @skill\n"
        "    def wave(bb, rng) -> Literal['success']:\n"
        "        return 'success'\n"
        "    registry.add(wave)\n"
    )
    reg.load_module(str(f))
    assert "Wave" in reg


def test_module_without_skills(tmp_path: Path) -> None:
    f = tmp_path / "empty.py"
    f.write_text("x = 1\n")
    with pytest.raises(RegistryError, match="defines no skills"):
        Registry().load_module(str(f))
    with pytest.raises(RegistryError, match="cannot import skills module"):
        Registry().load_module("no_such_module_here")


def test_two_registries_are_independent() -> None:
    a = Registry.from_modules([demo_skills])
    b = Registry()
    assert len(a) > 0 and len(b) == 0


def test_relabelling_a_backend_keeps_the_skill_kind() -> None:
    from skillcompose import FSASkill, fsa_skill

    reg = Registry.from_modules([demo_skills])
    child = FSA({"N": State("Noop", {}, {"success": "success"})}, "N", name="Child")
    nested = fsa_skill(child, reg)
    other = Registry.from_modules([demo_skills])
    added = other.add(nested, backend="sim")
    assert isinstance(added, FSASkill)
    assert added.backend == "sim" and nested.backend == "default"
    parent = FSA({"C": State("Child", {}, {"success": "success", "failure": "failure"})}, "C")
    assert compile_fsa(parent, other, "sim").run(None, 0).outcome == "success"


def test_entry_points_group(monkeypatch: pytest.MonkeyPatch) -> None:
    """Installed packages advertise skill modules in the `skillcompose.skills` group."""
    from importlib import metadata

    import skillcompose.registry as registry_module

    ep = metadata.EntryPoint("demo", "tests.skillcompose.demo_skills", "skillcompose.skills")

    def fake(group: str) -> list[metadata.EntryPoint]:
        return [ep] if group == "skillcompose.skills" else []

    monkeypatch.setattr(registry_module.metadata, "entry_points", fake)
    reg = Registry()
    added = reg.load_entry_points()
    assert "MoveToObject" in reg and len(added) == len(reg)


def test_backend_swap_on_one_file_from_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One FSA file, two backends picked at run time: the paper's sim-to-real point."""
    from skillcompose import save_fsa
    from skillcompose.cli import main

    module = tmp_path / "detect_skills.py"
    module.write_text(
        "from typing import Literal\n"
        "from skillcompose import skill\n"
        "@skill(name='Detect', backend='sim', writes=('seen',))\n"
        "def detect_sim(bb, rng) -> Literal['success', 'failure']:\n"
        "    return 'success'\n"
        "@skill(name='Detect', backend='kinematic', writes=('seen',))\n"
        "def detect_kin(bb, rng) -> Literal['success', 'failure']:\n"
        "    return 'failure'\n"
    )
    fsa = FSA({"D": State("Detect", {}, {"success": "success", "failure": "failure"})}, "D")
    path = save_fsa(fsa, tmp_path / "detect.fsa.yaml").path
    assert path is not None
    for backend, expected in (("sim", "success"), ("kinematic", "failure")):
        assert main(["run", path, "--skills", str(module), "--backend", backend]) == 0
        out = capsys.readouterr().out
        assert f"backend {backend}" in out and f"  {expected} " in out
