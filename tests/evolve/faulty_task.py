"""The toy task with one misbehaving skill, ``Fault``, chosen by the setting ``fault``:

- ``raise``: raises ``ValueError``;  ``exit``: calls ``sys.exit(0)``;
  ``interrupt``: raises ``KeyboardInterrupt`` (as if Ctrl-C, but from the skill);
- ``hang``: sleeps for an hour;  ``stuck``: the same with ``SIGALRM`` blocked, as code
  that never returns to the interpreter would be; ``stuck_checks``: the same, only in the
  process that runs a run's checks (:mod:`skillcompose.evolve.isolated`);
- ``leak``: keeps ``leak_mb`` MB more of memory on every call;
- ``crash``: ends its process at once (``os._exit``), as a segfault would (never run it
  in the test process);
- ``sigint``: sends this process a real ``SIGINT`` (a person's Ctrl-C);
- ``setup``: the task's world setup raises (every evaluation fails);
- ``crash_setup``: the world setup ends its process at once in a worker (every evaluation
  kills its worker), and raises in the process that loaded the task;
- ``crash_world``: the same, in the worlds whose setup draws below ``p_fault`` (with common
  random numbers, every evaluation of a generation shares that world's fate).

``p_fault`` is the probability (drawn from the run's generator, so the same in every run)
that a call misbehaves; otherwise ``Fault`` returns ``success``. For tests of how evolution
counts, bounds and reports faults.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from dataclasses import replace
from typing import Literal

import numpy as np

from examples import toy_task
from skillcompose import Blackboard, Registry, Skill, skill
from skillcompose.evolve.evaluation import Guard
from skillcompose.task import Task

FAULTS = ("raise", "exit", "interrupt", "hang", "stuck", "stuck_checks", "leak", "crash",
          "sigint", "setup", "crash_setup", "crash_world")
MAIN_PID = os.getpid()


def make_fault(kind: str, p_fault: float, leak_mb: float) -> Skill:
    kept: list[bytearray] = []

    @skill
    def fault(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
        """Misbehave with probability ``p_fault``."""
        if rng.random() >= p_fault:
            return "success"
        if kind == "raise":
            raise ValueError("the Fault skill broke")
        if kind == "exit":
            sys.exit(0)
        if kind == "interrupt":
            raise KeyboardInterrupt
        if kind == "hang":
            time.sleep(3600)
        if kind == "stuck" or (kind == "stuck_checks" and Guard.watch is not None):
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGALRM})
            time.sleep(3600)
        if kind == "leak":
            kept.append(bytearray(int(leak_mb * 2**20)))
            kept[-1][::4096] = b"x" * len(range(0, len(kept[-1]), 4096))  # touch every page
        if kind == "crash":
            os._exit(3)
        if kind == "sigint":
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1)
        return "failure"

    return fault


def make_task(
    fault: str = "raise", p_fault: float = 1.0, p_fail: float = 0.0, trials: int = 1,
    leak_mb: float = 20.0,
) -> Task:
    if fault not in FAULTS:
        raise ValueError(f"fault must be one of {FAULTS}, got {fault!r}")
    base = toy_task.make_task(p_fail=p_fail, trials=trials)
    registry = Registry()
    toy_task.register(registry)
    registry.add(make_fault(fault, p_fault, leak_mb))
    setup = base.setup
    if fault == "setup":
        def setup(rng: np.random.Generator) -> Blackboard:
            raise RuntimeError("the world could not be set up")
    if fault == "crash_setup":
        def setup(rng: np.random.Generator) -> Blackboard:
            if os.getpid() != MAIN_PID:
                os._exit(3)
            raise RuntimeError("crash_setup ran in the process that loaded the task")
    if fault == "crash_world":
        def setup(rng: np.random.Generator) -> Blackboard:
            if rng.random() < p_fault:
                if os.getpid() != MAIN_PID:
                    os._exit(3)
                raise RuntimeError("crash_world ran in the process that loaded the task")
            return base.setup(rng)

    return replace(base, registry=registry, setup=setup, name=f"faulty_{fault}",
                   settings={"fault": fault, "p_fault": p_fault, "p_fail": p_fail,
                             "trials": trials, "leak_mb": leak_mb})
