"""Pages of the reference written from the code at build time (mkdocs-gen-files): every
field of ``Task`` with its type, default and meaning; the presets and every evolution
setting from ``EvolutionConfig`` and its table of settings; the command line from its
parser. Nothing here is written by hand, so the reference cannot drift from the code."""

from __future__ import annotations

import argparse
import dataclasses
import os
import runpy
from pathlib import Path

import mkdocs_gen_files

from skillcompose.cli import build_parser
from skillcompose.evolve.config import (
    NOISY_DEFAULT,
    PRESET_ABOUT,
    PRESET_NAMES,
    PRESETS,
    EvolutionConfig,
    preset_settings,
)
from skillcompose.evolve.settings import SETTINGS, Setting
from skillcompose.task import Task


def _bullets(doc: str) -> list[str]:
    """The ``- ...`` items of a docstring, each joined into one line."""
    items: list[str] = []
    for line in doc.splitlines():
        stripped = line.strip()
        if stripped.startswith("- "):
            items.append(stripped[2:])
        elif items and stripped and line.startswith("      "):
            items[-1] += " " + stripped
    return items


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def task_page() -> str:
    bullets = _bullets(Task.__doc__ or "")
    rows = []
    for f in dataclasses.fields(Task):
        if f.name == "ref":
            continue
        meaning = next((b for b in bullets if f"``{f.name}``" in b or
                        f"``{f.name}(" in b), "")
        if f.default is not dataclasses.MISSING:
            default = f"`{f.default!r}`"
        elif f.default_factory is not dataclasses.MISSING:
            default = f"`{f.default_factory()!r}`"
        else:
            default = "required"
        kind = str(f.type).replace("|", "or")
        rows.append(f"| `{f.name}` | `{kind}` | {default} | {_cell(meaning)} |")
    return "\n".join([
        "# Task fields",
        "",
        "Written from `skillcompose.task.Task` when the site is built. A task module's",
        "`make_task(**settings)` returns one; every field is checked where the Task is made,",
        "and a wrong one is a one-line `TaskError` naming the field and what it takes.",
        "",
        "| field | type | default | meaning |",
        "|---|---|---|---|",
        *rows,
        "",
    ])


def _code(s: Setting) -> str:
    return f"`{s.name}`"


def _preset_section(name: str, defaults: EvolutionConfig) -> list[str]:
    """What preset ``name`` is for and each setting it sets, with its meaning."""
    lines = [f"### `{name}`", "", PRESET_ABOUT[name][0].upper() + PRESET_ABOUT[name][1:] + ".",
             ""]
    chosen = PRESETS[name]
    if not chosen:
        lines.append("It sets nothing: every setting is `EvolutionConfig()`'s.")
    for s in SETTINGS:
        if s.name in chosen:
            lines.append(f"- {_code(s)} = {s.describe(chosen[s.name])} (default "
                         f"{s.describe_default(getattr(defaults, s.name))}): "
                         f"{s.text(_code)}")
    return [*lines, ""]


def presets_page() -> str:
    names = [n for n in PRESET_NAMES if n != "default"]
    defaults = EvolutionConfig()
    header = "| setting | " + " | ".join(f"`{n}`" for n in names) + " |"
    rows = [header, "|---|" + "---|" * len(names)]
    for s in SETTINGS:
        values = [PRESETS[n].get(s.name, getattr(defaults, s.name)) for n in names]
        cells = [f"**{v!r}**" if s.name in PRESETS[n] else repr(v)
                 for n, v in zip(names, values, strict=True)]
        rows.append(f"| {_code(s)} | " + " | ".join(cells) + " |")
    every = ["| setting | option | takes | default | meaning |", "|---|---|---|---|---|"]
    for s in SETTINGS:
        option = f"`{s.flag}`" if s.flag else "none: `EvolutionConfig` only"
        if s.flag_zero_is_none:
            option += f"; 0: {s.none}"
        every.append(f"| {_code(s)} | {option} | {_cell(s.takes())} | "
                     f"{_cell(s.describe_default(getattr(defaults, s.name)))} | "
                     f"{_cell(s.text(_code, more=True))} |")
    def resolved(deterministic: bool, vectors: bool = False) -> str:
        """The preset ``default`` is for a task that is ``deterministic`` or not, whose
        skills take a vector or not."""
        got = preset_settings("default", deterministic, vectors)
        if got == NOISY_DEFAULT:
            extra = {k: v for k, v in got.items() if PRESETS["islands"].get(k) != v}
            return ("`NOISY_DEFAULT` (`islands` with " +
                    ", ".join(f"`{k}={v}`" for k, v in extra.items()) + ")")
        return next((f"`{n}`" for n in PRESETS if n != "default" and PRESETS[n] == got),
                    "its own settings")
    return "\n".join([
        "# Presets",
        "",
        "Written from `skillcompose.evolve.config` and the table of settings,",
        "`skillcompose.evolve.settings.SETTINGS`, when the site is built: the config checks",
        "each setting, and `skillcompose evolve` offers it, from the same record. Bold: what",
        "the preset sets; the rest is the paper's table 1 (`EvolutionConfig()`), which `paper`",
        "is. `default` (`skillcompose evolve TASK` with no `--preset`, and `evolve(task)` with",
        f"no config) is {resolved(False)} for a noisy task, {resolved(False, True)} for a "
        "noisy task with a skill that takes a vector (a network's weights), and "
        f"{resolved(True)} for a task whose episodes are all the same.",
        "",
        *rows,
        "",
        "## What each preset sets",
        "",
        *[line for n in names for line in _preset_section(n, defaults)],
        "## Every setting",
        "",
        "What each setting takes is what both the config and its command-line option accept.",
        "What the settings mean together (budgets, what \"solved\" means) is in",
        "[`EvolutionConfig`](api.md) and [Evolving](../evolve.md).",
        "",
        *every,
        "",
    ])


def cli_page() -> str:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    parts = ["# Command line", "", "Written from the parser when the site is built.", "",
             "```text", parser.format_help().rstrip(), "```", ""]
    for name, sub in action.choices.items():
        parts += [f"## `skillcompose {name}`", "", "```text", sub.format_help().rstrip(),
                  "```", ""]
    return "\n".join(parts)


def main() -> None:
    """Lay out the installed package for mkdocstrings, and write the pages into the site."""
    # mkdocstrings reads the package from the installed layout that .ci/typecheck.py lays
    # out of symbolic links (an editable install finds evolve/, robots/ and skills/ through
    # an import hook, which static readers do not run); mkdocs.yml points its `paths` there
    tools = runpy.run_path(str(Path(__file__).resolve().parents[2] / ".ci" / "typecheck.py"),
                           run_name="docs")
    tools["build_tree"](tools["package_dirs"]())
    os.environ["COLUMNS"] = "100"  # argparse wraps its help at this width
    for path, text in (("reference/task.md", task_page()),
                       ("reference/presets.md", presets_page()),
                       ("reference/cli.md", cli_page())):
        with mkdocs_gen_files.open(path, "w") as out:
            out.write(text)


if __name__ in ("__main__", "<run_path>"):  # mkdocs-gen-files runs it with runpy.run_path;
    main()  # a test imports it under another name to read the pages alone
