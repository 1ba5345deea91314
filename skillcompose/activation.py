"""The activation protocol: how a skill that takes many ticks is started, ticked and cancelled.

The bottom layer of the engine. A long-running skill is started once per activation and
returns an :class:`Activation`, whose ``tick()`` returns ``"running"`` (:data:`RUNNING`) until
it returns an outcome, and whose ``cancel()`` is its cancel hook. A :data:`Starter` is
``start(bb, rng, **params) -> Activation``; each kind of :class:`~skillcompose.skill.Skill`
gives its own through ``starter()``, so the engine never asks what kind a skill is.
"""
from __future__ import annotations

import copy
import threading
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import Any, Final, Protocol

import numpy as np

from .blackboard import DELETED, Access, Blackboard
from .errors import SkillProtocolError

__all__ = [
    "RUNNING",
    "Activation",
    "GeneratorActivation",
    "InstanceActivation",
    "Starter",
    "ThreadActivation",
    "driven",
    "start_generator",
    "start_instance",
]

RUNNING: Final = "running"
"""What ``tick()`` returns while a skill (or an FSA run) has not finished."""


class Activation(Protocol):
    """One activation of a long-running skill, bound to its blackboard and generator."""

    def tick(self) -> str:
        """Advance by one tick: :data:`RUNNING`, or the outcome when finished."""

    def cancel(self) -> None:
        """Stop early. Called at most once, and never after ``tick`` returned an outcome."""


Starter = Callable[..., Activation]
"""``start(bb, rng, **params) -> Activation``."""


@dataclass(slots=True, eq=False)
class InstanceActivation:
    """A start / tick / cancel object: ``tick(bb, rng)``, ``cancel(bb)`` (optional)."""

    obj: Any
    bb: Blackboard
    rng: np.random.Generator

    def tick(self) -> str:
        out: str = self.obj.tick(self.bb, self.rng)
        return out

    def cancel(self) -> None:
        hook = getattr(self.obj, "cancel", None)
        if hook is not None:
            hook(self.bb)


@dataclass(slots=True, eq=False)
class GeneratorActivation:
    """A generator skill: each tick resumes it; ``cancel`` closes it (runs its ``finally``)."""

    gen: Generator[Any, None, Any]
    name: str

    def tick(self) -> str:
        try:
            y = next(self.gen)
        except StopIteration as stop:
            if stop.value == RUNNING:
                raise SkillProtocolError(
                    f"skill {self.name} returned {RUNNING!r}; a generator skill yields "
                    f"{RUNNING!r} while it works and returns its outcome when done"
                ) from None
            out: str = stop.value
            return out
        if y is None or y == RUNNING:
            return RUNNING
        raise SkillProtocolError(
            f"skill {self.name} yielded {y!r}; a generator skill yields {RUNNING!r} (or "
            "nothing) while it works and returns its outcome: `return 'success'`"
        )

    def cancel(self) -> None:
        self.gen.close()


def start_instance(cls: type, bb: Blackboard, rng: np.random.Generator, **params: Any) -> Any:
    """Starter of a start / tick / cancel class: a fresh instance per activation."""
    obj = cls()
    obj.start(bb, rng, **params)
    return InstanceActivation(obj, bb, rng)


def start_generator(
    fn: Callable[..., Any], name: str, bb: Blackboard, rng: np.random.Generator, **params: Any
) -> Any:
    """Starter of a generator skill."""
    return GeneratorActivation(fn(bb, rng, **params), name)


def driven(start: Starter) -> Callable[..., str]:
    """Run-to-completion form of a long-running skill: start it and tick it until it ends."""

    def drive(bb: Blackboard, rng: np.random.Generator, **params: Any) -> str:
        act = start(bb, rng, **params)
        out = act.tick()
        while out == RUNNING:
            out = act.tick()
        return out

    drive.__qualname__ = drive.__name__ = f"driven_{getattr(start, '__name__', 'skill')}"
    return drive


class ThreadActivation:
    """An instant skill under a wall-clock limit, run in a worker thread on a private copy
    of its declared keys and of the generator, committed when it returns in time. A thread
    that overruns is abandoned (Python cannot kill it; it runs on, daemonised, against its
    copy, so the run's blackboard and generator stay consistent) and the skill's cancel
    hook, if any, is called once."""

    __slots__ = (
        "_done", "_exc", "_hook", "_out", "_rng_copy", "_staged", "_thread", "bb", "rng",
    )

    def __init__(
        self,
        fn: Callable[..., str],
        bb: Blackboard,
        rng: np.random.Generator,
        access: Access,
        hook: Callable[[Blackboard], Any] | None,
    ) -> None:
        self.bb = bb
        self.rng = rng
        self._hook = hook
        staged = Blackboard(types=bb.types)
        data = bb._data
        staged._data.update({k: copy.deepcopy(data[k]) for k in access.reads | access.writes
                             if k in data})
        staged._client = access
        staged.start_log()
        self._staged = staged
        self._rng_copy = copy.deepcopy(rng)
        self._out: Any = None
        self._exc: BaseException | None = None
        self._done = threading.Event()
        self._thread = threading.Thread(
            target=self._work, args=(fn,), name=f"skillcompose-{access.owner}", daemon=True
        )
        self._thread.start()

    def _work(self, fn: Callable[..., str]) -> None:
        try:
            self._out = fn(self._staged, self._rng_copy)
        except BaseException as exc:  # handed to the ticking thread
            self._exc = exc
        finally:
            self._done.set()

    def tick(self) -> str:
        if not self._done.is_set():
            return RUNNING
        if self._exc is not None:
            raise self._exc
        bb = self.bb
        for k, (_, new) in self._staged.take_log().items():
            if new is DELETED:
                if k in bb._data:
                    del bb[k]
            else:
                bb[k] = new
        self.rng.bit_generator.state = self._rng_copy.bit_generator.state
        out: str = self._out
        return out

    def cancel(self) -> None:
        if self._hook is not None:
            self._hook(self.bb)
