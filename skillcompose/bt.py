"""The py_trees bridge: FSAs and skills inside behaviour trees, trees inside FSAs.

- :class:`FSABehaviour` runs an FSA tick-wise inside a tree: ``RUNNING`` while the FSA runs,
  then ``SUCCESS`` / ``FAILURE`` by a mapping of the FSA's outcomes (``status_map``, default
  ``success`` → ``SUCCESS``, anything else → ``FAILURE``). When the tree interrupts it
  (``terminate(INVALID)``), the FSA is preempted: the running skill's cancel hook runs once.
- :class:`SkillBehaviour` does the same for one skill with bound parameters.
- :func:`tree_skill` makes a py_trees subtree a skill of an FSA, with outcomes ``success`` /
  ``failure`` from the tree's final status; the FSA ticks it like any long-running skill and
  cancelling it stops the tree.
- :class:`BlackboardBridge` maps an FSA's declared keys to py_trees blackboard keys in a
  namespace per FSA (``/pick/object`` for key ``object`` of FSA ``pick``; ``key_map``
  overrides single keys). Declared access holds both ways: the FSA sees from the tree only
  the keys it reads or writes, and the tree sees from the FSA only the keys it writes; a
  tree skill sees its declared reads and writes and returns only its writes.

py_trees keeps its blackboard in class attributes (one per process). The bridge touches it
only when a tree is involved; without one, a skillcompose :class:`Blackboard` stays a plain
instance.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import py_trees
from py_trees.common import Access as TreeAccess
from py_trees.common import Status

from .activation import RUNNING, Starter
from .blackboard import DELETED, Blackboard
from .errors import SkillcomposeError, SkillProtocolError
from .executor import CompiledFSA, FSARun, RunResult, compile_fsa
from .fsa import FSA, RESERVED_OUTCOMES, State
from .registry import Registry
from .skill import Skill, SkillSpec

__all__ = [
    "BlackboardBridge",
    "BridgeError",
    "FSABehaviour",
    "SkillBehaviour",
    "TreeSkill",
    "tree_skill",
]


class BridgeError(SkillcomposeError, ValueError):
    """A behaviour-tree bridge is configured wrongly (namespace, key map, status map)."""


# -- blackboard bridge ---------------------------------------------------------------------
class BlackboardBridge:
    """Copies declared keys between a skillcompose :class:`Blackboard` and py_trees'.

    ``to_tree`` keys are written to the tree (py_trees WRITE access), ``from_tree`` keys are
    read from it (READ, or WRITE when also in ``to_tree``). Key ``k`` lives at
    ``{namespace}/{k}`` unless ``key_map`` names another absolute py_trees key for it.
    """

    def __init__(
        self,
        owner: str,
        *,
        to_tree: Iterable[str] = (),
        from_tree: Iterable[str] = (),
        namespace: str,
        key_map: Mapping[str, str] | None = None,
    ) -> None:
        self.owner = owner
        self.namespace = _namespace(namespace, owner)
        self.to_tree = tuple(sorted(set(to_tree)))
        self.from_tree = tuple(sorted(set(from_tree)))
        key_map = dict(key_map or {})
        keys = set(self.to_tree) | set(self.from_tree)
        unknown = sorted(set(key_map) - keys)
        if unknown:
            raise BridgeError(
                f"{owner}: key_map names keys {unknown} that it neither reads nor writes; "
                f"its keys are {sorted(keys)}"
            )
        self.names: dict[str, str] = {}
        for k in sorted(keys):
            name = key_map.get(k) or f"{self.namespace}/{k}"
            if not name.startswith("/") or "." in name or any(c.isspace() for c in name):
                raise BridgeError(
                    f"{owner}: blackboard key {k!r} maps to py_trees key {name!r}, which is "
                    "not an absolute key without dots or spaces (py_trees reads dots as "
                    f"attributes); map it explicitly: key_map={{{k!r}: '/ns/{k}_name'}}"
                )
            self.names[k] = name
        self.client = py_trees.blackboard.Client(name=f"skillcompose:{owner}")
        for k, name in self.names.items():
            access = TreeAccess.WRITE if k in self.to_tree else TreeAccess.READ
            self.client.register_key(key=name, access=access)

    def pull(self, bb: Blackboard) -> None:
        """Tree → ``bb`` for the ``from_tree`` keys the tree holds (typed keys stay checked)."""
        client = self.client
        data = bb._data
        for k in self.from_tree:
            name = self.names[k]
            if client.exists(name):
                v = client.get(name)
                if data.get(k, DELETED) is not v:
                    bb[k] = v

    def push(self, bb: Blackboard) -> None:
        """``bb`` → tree for the ``to_tree`` keys; a key deleted in ``bb`` is unset."""
        client = self.client
        data = bb._data
        for k in self.to_tree:
            name = self.names[k]
            v = data.get(k, DELETED)
            exists = client.exists(name)
            if v is DELETED:
                if exists and k in self.from_tree:
                    client.unset(name)
            elif not exists or client.get(name) is not v:
                client.set(name, v)

    def close(self) -> None:
        """Unregister the py_trees client (its keys' values stay on py_trees' blackboard)."""
        self.client.unregister(clear=False)

    def __repr__(self) -> str:
        return f"<BlackboardBridge {self.owner} {self.names}>"


def _namespace(ns: str, owner: str) -> str:
    ns = ns.rstrip("/")
    if not ns.startswith("/"):
        ns = "/" + ns
    if len(ns) < 2 or "." in ns or any(c.isspace() for c in ns):
        raise BridgeError(
            f"{owner}: namespace {ns!r} must be a py_trees namespace like '/pick' "
            "(no dots or spaces)"
        )
    return ns


# -- FSA and skill as behaviours -----------------------------------------------------------
_STATUS = {"SUCCESS": Status.SUCCESS, "FAILURE": Status.FAILURE}


class FSABehaviour(py_trees.behaviour.Behaviour):
    """Runs an FSA inside a behaviour tree, one FSA tick per tree tick.

    Args:
        fsa: a compiled FSA, or an FSA with its ``registry`` (and ``backend``).
        name: the behaviour's name (default: the FSA's name).
        namespace: py_trees namespace of the FSA's keys (default ``/<name>``).
        key_map: FSA key → absolute py_trees key, for keys shared under another name.
        status_map: FSA outcome → ``Status.SUCCESS`` / ``Status.FAILURE`` (or the strings
            ``"SUCCESS"`` / ``"FAILURE"``); unmapped outcomes give ``FAILURE``. The default
            maps ``success`` to ``SUCCESS``.
        seed: activation ``k`` of this behaviour runs with the ``k``-th child of ``seed``.
        blackboard: the FSA's own blackboard (default: a new one); kept across activations.
        time_limits: state → wall-clock limit [s] (:mod:`skillcompose.executor`).
        show_states: list the FSA's states as display-only children, so py_trees' renderings
            (``py_trees.display.ascii_tree``) show the FSA inside the tree. They are never
            ticked; the running state shows ``RUNNING``.

    ``last_result`` holds the :class:`RunResult` of the latest activation (preempted runs
    included).
    """

    def __init__(
        self,
        fsa: CompiledFSA | FSA,
        registry: Registry | None = None,
        *,
        name: str | None = None,
        namespace: str | None = None,
        key_map: Mapping[str, str] | None = None,
        status_map: Mapping[str, Status | str] | None = None,
        seed: int | np.random.SeedSequence | None = None,
        blackboard: Blackboard | None = None,
        time_limits: Mapping[str, float] | None = None,
        backend: str | None = None,
        show_states: bool = True,
    ) -> None:
        if isinstance(fsa, CompiledFSA):
            compiled = fsa
        else:
            if registry is None:
                raise BridgeError(
                    "FSABehaviour(fsa, registry) needs the registry to compile the FSA, "
                    "or pass a CompiledFSA"
                )
            compiled = compile_fsa(fsa, registry, backend)
        label = name or compiled.fsa.name or "FSA"
        super().__init__(label)
        self.compiled = compiled
        self.fsa_blackboard = blackboard if blackboard is not None else Blackboard()
        self.status_map = _status_map(status_map, compiled, label)
        self.time_limits = dict(time_limits or {})
        self._seeds = (
            seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        )
        reads = frozenset().union(*(impl.spec.reads for impl, _ in compiled.impls))
        writes = frozenset().union(*(impl.spec.writes for impl, _ in compiled.impls))
        ident = compiled.fsa.name or label.replace(" ", "_")
        self.bridge = BlackboardBridge(
            f"FSA {label}", to_tree=writes, from_tree=reads | writes,
            namespace=namespace or f"/{ident}", key_map=key_map,
        )
        self.fsa_run: FSARun | None = None
        self.last_result: RunResult | None = None
        self.activations = 0
        states = compiled.fsa.states
        self._views = {s: _StateView(s, states[s]) for s in compiled.names} if show_states else {}
        for view in self._views.values():
            view.parent = self
            self.children.append(view)

    def initialise(self) -> None:
        rng = np.random.default_rng(self._seeds.spawn(1)[0])
        self.activations += 1
        self.fsa_run = self.compiled.start(
            self.fsa_blackboard, rng, time_limits=self.time_limits
        )
        self.last_result = None
        self._show(None)

    def update(self) -> Status:
        run = self.fsa_run
        if run is None:  # py_trees always initialises first; guard direct calls
            raise SkillProtocolError(f"{self.name}: update() before initialise()")
        self.bridge.pull(self.fsa_blackboard)
        out = run.tick()
        self.bridge.push(self.fsa_blackboard)
        if out == RUNNING:
            self.feedback_message = f"state {run.state} (step {run.steps + 1})"
            self._show(run.state)
            return Status.RUNNING
        self.last_result = run.result
        self.feedback_message = f"{out} after {run.steps} steps in {run.ticks} ticks"
        self._show(None, run.state)
        return self.status_map.get(out, Status.FAILURE)

    def terminate(self, new_status: Status) -> None:
        run = self.fsa_run
        if new_status == Status.INVALID and run is not None and not run.done:
            state = run.state
            self.last_result = run.preempt()
            self.bridge.push(self.fsa_blackboard)
            self.feedback_message = f"preempted in state {state}"
            self._show(None)

    def shutdown(self) -> None:
        self.bridge.close()

    def _show(self, running: str | None, last: str | None = None) -> None:
        for sname, view in self._views.items():
            view.feedback_message = ""
            if sname == running:
                view.status = Status.RUNNING
            elif sname == last and self.last_result is not None:
                view.status = self.status_map.get(self.last_result.outcome, Status.FAILURE)
                view.feedback_message = f"ended: {self.last_result.outcome}"
            else:
                view.status = Status.INVALID


class _StateView(py_trees.behaviour.Behaviour):
    """Display-only child of :class:`FSABehaviour`: one FSA state, never ticked."""

    def __init__(self, name: str, state: State) -> None:
        params = ", ".join(f"{k}={v}" for k, v in state.params.items())
        routes = ", ".join(f"{o}→{t}" for o, t in state.transitions.items())
        super().__init__(f"{name}: {state.skill}({params}) [{routes}]")

    def update(self) -> Status:
        raise SkillProtocolError(
            f"{self.name} is a display-only view of an FSA state; it is never ticked"
        )


def _status_map(
    given: Mapping[str, Status | str] | None, compiled: CompiledFSA, owner: str
) -> dict[str, Status]:
    if given is None:
        return {"success": Status.SUCCESS}
    out: dict[str, Status] = {}
    valid = [*compiled.terminals, *RESERVED_OUTCOMES]
    for outcome, status in given.items():
        if outcome not in valid:
            raise BridgeError(
                f"{owner}: status_map names outcome {outcome!r}, which the FSA never ends "
                f"with; its outcomes are {valid}"
            )
        st = _STATUS.get(status.upper()) if isinstance(status, str) else status
        if st not in (Status.SUCCESS, Status.FAILURE):
            raise BridgeError(
                f"{owner}: status_map[{outcome!r}] is {status!r}; use Status.SUCCESS or "
                "Status.FAILURE (or 'SUCCESS' / 'FAILURE')"
            )
        out[outcome] = st
    return out


class SkillBehaviour(FSABehaviour):
    """One skill, parameters bound, as a behaviour (a one-state FSA under the hood).

    ``SkillBehaviour(grasp, params={"force": 20.0})`` or ``SkillBehaviour("Grasp",
    registry, ...)``. Each outcome of the skill ends the run with that outcome; the
    ``status_map`` and blackboard bridge work as in :class:`FSABehaviour`.
    """

    def __init__(
        self,
        skill: Skill | str,
        registry: Registry | None = None,
        *,
        params: Mapping[str, Any] | None = None,
        name: str | None = None,
        namespace: str | None = None,
        key_map: Mapping[str, str] | None = None,
        status_map: Mapping[str, Status | str] | None = None,
        seed: int | np.random.SeedSequence | None = None,
        blackboard: Blackboard | None = None,
        time_limit: float | None = None,
        backend: str | None = None,
    ) -> None:
        if isinstance(skill, Skill):
            reg = registry if registry is not None else Registry([skill])
            sname = skill.name
        else:
            if registry is None:
                raise BridgeError(f"SkillBehaviour({skill!r}) needs the registry to find it")
            reg, sname = registry, skill
        spec = reg.spec(sname)
        reserved = [o for o in spec.outcomes if o in RESERVED_OUTCOMES]
        if reserved:
            raise BridgeError(
                f"skill {sname}: outcomes {reserved} are reserved for runs, so it cannot "
                "be a SkillBehaviour on its own; put it in an FSA and use FSABehaviour"
            )
        fsa = FSA(
            {sname: State(sname, dict(params or {}), {o: o for o in spec.outcomes})},
            sname, terminals=spec.outcomes, step_limit=1, name=sname,
        )
        super().__init__(
            fsa, reg, name=name or sname, namespace=namespace, key_map=key_map,
            status_map=status_map, seed=seed, blackboard=blackboard, backend=backend,
            time_limits={sname: time_limit} if time_limit is not None else None,
            show_states=False,
        )


# -- tree as a skill -----------------------------------------------------------------------
TreeSource = py_trees.behaviour.Behaviour | Callable[[], py_trees.behaviour.Behaviour]


class TreeSkill(Skill):
    """A py_trees subtree as a skill: ``success`` / ``failure`` from its final status."""

    __slots__ = ("_set_up", "bridge")
    long_running = True

    def __init__(
        self, spec: SkillSpec, source: TreeSource, bridge: BlackboardBridge
    ) -> None:
        super().__init__(spec, source, backend="default")
        self.bridge = bridge
        self._set_up = False  # (a single tree, set up once)

    def starter(self, backend: str | None = None) -> Starter | None:
        return self._start

    def _start(self, bb: Blackboard, rng: np.random.Generator) -> _TreeActivation:
        single = isinstance(self.impl, py_trees.behaviour.Behaviour)  # else a factory
        root = self.impl if single else self.impl()
        if not isinstance(root, py_trees.behaviour.Behaviour):
            raise SkillProtocolError(
                f"skill {self.name}: its tree factory returned {root!r}, not a py_trees "
                "behaviour"
            )
        if root.status == Status.RUNNING:
            raise SkillProtocolError(
                f"skill {self.name}: its tree is running in another activation already; "
                "register a factory (a function building the tree) instead of one tree"
            )
        if not (single and self._set_up):
            root.setup_with_descendants()
            self._set_up = single
        return _TreeActivation(self, root, bb)


_OUTCOMES = {Status.RUNNING: RUNNING, Status.SUCCESS: "success", Status.FAILURE: "failure"}


@dataclass(slots=True, eq=False)
class _TreeActivation:
    skill: TreeSkill
    root: py_trees.behaviour.Behaviour
    bb: Blackboard

    def tick(self) -> str:
        bridge = self.skill.bridge
        bridge.push(self.bb)
        self.root.tick_once()
        bridge.pull(self.bb)
        st = self.root.status
        if st in _OUTCOMES:
            return _OUTCOMES[st]
        raise SkillProtocolError(
            f"skill {self.skill.name}: tree {self.root.name} ended with status {st}; a tree "
            "skill must end with SUCCESS or FAILURE"
        )

    def cancel(self) -> None:
        self.root.stop(Status.INVALID)
        self.skill.bridge.pull(self.bb)


def tree_skill(
    tree: TreeSource,
    *,
    name: str,
    reads: Iterable[str] = (),
    writes: Iterable[str] = (),
    namespace: str | None = None,
    key_map: Mapping[str, str] | None = None,
) -> TreeSkill:
    """Make a py_trees subtree (or a function building one) a skill named ``name``.

    Before each tick the skill's ``reads`` and ``writes`` are copied from the FSA's
    blackboard to ``{namespace}/{key}`` (default namespace ``/<name>``), and after it its
    ``writes`` are copied back. Register it with ``registry.add(tree_skill(...))``. Give a
    factory when the same tree skill may run twice at once (two FSAs, nested use).
    """
    if not isinstance(name, str) or not name.isidentifier():
        raise BridgeError(f"tree_skill: name {name!r} must be an identifier")
    if isinstance(reads, str) or isinstance(writes, str):
        raise BridgeError(f"tree_skill {name}: reads / writes take a tuple of keys, not a str")
    r, w = frozenset(reads), frozenset(writes)
    spec = SkillSpec(
        name=name, outcomes=("success", "failure"), reads=r, writes=w,
        doc=f"py_trees subtree {getattr(tree, 'name', getattr(tree, '__name__', ''))}",
    )
    bridge = BlackboardBridge(
        f"tree skill {name}", to_tree=r | w, from_tree=w,
        namespace=namespace or f"/{name}", key_map=key_map,
    )
    return TreeSkill(spec, tree, bridge)
