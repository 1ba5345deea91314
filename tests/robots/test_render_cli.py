from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from skillcompose.robots.cli import add_robot_cli, run_robot_cli

pytestmark = pytest.mark.kinematics


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_robot_cli(parser.add_subparsers(dest="command"))
    return parser.parse_args(argv)


def test_show_writes_a_png(tmp_path: Path) -> None:
    config = tmp_path / "pose.json"
    config.write_text(
        json.dumps(
            {
                "torso_height_m": 0.2,
                "arm_rad": {"left": [0.3, 0.2, 0.0, -1.2, 0.0, -0.8, 0.0]},
                "boxes": [{"center_m": [0.95, 0, 0.36], "half_extents_m": [0.3, 0.6, 0.36]}],
            }
        )
    )
    out = tmp_path / "robot.png"
    assert run_robot_cli(_parse(["robot", "show", "--config", str(config), "--out", str(out)])) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bad_config_key_is_an_error_naming_the_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "bad.json"
    config.write_text(json.dumps({"torso": 0.1}))
    args = _parse(["robot", "show", "--config", str(config), "--out", str(tmp_path / "x.png")])
    assert run_robot_cli(args) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("skillcompose robot show: error: ")
    assert "torso_height_m" in err[0]


@pytest.mark.parametrize("flag", ["-q", "-v", "--quiet", "--verbose"])
def test_output_options_are_taken_after_robot_show(flag: str, tmp_path: Path) -> None:
    from skillcompose.cli import main

    out = tmp_path / "robot.png"
    assert main(["robot", "show", flag, "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
