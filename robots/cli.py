"""``skillcompose robot ...`` sub-commands (the main CLI hooks these in).

    skillcompose robot show --config tucked --out robot.png
    skillcompose robot show --config pose.json --out robot.png

A configuration is ``neutral``, ``tucked`` or a JSON file::

    {"base_xy_yaw": [0.0, 0.0, 0.0], "torso_height_m": 0.1,
     "arm_rad": {"left": [7 angles], "right": [7 angles]},
     "boxes": [{"center_m": [0.8, 0, 0.35], "half_extents_m": [0.3, 0.5, 0.35],
                "yaw_rad": 0.0, "name": "table"}]}
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from skillcompose.arguments import add_output_options, note
from skillcompose.errors import one_line
from skillcompose.robots.errors import InvalidConfiguration, RobotModelError

if TYPE_CHECKING:
    from skillcompose.robots.collision import Scene
    from skillcompose.robots.model import RobotModel, RobotPose

# Pinocchio (skillcompose.robots.model, skillcompose.robots.collision) is imported when a robot
# command runs, not when
# `skillcompose --help` registers the command.

_POSE_KEYS = {"base_xy_yaw", "torso_height_m", "arm_rad", "boxes"}
_BOX_KEYS = {"center_m", "half_extents_m", "yaw_rad", "name"}


def add_robot_cli(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``robot`` command to an argparse ``subparsers`` object."""
    robot = subparsers.add_parser("robot", help="PR2 model: render configurations")
    sub = robot.add_subparsers(dest="robot_command", required=True)
    show = sub.add_parser("show", help="render a configuration to a PNG")
    show.add_argument("--config", default="tucked", help="neutral, tucked or a JSON file")
    show.add_argument("--out", type=Path, default=Path("robot.png"), help="PNG to write")
    show.set_defaults(func=run_robot_cli)
    add_output_options(show)  # -q/-v after `robot show` too, as after every command
    return robot


def register_cli(subparsers: Any) -> None:
    """The hook ``skillcompose.cli`` calls to add ``skillcompose robot``."""
    add_robot_cli(subparsers)


def load_configuration(model: RobotModel, spec: str) -> tuple[RobotPose, Scene]:
    """A pose and scene from ``neutral``, ``tucked`` or a JSON file (see module doc)."""
    from skillcompose.robots.collision import Box, Scene
    from skillcompose.robots.model import RobotPose

    if spec == "neutral":
        return model.neutral_pose(), Scene()
    if spec == "tucked":
        return model.tucked_pose(), Scene()
    path = Path(spec)
    if not path.is_file():
        raise InvalidConfiguration(
            f"--config {spec!r}: not 'neutral', 'tucked' or an existing file"
        )
    try:
        raw = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise InvalidConfiguration(f"{path}:{exc.lineno}: invalid JSON: {exc.msg}") from exc
    if not isinstance(raw, dict) or not set(raw) <= _POSE_KEYS:
        keys = sorted(raw) if isinstance(raw, dict) else type(raw).__name__
        raise InvalidConfiguration(f"{path}: keys {keys}; valid keys: {sorted(_POSE_KEYS)}")
    tucked = model.tucked_pose()
    arms = dict(tucked.arm_rad)
    for arm, angles in raw.get("arm_rad", {}).items():
        if arm not in arms:
            raise InvalidConfiguration(f"{path}: arm_rad key {arm!r}; valid: left, right")
        arms[arm] = tuple(float(a) for a in angles)
    base = tuple(float(v) for v in raw.get("base_xy_yaw", (0.0, 0.0, 0.0)))
    if len(base) != 3:
        raise InvalidConfiguration(f"{path}: base_xy_yaw needs 3 values, got {len(base)}")
    pose = RobotPose((base[0], base[1], base[2]), float(raw.get("torso_height_m", 0.0)), arms)
    pose.values_by_coordinate()  # validates the arm lengths
    boxes = []
    for i, entry in enumerate(raw.get("boxes", [])):
        if not isinstance(entry, dict) or not set(entry) <= _BOX_KEYS:
            raise InvalidConfiguration(
                f"{path}: boxes[{i}] keys must be within {sorted(_BOX_KEYS)}"
            )
        boxes.append(
            Box(
                tuple(entry["center_m"]),
                tuple(entry["half_extents_m"]),
                float(entry.get("yaw_rad", 0.0)),
                str(entry.get("name", f"box{i}")),
            )
        )
    return pose, Scene(tuple(boxes))


def run_robot_cli(args: argparse.Namespace) -> int:
    """Run a ``robot`` sub-command; returns the exit code (errors printed, code 2)."""
    from skillcompose.robots.model import load_pr2
    from skillcompose.robots.render import render_configuration

    try:
        model = load_pr2()
        if args.robot_command == "show":
            pose, scene = load_configuration(model, args.config)
            out = render_configuration(model, pose, args.out, scene=scene)
            note(args, f"wrote {out}")  # a note on standard error, as every command's
            return 0
    except RobotModelError as exc:
        print(f"skillcompose robot {args.robot_command}: error: {one_line(str(exc))}",
              file=sys.stderr)
        return 2
    print(f"skillcompose robot: error: unknown robot command {args.robot_command!r}; "
          "choose show", file=sys.stderr)
    return 2
