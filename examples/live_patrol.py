"""A robot on patrol, shown live in ``skillcompose view``: skills that take seconds.

A mobile robot drives to a waypoint, scans the room there, and goes on to the next
waypoint until it has made ``rounds`` rounds, then docks. Driving and scanning are
long-running skills (generators that yield ``"running"`` while time passes), so the FSA runs
tick-wise, and each tick is published to a live file the viewer's Live page watches::

    python examples/live_patrol.py --out live/          # in one terminal (any folder)
    skillcompose view live/                             # in another; open the Live page

``--time-scale 0.1`` makes every skill ten times faster (the test runs it that way).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Generator, Sequence
from pathlib import Path
from typing import Annotated, Literal

import numpy as np

from skillcompose import FSA, RUNNING, Blackboard, Param, Registry, State, compile_fsa, skill
from skillcompose.view.live import LivePublisher

SPEED_M_S = 0.5
WAYPOINTS_M = ((2.0, 0.0), (2.0, 2.0), (0.0, 2.0))


def _wait(bb: Blackboard, seconds: float) -> Generator[str, None, None]:
    end = time.monotonic() + seconds * float(bb["time_scale"])
    while time.monotonic() < end:
        yield "running"


@skill(reads=("position_m", "time_scale"), writes={"position_m": tuple, "waypoint": int})
def drive_to_next(
    bb: Blackboard, rng: np.random.Generator, *,
    speed: Annotated[float, Param(0.1, 1.0, unit="m/s")] = SPEED_M_S,
) -> Generator[str, None, Literal["arrived"]]:
    """Drive to the next waypoint at ``speed``: as long as the distance takes."""
    k = (int(bb.get("waypoint", -1)) + 1) % len(WAYPOINTS_M)
    start = np.asarray(bb["position_m"], dtype=float)
    goal = np.asarray(WAYPOINTS_M[k])
    seconds = float(np.linalg.norm(goal - start)) / speed
    steps = max(1, int(seconds / 0.25))
    for i in range(1, steps + 1):
        yield from _wait(bb, seconds / steps)
        p = start + (goal - start) * i / steps
        bb["position_m"] = (round(float(p[0]), 3), round(float(p[1]), 3))
    bb["waypoint"] = k
    return "arrived"


@skill(reads=("waypoint", "time_scale", "rounds_done"),
       writes={"scans": int, "rounds_done": int})
def scan_room(
    bb: Blackboard, rng: np.random.Generator, *,
    duration: Annotated[float, Param(0.5, 10.0, unit="s")] = 2.0,
    rounds: Annotated[int, Param(1, 10)] = 1,
) -> Generator[str, None, Literal["continue", "done"]]:
    """Turn on the spot for ``duration``; ``done`` after ``rounds`` rounds of waypoints."""
    yield from _wait(bb, duration)
    bb["scans"] = int(bb.get("scans", 0)) + 1
    if int(bb["waypoint"]) == len(WAYPOINTS_M) - 1:
        bb["rounds_done"] = int(bb.get("rounds_done", 0)) + 1
        if bb["rounds_done"] >= rounds:
            return "done"
    return "continue"


@skill(reads=("time_scale",), writes={"docked": bool})
def dock(bb: Blackboard, rng: np.random.Generator) -> Generator[str, None, Literal["success"]]:
    """Back into the charger: one second."""
    yield from _wait(bb, 1.0)
    bb["docked"] = True
    return "success"


def patrol_fsa(rounds: int = 1) -> FSA:
    return FSA({
        "Drive": State("DriveToNext", {"speed": SPEED_M_S}, {"arrived": "Scan"}),
        "Scan": State("ScanRoom", {"duration": 2.0, "rounds": rounds},
                      {"continue": "Drive", "done": "Dock"}),
        "Dock": State("Dock", {}, {"success": "success"}),
    }, "Drive", terminals=("success",), step_limit=100, name="live_patrol")


def run(out: Path, *, rounds: int = 1, time_scale: float = 1.0, period: float = 0.05) -> str:
    """Run the patrol once, publishing to ``out/live_patrol.live.json``; its outcome."""
    fsa = patrol_fsa(rounds)
    compiled = compile_fsa(fsa, Registry([drive_to_next, scan_room, dock]))
    bb = Blackboard()
    bb["position_m"] = (0.0, 0.0)
    bb["time_scale"] = time_scale
    live_run = compiled.start(bb, np.random.default_rng(0), trace=True)
    with LivePublisher(out / "live_patrol.live.json", fsa, interval=0.25) as live:
        while live_run.tick() == RUNNING:
            live.publish(live_run, bb)
            time.sleep(period * time_scale)
        live.publish(live_run, bb)
    return live_run.result.outcome


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python examples/live_patrol.py", description=__doc__
                                .split("\n")[0])
    p.add_argument("--out", type=Path, default=Path("live"), help="folder of the live file")
    p.add_argument("--rounds", type=int, default=1, choices=range(1, 11), metavar="1..10",
                   help="rounds of the waypoints before docking (default 1)")
    p.add_argument("--time-scale", type=float, default=1.0,
                   help="multiply every skill's duration by this (default 1)")
    args = p.parse_args(argv)
    if not 0.0 < args.time_scale <= 100.0:
        p.error(f"--time-scale {args.time_scale}: give a number in (0, 100]")
    try:
        outcome = run(args.out, rounds=args.rounds, time_scale=args.time_scale)
    except KeyboardInterrupt:
        print("interrupted")
        return 130
    print(f"patrol ended: {outcome}; live file {args.out / 'live_patrol.live.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
