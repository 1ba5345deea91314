"""The blackboard: the memory all states of an FSA share during one run.

A :class:`Blackboard` is an ordinary instance: one per run, any number alive at once, no
global storage. While a skill runs, the executor sets the blackboard's *client* to that
skill's declared access, and every read or write of an undeclared key raises
:class:`~skillcompose.errors.BlackboardAccessError` naming the skill and the key. Code that is
not a skill (a task's world setup, a fitness function, a test) uses the blackboard without a
client and may touch any key.

Keys may be typed: ``Blackboard(types={"jug": np.ndarray})`` or by the skills' declarations
(``writes={"jug": np.ndarray}``). Writing a value of another type to a typed key raises.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from .errors import BlackboardAccessError, BlackboardKeyError, BlackboardTypeError

__all__ = ["DELETED", "Access", "Blackboard", "diff"]


class _Deleted:
    def __repr__(self) -> str:
        return "<deleted>"


DELETED: Any = _Deleted()
"""Marks, in a diff, a key that was deleted (or, as an old value, one that did not exist)."""


@dataclass(frozen=True)
class Access:
    """The keys one client (a skill) may read and write. Writing a key implies reading it."""

    owner: str
    reads: frozenset[str]
    writes: frozenset[str]

    def can_read(self, key: str) -> bool:
        return key in self.reads or key in self.writes


class Blackboard:
    """Key-value memory shared by the states of one FSA run."""

    __slots__ = ("_client", "_data", "_log", "_types")

    def __init__(
        self,
        initial: Mapping[str, Any] | None = None,
        *,
        types: Mapping[str, type | tuple[type, ...]] | None = None,
    ) -> None:
        self._data: dict[str, Any] = {}
        self._types: dict[str, type | tuple[type, ...]] = dict(types or {})
        self._client: Access | None = None
        self._log: list[tuple[str, Any, Any]] | None = None
        for k, v in (initial or {}).items():
            self[k] = v

    # -- mapping protocol with access checks --------------------------------------------
    def __getitem__(self, key: str) -> Any:
        c = self._client
        if c is not None and key not in c.reads and key not in c.writes:
            raise BlackboardAccessError(
                f"skill {c.owner} read blackboard key {key!r} without declaring it; "
                f"add {key!r} to reads=(...) in its @skill declaration "
                f"(declared reads: {sorted(c.reads)}, writes: {sorted(c.writes)})"
            )
        try:
            return self._data[key]
        except KeyError:
            who = f"skill {c.owner}" if c is not None else "the caller"
            raise BlackboardKeyError(
                f"{who} read blackboard key {key!r} before anything wrote it; "
                f"keys present: {sorted(self._data)}. Use bb.get({key!r}, default) "
                "for an optional key"
            ) from None

    def get(self, key: str, default: Any = None) -> Any:
        """Return ``bb[key]``, or ``default`` when nothing wrote the key yet."""
        c = self._client
        if c is not None and key not in c.reads and key not in c.writes:
            self[key]  # raises the access error
        return self._data.get(key, default)

    def __contains__(self, key: object) -> bool:
        c = self._client
        if c is not None and isinstance(key, str) and not c.can_read(key):
            self[key]  # raises the access error
        return key in self._data

    def __setitem__(self, key: str, value: Any) -> None:
        c = self._client
        if c is not None and key not in c.writes:
            raise BlackboardAccessError(
                f"skill {c.owner} wrote blackboard key {key!r} without declaring it; "
                f"add {key!r} to writes=(...) in its @skill declaration "
                f"(declared writes: {sorted(c.writes)})"
            )
        t = self._types.get(key)
        if t is not None and not isinstance(value, t):
            who = f"skill {c.owner}" if c is not None else "the caller"
            raise BlackboardTypeError(
                f"{who} wrote {type(value).__name__} to blackboard key {key!r}, "
                f"which is typed {_type_name(t)}"
            )
        log = self._log
        if log is not None:
            log.append((key, self._data.get(key, DELETED), value))
        self._data[key] = value

    def __delitem__(self, key: str) -> None:
        c = self._client
        if c is not None and key not in c.writes:
            raise BlackboardAccessError(
                f"skill {c.owner} deleted blackboard key {key!r} without declaring it "
                f"in writes=(...)"
            )
        old = self._data.pop(key)
        if self._log is not None:
            self._log.append((key, old, DELETED))

    def __iter__(self) -> Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def keys(self) -> list[str]:
        return list(self._data)

    def __repr__(self) -> str:
        return f"Blackboard({self._data!r})"

    # -- types -----------------------------------------------------------------------------
    def declare(self, key: str, type_: type | tuple[type, ...]) -> None:
        """Type ``key``: later writes must be instances of ``type_``."""
        old = self._types.get(key)
        if old is not None and old != type_:
            raise BlackboardTypeError(
                f"blackboard key {key!r} is typed {_type_name(old)} already; "
                f"cannot retype it as {_type_name(type_)}"
            )
        cur = self._data.get(key, DELETED)
        if cur is not DELETED and not isinstance(cur, type_):
            raise BlackboardTypeError(
                f"blackboard key {key!r} holds a {type(cur).__name__}, "
                f"not a {_type_name(type_)}"
            )
        self._types[key] = type_

    @property
    def types(self) -> Mapping[str, type | tuple[type, ...]]:
        return dict(self._types)

    # -- snapshots and diffs ---------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """A shallow copy of the contents (values are shared, not copied)."""
        return dict(self._data)

    def start_log(self) -> None:
        """Record every write from now on; :meth:`take_log` returns and clears the record."""
        self._log = []

    def take_log(self) -> dict[str, tuple[Any, Any]]:
        """The changes since :meth:`start_log` or the last call: ``{key: (old, new)}``."""
        log = self._log
        if not log:
            return {}
        self._log = []
        out: dict[str, tuple[Any, Any]] = {}
        for key, old, new in log:
            out[key] = (out[key][0] if key in out else old, new)
        return {k: v for k, v in out.items() if not _same(*v)}

    def stop_log(self) -> None:
        self._log = None


def diff(before: Mapping[str, Any], after: Mapping[str, Any]) -> dict[str, tuple[Any, Any]]:
    """``{key: (old, new)}`` for every key whose value differs between two snapshots."""
    changed = {k: (before.get(k, DELETED), v) for k, v in after.items()}
    gone = {k: (v, DELETED) for k, v in before.items() if k not in after}
    return {k: v for k, v in changed.items() if not _same(*v)} | gone


def _same(a: Any, b: Any) -> bool:
    if a is b:
        return True
    try:
        r = a == b
        if isinstance(r, bool):
            return r
        return bool(getattr(r, "all", lambda: False)())  # numpy arrays compare elementwise
    except Exception:  # values that cannot be compared are reported as changed
        return False


def _type_name(t: type | tuple[type, ...]) -> str:
    return " | ".join(x.__name__ for x in (t if isinstance(t, tuple) else (t,)))
