"""The one table of evolution settings: the config's checks, the command line's options and
the presets page all come from it, so they agree (bounds included) by construction."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import importlib.util
import io
import math
from pathlib import Path
from typing import Any

import pytest

from skillcompose.evolve.cli import _given_settings, build_parser
from skillcompose.evolve.config import PRESET_NAMES, PRESETS, EvolutionConfig
from skillcompose.evolve.errors import EvolutionConfigError
from skillcompose.evolve.settings import FLAGGED, MOST, SETTINGS, Kind, Setting

ROOT = Path(__file__).resolve().parents[2]
BY_NAME = {s.name: s for s in SETTINGS}


def test_every_field_is_in_the_table_once_and_the_table_has_nothing_else() -> None:
    names = [s.name for s in SETTINGS]
    assert len(names) == len(set(names)), "a setting is in the table twice"
    assert set(names) == {f.name for f in dataclasses.fields(EvolutionConfig)}
    assert {s.kind for s in SETTINGS} == set(Kind)


def test_flags_are_unique_options_and_only_the_flagged_settings_have_one() -> None:
    flags = [s.flag for s in FLAGGED]
    assert len(flags) == len(set(flags))
    assert all(f.startswith("--") for f in flags)
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    options = sub.choices["evolve"]._option_string_actions
    for s in SETTINGS:
        if s.flag:
            assert options[s.flag].dest == s.name
        else:
            assert "--" + s.name.replace("_", "-") not in options


def test_every_setting_named_in_a_text_is_one() -> None:
    for s in SETTINGS:
        for text in (s.text(lambda r: r.name, more=True), s.option_help(None)):
            assert "{" not in text and "}" not in text, (s.name, text)
            assert "``" not in text  # --help and the page are plain text and markdown


# -- the command line takes exactly what the config takes --------------------------------------
def _cli(flag: str, text: str) -> argparse.Namespace | None:
    """The parsed arguments of ``evolve TASK flag text``, or None when the parser refuses."""
    with contextlib.redirect_stderr(io.StringIO()):
        try:
            return build_parser().parse_args(["evolve", "examples.toy_task", flag, text])
        except SystemExit:
            return None


def _config_takes(name: str, value: Any) -> bool:
    """Whether the config's check of ``name`` takes ``value`` (the checks between settings,
    such as elitism below population, are not this setting's bound)."""
    try:
        EvolutionConfig(**{name: value})
    except EvolutionConfigError as exc:
        return f"{name} = {value!r}:" not in str(exc)
    return True


def _edges(s: Setting) -> list[Any]:
    """The bounds of ``s`` and the values just past them."""
    if s.kind is Kind.WHOLE:
        return [int(s.low) - 1, int(s.low), int(s.high), int(s.high) + 1]
    low, high, _, _ = s.bounds()
    values = [math.nextafter(low, -math.inf), low, math.nextafter(low, math.inf)]
    if math.isinf(high):
        return [*values, 1e308, math.inf, math.nan]
    return [*values, math.nextafter(high, -math.inf), high, math.nextafter(high, math.inf)]


@pytest.mark.parametrize("s", [s for s in FLAGGED if s.kind not in (Kind.SWITCH, Kind.CHOICE)],
                         ids=lambda s: s.name)
def test_an_option_takes_what_its_setting_takes_at_its_bounds(s: Setting) -> None:
    for value in _edges(s):
        args = _cli(s.flag, repr(value) if isinstance(value, float) else str(value))
        if args is None:
            assert not _config_takes(s.name, value), (s.flag, value)
            continue
        given = _given_settings(args)[s.name]
        assert _config_takes(s.name, given), (s.flag, value)
        if given is None:  # --eval-time-limit 0: no limit
            assert s.flag_zero_is_none and value == 0
        else:
            assert given == value and _config_takes(s.name, value)


def test_the_bounds_that_drifted_once_are_one() -> None:
    assert _cli("--generations", str(MOST)) is not None
    assert _cli("--generations", str(MOST + 1)) is None
    assert not _config_takes("generations", MOST + 1)
    assert _cli("--success-rate", "1") is None  # the config's open (0, 1), not [0, 1]
    args = _cli("--param-sigma", "2")  # the config's [0, inf), not [0, 1]
    assert args is not None and _given_settings(args)["param_sigma"] == 2.0


def test_choices_and_switches_come_from_the_table() -> None:
    for choice in BY_NAME["topology"].choices:
        args = _cli("--topology", choice)
        assert args is not None and _given_settings(args)["topology"] == choice
    assert _cli("--topology", "star") is None and not _config_takes("topology", "star")
    plain = build_parser().parse_args(["evolve", "examples.toy_task"])
    assert _given_settings(plain) == {}
    switches = [s for s in FLAGGED if s.kind is Kind.SWITCH]
    args = build_parser().parse_args(["evolve", "examples.toy_task",
                                      *(s.flag for s in switches)])
    assert _given_settings(args) == {s.name: True for s in switches}


def test_an_option_refuses_in_the_words_of_the_config(
        capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        build_parser().parse_args(["evolve", "x", "--eval-time-limit", "-1"])
    assert "--eval-time-limit: must be seconds > 0, or 0 for no limit, got '-1'" in \
        capsys.readouterr().err
    with pytest.raises(SystemExit):
        build_parser().parse_args(["evolve", "x", "--worker-max-growth-mb", "nan"])
    assert "must be MB >= 0 (0: no limit), got 'nan'" in capsys.readouterr().err


# -- each kind's check, and its message ------------------------------------------------------
@pytest.mark.parametrize(("name", "value", "message"), [
    ("population", 1, "population = 1: expected a whole number from 2 to 1,000,000"),
    ("population", True, "population = True: expected a whole number from 2"),
    ("population", 30.0, "population = 30.0: expected a whole number"),
    ("generations", MOST + 1, f"expected a whole number from 0 to {MOST:,}"),
    ("max_episodes", 0, f"max_episodes = 0: expected a whole number from 1 to {MOST:,}, "
     "or None for no budget"),
    ("restart_after", -1, "restart_after = -1: expected a whole number from 0 to "
     f"{MOST:,} (0: never)"),
    ("p_mut", 1.5, "p_mut = 1.5: expected a probability in [0, 1]"),
    ("p_mut", math.nan, "p_mut = nan: expected a probability"),
    ("p_cross", "0.1", "p_cross = '0.1': expected a probability"),
    ("success_rate", 1, "success_rate = 1: expected a rate between 0 and 1 (exclusive), or "
     "None for the task's"),
    ("success_rate", 0.0, "success_rate = 0.0: expected a rate"),
    ("param_sigma", math.inf, "param_sigma = inf: expected a finite number >= 0"),
    ("terminal_weight", -1.0, "terminal_weight = -1.0: expected a finite number >= 0"),
    ("eval_time_limit", 0, "eval_time_limit = 0: expected seconds > 0, or None for no limit"),
    ("worker_max_growth_mb", -1, "worker_max_growth_mb = -1: expected MB >= 0 (0: no limit)"),
    ("holds_confidence", 1.0, "holds_confidence = 1.0: expected a number from 0.5 to below 1"),
    ("holds_confidence", 0.4, "holds_confidence = 0.4: expected a number from 0.5"),
    ("cache", "no", "cache = 'no': expected true or false"),
    ("neutral", 1, "neutral = 1: expected true or false"),
    ("topology", "star", "topology = 'star': choose one of ring, complete"),
    ("topology", None, "topology = None: choose one of ring, complete"),
    ("trials", 0, "trials = 0: expected a whole number from 1 to 1,000,000, or None"),
])
def test_each_kind_refuses_what_it_should_naming_it(name: str, value: Any,
                                                     message: str) -> None:
    with pytest.raises(EvolutionConfigError, match="invalid evolution settings: ") as caught:
        EvolutionConfig(**{name: value})
    assert message in str(caught.value)


@pytest.mark.parametrize(("name", "value"), [
    ("max_episodes", None), ("trials", None), ("success_rate", None), ("success_rate", 0.5),
    ("eval_time_limit", None), ("worker_max_growth_mb", 0), ("holds_confidence", 0.5),
    ("p_mut", 0), ("p_mut", 1), ("param_sigma", 3.0), ("generations", 0),
])
def test_each_kind_takes_its_bounds_and_its_none(name: str, value: Any) -> None:
    assert getattr(EvolutionConfig(**{name: value}), name) == value


def test_every_setting_refuses_a_value_of_no_kind_and_every_problem_is_in_one_error() -> None:
    nothing = object()
    with pytest.raises(EvolutionConfigError) as caught:
        every: dict[str, Any] = dict.fromkeys(BY_NAME, nothing)
        EvolutionConfig(**every)
    message = str(caught.value)
    assert message.startswith("invalid evolution settings: ")
    assert message.count(f"{nothing!r}") == len(SETTINGS)
    for s in SETTINGS:
        assert s.problem(nothing) is not None and f"{s.name} = {nothing!r}: " in message
        assert s.problem(getattr(EvolutionConfig(), s.name)) is None


# -- the presets page --------------------------------------------------------------------------
def _presets_page() -> str:
    pytest.importorskip("mkdocs_gen_files")
    spec = importlib.util.spec_from_file_location(
        "reference_pages", ROOT / "docs" / "reference" / "generate.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # under its own name: it writes no pages
    return str(module.presets_page())


def test_the_presets_page_gives_every_setting_of_every_preset_its_meaning() -> None:
    page = _presets_page()
    assert set(PRESET_NAMES) - {"default"} == set(PRESETS)
    code = lambda s: f"`{s.name}`"  # noqa: E731 - the page's way of naming a setting
    for name, chosen in PRESETS.items():
        section = page.split(f"### `{name}`\n", 1)[1].split("\n### ", 1)[0]
        for key, value in chosen.items():
            s = BY_NAME[key]
            assert f"- `{key}` = {s.describe(value)} (default " in section, (name, key)
            assert s.text(code) in section
        listed = [line for line in section.splitlines() if line.startswith("- `")]
        assert len(listed) == len(chosen)
    for s in SETTINGS:
        assert f"| `{s.name}` | " in page.split("## Every setting", 1)[1]
        assert s.text(code, more=True) in page and s.takes() in page
