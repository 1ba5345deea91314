"""Subcommands come through entry points: this package's own, and another package's."""

from __future__ import annotations

import sys
import types
from importlib import metadata

import pytest

from skillcompose import cli


def test_this_packages_commands_are_its_entry_points() -> None:
    installed = [ep.value for ep in metadata.entry_points(group=cli.COMMANDS_GROUP)]
    if not installed:
        pytest.skip("the package is not installed: its commands come from the built-in list")
    assert set(cli.subcommand_modules()) == set(cli.SUBCOMMAND_MODULES)
    parser = cli.build_parser()
    commands = next(a for a in parser._actions if a.dest == "command").choices
    assert commands is not None
    assert {"evolve", "robustness", "robot", "view", "run", "validate"} <= set(commands)


def test_another_package_adds_a_command(monkeypatch: pytest.MonkeyPatch,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    module = types.ModuleType("other_pkg_commands_for_test")

    def register_cli(subparsers: object) -> None:
        p = subparsers.add_parser("hello", help="say hello")  # type: ignore[attr-defined]
        p.set_defaults(func=lambda args: print("hello from another package") or 0)

    module.register_cli = register_cli  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, module.__name__, module)
    original = metadata.entry_points
    ours = original(group=cli.COMMANDS_GROUP)
    extra = metadata.EntryPoint("hello", module.__name__, cli.COMMANDS_GROUP)

    def entry_points(**kwargs: object) -> object:
        if kwargs.get("group") == cli.COMMANDS_GROUP:
            return metadata.EntryPoints([*ours, extra])
        return original(**kwargs)

    monkeypatch.setattr(metadata, "entry_points", entry_points)
    assert module.__name__ in cli.subcommand_modules()
    assert cli.main(["hello", "-q"]) == 0
    assert capsys.readouterr().out == "hello from another package\n"
