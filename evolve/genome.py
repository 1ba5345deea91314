"""The genome: an FSA as a directed multigraph over the task's skills (section 3.3).

Each node holds a skill, its parameters normalised to [0, 1] and exactly one outgoing edge per
outcome of its skill. An edge goes to a node or to one of the FSA's terminal outcomes
(``success`` / ``failure``), which ends a run the way the paper's terminating actions did.
Nodes carry stable integer ids, so an exported state is named like the paper's figures,
``MoveToObject_7``.

A genome is compiled for every evaluation, so :class:`GenomeCompiler` builds the runtime's
:class:`~skillcompose.CompiledFSA` straight from the genome with the skills' implementations
bound once; the run itself is the runtime's executor, not a second interpreter.
"""

from __future__ import annotations

import dataclasses
import re
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from skillcompose import FSA, CompiledFSA, ParamSpec, Skill, State
from skillcompose.errors import one_line
from skillcompose.fsa import RESERVED_OUTCOMES
from skillcompose.fsafile import MAX_STATES, MAX_VALUES
from skillcompose.params import param_problems
from skillcompose.task import Task

from .errors import SeedFSAError

__all__ = ["Genome", "GenomeCompiler", "Node", "SkillChoice", "SkillSet"]


@dataclass(frozen=True)
class SkillChoice:
    """One skill evolution may place: its name, outcomes and parameters."""

    name: str
    outcomes: tuple[str, ...]
    params: tuple[ParamSpec, ...]
    fixed: tuple[int | None, ...] = ()
    """Per outcome: the terminal code it always ends in (a terminating skill), or None."""
    then: SkillChoice | None = None
    """A pair (see :meth:`SkillSet.from_task`'s ``pairs``): this choice's skill (an action,
    whose parameters the node holds), then the decision ``then``, whose outcomes and fixed
    edges the node's are; the action's fixed outcomes end the run as its own would."""
    act: SkillChoice | None = None
    """A pair's action as a plain choice: its outcomes, one of which goes on to ``then``
    (the others are fixed: they end the run)."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "genes", sum(p.genes for p in self.params))
        object.__setattr__(self, "_scalar", all(p.size is None for p in self.params))

    genes: int = dataclasses.field(init=False, repr=False, compare=False)
    """How many numbers in [0, 1] a node of this skill holds (a vector counts its length)."""
    _scalar: bool = dataclasses.field(init=False, repr=False, compare=False)

    def fixed_edge(self, outcome_index: int) -> int | None:
        return self.fixed[outcome_index] if self.fixed else None

    def decode(self, genes: Sequence[float]) -> dict[str, Any]:
        """The parameters, in the skill's units, that a node's genes encode."""
        if self._scalar:
            return {p.name: p.from_unit(x) for p, x in zip(self.params, genes, strict=True)}
        out: dict[str, Any] = {}
        i = 0
        for p in self.params:
            out[p.name] = p.from_genes(genes[i : i + p.genes])
            i += p.genes
        return out

    def encode(self, values: Mapping[str, Any]) -> list[float]:
        """A node's genes for parameter ``values`` (checked values, in the skill's units)."""
        out: list[float] = []
        for p in self.params:
            out.extend(p.to_genes(values[p.name]))
        return out


_FILE_RESERVE = 1_000
"""Values of an exported FSA file kept for what is not its states (its header keys, its
``meta``: the run's settings and results)."""


class SkillSet:
    """The skills of a task that evolution may place, indexed, and the FSA's terminals."""

    def __init__(
        self, choices: Iterable[SkillChoice], terminals: tuple[str, ...] = ("success", "failure"),
        free_terminals: bool = True, pairs: bool = False, pairs_only: bool = False,
    ) -> None:
        base = tuple(choices)
        self.terminals = tuple(terminals)
        self.free_terminals = free_terminals
        self.pairs = pairs
        self.choices = base + (pair_choices(base) if pairs else ())
        # what a random node may be (:meth:`draw`): every choice, or with ``pairs_only`` all
        # but the actions a pair covers; the others stay choices, for seed files and names
        covered = {c.act.name for c in self.choices if c.act is not None} if pairs_only \
            else set()
        self.drawable = tuple(k for k, c in enumerate(self.choices)
                              if c.then is not None or c.name not in covered)
        self.index = {c.name: k for k, c in enumerate(self.choices) if c.then is None}
        # the draw's cumulative weights over drawable (None: uniform, see learn())
        self._cumulative: np.ndarray | None = None
        if not self.choices:
            raise SeedFSAError("the task lets evolution place no skills; list some in Task.skills")
        # the most nodes a genome may hold: what an FSA file holds and reads back (its
        # states, and its values: a state's name, skill, parameters (a vector counts its
        # items) and transitions, the rest of the file (its meta, the run's record) within
        # _FILE_RESERVE), so that every FSA evolution exports loads again; a pair's node is
        # two states
        per_node = max(_values(c) + (_values(c.then) if c.then is not None else 0)
                       for c in self.choices)
        states = MAX_STATES // (2 if len(self.choices) > len(base) else 1)
        self.max_nodes = max(1, min(states, (MAX_VALUES - _FILE_RESERVE) // per_node))

    @classmethod
    def from_task(cls, task: Task, terminals: tuple[str, ...] | None = None,
                  pairs: bool = False, pairs_only: bool = False) -> SkillSet:
        """The task's skills; ``terminals`` default to the task's own (``Task.terminals``).
        With ``pairs``, each action followed by each decision is one more choice
        (:func:`pair_choices`); with ``pairs_only`` as well, an action that a pair covers is
        no longer drawn alone (:meth:`draw`)."""
        terminals = tuple(task.terminals if terminals is None else terminals)
        bad = [t for t in terminals if not isinstance(t, str) or not t.isidentifier()
               or t in RESERVED_OUTCOMES]
        if not terminals or bad:
            raise SeedFSAError(
                f"task {task.name}: terminals {list(terminals)} must be one or more names "
                f"(identifiers) other than {list(RESERVED_OUTCOMES)}; e.g. "
                "terminals=('success', 'failure')"
            )
        choices = []
        enders = task.terminal_skills
        codes = {t: -(k + 1) for k, t in enumerate(terminals)}
        for name in task.skill_names():
            spec = task.registry.spec(name)
            fixed: tuple[int | None, ...] = ()
            if enders is not None and name in enders:
                fixed = tuple(codes.get(o) for o in spec.outcomes)
            choices.append(SkillChoice(spec.name, spec.outcomes, spec.params, fixed))
        if enders is not None:
            unknown = [n for n in enders if n not in task.skill_names()]
            if unknown:
                raise SeedFSAError(
                    f"task {task.name}: terminal_skills {unknown} are not among the skills "
                    f"evolution may place {list(task.skill_names())}"
                )
        return cls(choices, terminals, free_terminals=enders is None, pairs=pairs,
                   pairs_only=pairs_only)

    def __len__(self) -> int:
        return len(self.choices)

    def draw(self, rng: np.random.Generator) -> int:
        """A random node's skill: uniform over :attr:`drawable`, or as :meth:`learn` last
        weighted them (``skill_bias``; uniform again after it is given nothing to learn
        from). Uniform with every choice drawable, it is ``rng.integers(len(self))``, so
        the random stream is the one without ``pairs_only``. With ``pairs_only`` an action
        covered by a pair is not drawn: a pair whose decision's outcomes all lead to one
        state acts as the action alone (but for the decision's own step, none in the ant's
        sensing form), so the choices differ from a task whose actions report what they
        sense (Jefferson's ant) by the plain decisions alone."""
        if self._cumulative is None:
            k = int(rng.integers(len(self.drawable)))
        else:
            u = rng.random() * float(self._cumulative[-1])
            k = min(int(np.searchsorted(self._cumulative, u, side="right")),
                    len(self.drawable) - 1)
        return self.drawable[k]

    def learn(self, genomes: Iterable[Genome], share: float) -> None:
        """Draw the skills (:meth:`draw`) with ``share`` of the weight as often as
        ``genomes`` use them (each node counts once; a choice that is not drawable does
        not count) and the rest uniformly; ``share`` 0, or genomes using no drawable
        choice, gives the uniform draw back. Setting ``skill_bias``: the breeding calls it
        with an island's best before each island's children."""
        m = len(self.drawable)
        position = {k: i for i, k in enumerate(self.drawable)}
        counts = np.zeros(m)
        for g in genomes:
            for n in g.nodes.values():
                i = position.get(n.skill)
                if i is not None:
                    counts[i] += 1.0
        total = float(counts.sum())
        if share <= 0.0 or total == 0.0:
            self._cumulative = None
            return
        weights = (1.0 - share) / m + share * counts / total
        self._cumulative = np.cumsum(weights)

    @property
    def shape(self) -> tuple[tuple[str, ...], bool]:
        """What a worker passes to :meth:`from_task` besides the task to build the same
        skill set: ``(terminals, pairs)``."""
        return self.terminals, self.pairs

    def terminal_code(self, outcome: str) -> int:
        """The edge code of a terminal outcome: ``-(k + 1)`` for the ``k``-th terminal."""
        return -(self.terminals.index(outcome) + 1)


def _values(c: SkillChoice) -> int:
    """The values one state of ``c``'s skill takes in an FSA file (see ``max_nodes``)."""
    return 6 + 2 * len(c.outcomes) + sum(2 + (p.size or 0) for p in c.params)


def _going_on(c: SkillChoice) -> int:
    """How many of ``c``'s outcomes do not end the run."""
    return sum(c.fixed_edge(o) is None for o in range(len(c.outcomes)))


def is_action(c: SkillChoice) -> bool:
    """Whether ``c`` is an action in the sense of :func:`pair_choices`: a skill with exactly
    one outcome that does not end the run, so that what follows it cannot depend on it."""
    return c.then is None and _going_on(c) == 1


def is_decision(c: SkillChoice) -> bool:
    """Whether ``c`` is a decision in the sense of :func:`pair_choices`: a skill without
    parameters with two or more outcomes that do not end the run (a sensor's yes / no)."""
    return c.then is None and c.genes == 0 and _going_on(c) >= 2


def pair_choices(choices: Sequence[SkillChoice]) -> tuple[SkillChoice, ...]:
    """Each action of ``choices`` followed by each decision, as one choice ("act, then
    decide"): a task written with sensing skills apart from actions that only report
    ``done`` (Koza's ant) gets the building block that a task whose actions report what
    they sense (Jefferson's ant) has in every state, while the plain skills stay choices
    too. A pair's node is exported as two plain states, the action's then the decision's,
    so the file uses the task's own skills. None when the task has no actions or no
    decisions (every skill of a task whose actions report has two outcomes, so it gets no
    pairs)."""
    acts = [c for c in choices if is_action(c)]
    decisions = [c for c in choices if is_decision(c)]
    return tuple(
        SkillChoice(a.name, d.outcomes, a.params, d.fixed, then=d, act=a)
        for a in acts for d in decisions)


class Node:
    """One state of a genome: a skill index, parameters in [0, 1] and one edge per outcome.

    ``edges[k]`` is the target of the skill's ``k``-th outcome: a node id (>= 0) or a terminal
    outcome, coded ``-(t + 1)`` for the ``t``-th terminal.
    """

    __slots__ = ("edges", "params", "skill")

    def __init__(self, skill: int, params: list[float], edges: list[int]) -> None:
        self.skill = skill
        self.params = params
        self.edges = edges

    def copy(self) -> Node:
        return Node(self.skill, self.params[:], self.edges[:])

    def __repr__(self) -> str:
        return f"Node(skill={self.skill}, params={self.params}, edges={self.edges})"


class Genome:
    """A directed multigraph of :class:`Node` by id, with a start node.

    ``origin`` records how the genome came to be (generation, parents, operators): the
    lineage written beside an exported FSA.
    """

    __slots__ = ("next_id", "nodes", "origin", "start")

    def __init__(
        self, nodes: dict[int, Node], start: int, next_id: int | None = None,
        origin: Mapping[str, Any] | None = None,
    ) -> None:
        self.nodes = nodes
        self.start = start
        self.next_id = next_id if next_id is not None else (max(nodes, default=-1) + 1)
        self.origin: dict[str, Any] = dict(origin or {})

    def encode(self) -> tuple[Any, ...]:
        """A compact, picklable form (plain tuples) for sending to workers."""
        return (self.start, self.next_id, tuple(
            (k, n.skill, tuple(n.params), tuple(n.edges)) for k, n in self.nodes.items()
        ))

    @classmethod
    def decode(cls, data: tuple[Any, ...], origin: Mapping[str, Any] | None = None) -> Genome:
        start, next_id, nodes = data
        return cls(
            {k: Node(skill, list(params), list(edges)) for k, skill, params, edges in nodes},
            start, next_id, origin,
        )

    def __reduce__(self) -> tuple[Any, ...]:
        return (_decode_genome, (self.encode(), self.origin))

    def copy(self) -> Genome:
        return Genome(
            {k: n.copy() for k, n in self.nodes.items()}, self.start, self.next_id,
            dict(self.origin),
        )

    def __len__(self) -> int:
        return len(self.nodes)

    def new_id(self) -> int:
        i = self.next_id
        self.next_id += 1
        return i

    # -- graph queries ---------------------------------------------------------------------
    def reachable(self) -> list[int]:
        """Node ids reachable from the start, in breadth-first order."""
        nodes = self.nodes
        if self.start not in nodes:
            return []
        seen = {self.start}
        order = [self.start]
        queue = deque(order)
        while queue:
            for t in nodes[queue.popleft()].edges:
                if t >= 0 and t not in seen:
                    seen.add(t)
                    order.append(t)
                    queue.append(t)
        return order

    def prune(self) -> int:
        """Remove the nodes the start cannot reach (section 3.4); return how many."""
        reach = set(self.reachable())
        dead = [k for k in self.nodes if k not in reach]
        for k in dead:
            del self.nodes[k]
        return len(dead)

    def incoming(self) -> dict[int, list[tuple[int, int]]]:
        """For each node id, its incoming edges as ``(source id, outcome index)``."""
        inc: dict[int, list[tuple[int, int]]] = {k: [] for k in self.nodes}
        for src, n in self.nodes.items():
            for o, t in enumerate(n.edges):
                if t >= 0:
                    inc[t].append((src, o))
        return inc

    def key(self) -> tuple[Any, ...]:
        """A canonical form: equal for genomes that are the same FSA up to node ids."""
        order = self.reachable()
        rank = {k: i for i, k in enumerate(order)}
        return tuple(
            (n.skill, tuple(n.params), tuple(rank[t] if t >= 0 else t for t in n.edges))
            for n in (self.nodes[k] for k in order)
        )

    # -- invariants ------------------------------------------------------------------------
    def problems(self, skills: SkillSet) -> list[str]:
        """Broken invariants (empty when the genome is sound): used by tests and on load."""
        out: list[str] = []
        nterm = len(skills.terminals)
        if self.start not in self.nodes:
            out.append(f"start {self.start} is not a node")
        for k, n in self.nodes.items():
            if k < 0 or k >= self.next_id:
                out.append(f"node id {k} outside [0, next_id={self.next_id})")
            if not 0 <= n.skill < len(skills):
                out.append(f"node {k}: skill index {n.skill} out of range")
                continue
            c = skills.choices[n.skill]
            if len(n.edges) != len(c.outcomes):
                out.append(
                    f"node {k} ({c.name}): {len(n.edges)} edges for {len(c.outcomes)} outcomes"
                )
            if len(n.params) != c.genes:
                out.append(
                    f"node {k} ({c.name}): {len(n.params)} parameter genes, expected {c.genes}"
                )
            for x in n.params:
                if not 0.0 <= x <= 1.0:
                    out.append(f"node {k} ({c.name}): parameter {x} outside [0, 1]")
            for o, t in enumerate(n.edges):
                fixed = c.fixed_edge(o)
                if fixed is not None and t != fixed:
                    out.append(f"node {k} ({c.name}): outcome {c.outcomes[o]} must end the run")
                if t >= 0 and t not in self.nodes:
                    out.append(f"node {k} ({c.name}): edge to missing node {t}")
                if t < 0 and -t > nterm:
                    out.append(f"node {k} ({c.name}): edge to unknown terminal code {t}")
        if not out:
            reach = set(self.reachable())
            for k in self.nodes:
                if k not in reach:
                    out.append(f"node {k} is unreachable from the start {self.start}")
        return out

    # -- to and from the runtime's FSA -----------------------------------------------------
    def state_name(self, node_id: int, skills: SkillSet) -> str:
        return f"{skills.choices[self.nodes[node_id].skill].name}_{node_id}"

    def to_fsa(
        self, skills: SkillSet, *, step_limit: int = 20, name: str = "",
        meta: Mapping[str, Any] | None = None,
    ) -> FSA:
        """The FSA this genome encodes, with parameters in the skills' units.

        States are named ``Skill_N`` (the node id), in breadth-first order from the start.
        """
        states = {name: st for name, st, _, _ in self.states(skills)}
        return FSA(states, self.state_name(self.start, skills), skills.terminals, step_limit,
                   name, dict(meta or {}))

    def states(self, skills: SkillSet) -> list[tuple[str, State, int, int]]:
        """The FSA's states, in breadth-first order of the nodes from the start: ``(name,
        state, choice index, part)``, ``part`` 0 for a node's own state and 1 for the
        decision of a pair (:func:`pair_choices`), which follows its action as a state of
        its own, ``Decision_N``."""
        order = self.reachable()
        names = {k: self.state_name(k, skills) for k in order}
        terminals = skills.terminals
        out: list[tuple[str, State, int, int]] = []
        for k in order:
            n = self.nodes[k]
            c = skills.choices[n.skill]
            params = c.decode(n.params)
            tr = {o: (names[t] if t >= 0 else terminals[-t - 1])
                  for o, t in zip(c.outcomes, n.edges, strict=True)}
            if c.then is None or c.act is None:
                out.append((names[k], State(c.name, params, tr), n.skill, 0))
                continue
            then = f"{c.then.name}_{k}"
            act = {o: (then if (f := c.act.fixed_edge(i)) is None else terminals[-f - 1])
                   for i, o in enumerate(c.act.outcomes)}
            out.append((names[k], State(c.name, params, act), n.skill, 0))
            out.append((then, State(c.then.name, {}, tr), n.skill, 1))
        return out

    @classmethod
    def from_fsa(cls, fsa: FSA, skills: SkillSet, where: str = "") -> Genome:
        """Encode a hand-written or edited FSA, for seeding a population.

        Raises :class:`SeedFSAError` when the FSA uses a skill the task does not offer, has
        other terminals, or misses a transition.
        """
        src = one_line(where or fsa.path or "the seed FSA")
        if tuple(fsa.terminals) != skills.terminals:
            raise SeedFSAError(
                f"{src}: terminals {list(fsa.terminals)} differ from the task's "
                f"{list(skills.terminals)}; set `terminals: {list(skills.terminals)}`"
            )
        ids: dict[str, int] = {}
        used: set[int] = set()
        pending: list[str] = []
        for sname in fsa.states:
            m = re.fullmatch(r".*_(\d+)", sname)
            if m is not None and int(m.group(1)) not in used:
                ids[sname] = int(m.group(1))
                used.add(ids[sname])
            else:
                pending.append(sname)
        nxt = max(used, default=-1) + 1
        for sname in pending:
            ids[sname] = nxt
            nxt += 1
        nodes: dict[int, Node] = {}
        problems: list[str] = []
        for sname, st in fsa.states.items():
            line = _line(fsa, "states", sname)
            k = skills.index.get(st.skill)
            if k is None:
                problems.append(
                    f"{src}{line}: state {sname}: skill {st.skill!r} is not one this task lets "
                    f"evolution place ({', '.join(c.name for c in skills.choices)}); "
                    "replace it or add it to the task's skills"
                )
                continue
            c = skills.choices[k]
            values, bad = param_problems(c.name, c.params, st.params, sname)
            problems.extend(
                f"{src}{_line(fsa, 'states', sname, 'params', p.key or '')}: {p.render()}"
                for p in bad
            )
            params = c.encode(values)
            for o in st.transitions:  # a typo'd outcome would vanish from the evolved file
                if o not in c.outcomes:
                    problems.append(
                        f"{src}{_line(fsa, 'states', sname, 'transitions', o)}: state {sname}: "
                        f"{o!r} is not an outcome of skill {c.name} (its outcomes are "
                        f"{list(c.outcomes)}); remove it or rename it to one of "
                        f"{list(c.outcomes)}"
                    )
            edges: list[int] = []
            for o in c.outcomes:
                t = st.transitions.get(o)
                if t is None:
                    problems.append(
                        f"{src}{line}: state {sname}: outcome {o!r} of {c.name} has no "
                        f"transition; add `{o}: <state or {'/'.join(skills.terminals)}>`"
                    )
                    edges.append(skills.terminal_code(skills.terminals[-1]))
                elif t in ids:
                    edges.append(ids[t])
                else:
                    edges.append(skills.terminal_code(t))
            nodes[ids[sname]] = Node(k, params, edges)
        if problems:
            raise SeedFSAError("cannot seed evolution from this FSA:\n  " + "\n  ".join(
                one_line(p) for p in problems))
        g = cls(nodes, ids[fsa.start], nxt, {"seeded_from": src})
        g.prune()
        return g

    def __repr__(self) -> str:
        return f"<Genome {len(self.nodes)} nodes, start {self.start}>"


def _decode_genome(data: tuple[Any, ...], origin: Mapping[str, Any]) -> Genome:
    return Genome.decode(data, origin)


def _line(fsa: FSA, *keys: str) -> str:
    return "" if fsa.source is None else fsa.source.at(*keys)


class GenomeCompiler:
    """Compiles genomes to the runtime's :class:`CompiledFSA`, cheaply, many times.

    Skill implementations are resolved once; each compilation maps the parameters to the
    skills' units and builds the program through :class:`CompiledFSA`'s constructor, as
    :func:`~skillcompose.compile_fsa` does. Genomes are valid by construction, so the registry
    check of :func:`~skillcompose.compile_fsa` is skipped.
    """

    def __init__(self, task: Task, skills: SkillSet, step_limit: int | None = None) -> None:
        reg = task.registry
        self.skills = skills
        self.backend = task.backend or reg.backend
        self.step_limit = step_limit if step_limit is not None else task.step_limit
        self._impls: list[tuple[Skill, ...]] = [
            (reg.resolve(c.name, self.backend),) if c.then is None else
            (reg.resolve(c.name, self.backend), reg.resolve(c.then.name, self.backend))
            for c in skills.choices]

    def fsa(self, g: Genome, **kw: Any) -> FSA:
        return g.to_fsa(self.skills, step_limit=self.step_limit, **kw)

    def compile(self, g: Genome) -> CompiledFSA:
        expanded = g.states(self.skills)
        states = {name: st for name, st, _, _ in expanded}
        impls = [(self._impls[k][part], st.params) for _, st, k, part in expanded]
        fsa = FSA.trusted(states, expanded[0][0], self.skills.terminals,
                          self.step_limit)  # valid by construction
        return CompiledFSA(fsa, impls, self.backend)
