"""Genetic operators of sections 3.4-3.7: initialisation, mutations and crossover.

Every operator takes an explicit ``numpy.random.Generator``, works in place on its genome(s)
and leaves them sound: one edge per outcome of each node's skill, parameters in [0, 1], the
start a node, every node reachable from the start (unreachable ones are pruned, section 3.4).

A random edge target is a node or a terminal outcome; each terminal weighs
``terminal_weight`` against one node (the paper's graphs had no terminals: its terminating
actions ended a run themselves).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from .config import EvolutionConfig
from .genome import Genome, Node, SkillSet

__all__ = [
    "add_node",
    "change_start",
    "crossover",
    "delete_node",
    "edge_for",
    "fix_start",
    "initialize",
    "mutate",
    "mutate_genes",
    "mutate_node",
    "random_node",
    "random_target",
]


def random_target(
    g: Genome, skills: SkillSet, rng: np.random.Generator, weight: float = 1.0,
    exclude: int | None = None, extra: int | None = None,
) -> int:
    """A random edge target: a node id (``extra`` counts as a node) or a terminal code."""
    ids = [k for k in g.nodes if k != exclude]
    if extra is not None and extra not in g.nodes and extra != exclude:
        ids.append(extra)
    nterm = len(skills.terminals) if skills.free_terminals else 0
    terms = [-(t + 1) for t in range(nterm) if -(t + 1) != exclude]
    total = len(ids) + weight * len(terms)
    if total <= 0:  # nothing else to choose: keep the excluded target if it is allowed
        if ids:
            return ids[0]
        if terms:
            return terms[0]
        if exclude is not None and (exclude >= 0 or skills.free_terminals):
            return exclude
        return next(iter(g.nodes)) if g.nodes else -1
    u = rng.random() * total
    if u < len(ids):
        return ids[min(int(u), len(ids) - 1)]
    k = min(int((u - len(ids)) / weight), len(terms) - 1) if weight > 0 else 0
    return terms[k]


def random_node(
    g: Genome, skills: SkillSet, rng: np.random.Generator, weight: float, node_id: int
) -> Node:
    """A node with a random skill, random parameters and random edges (``node_id`` may be
    a target of its own edges)."""
    k = skills.draw(rng)
    c = skills.choices[k]
    params = [float(x) for x in rng.random(c.genes)]
    edges = [edge_for(g, skills, rng, weight, k, o, extra=node_id) for o in range(len(c.outcomes))]
    return Node(k, params, edges)


def edge_for(
    g: Genome, skills: SkillSet, rng: np.random.Generator, weight: float, skill: int,
    outcome: int, exclude: int | None = None, extra: int | None = None,
) -> int:
    """The edge of ``outcome`` of a node of skill ``skill``: fixed for a terminating skill's
    terminal outcomes, else a random target."""
    fixed = skills.choices[skill].fixed_edge(outcome)
    if fixed is not None:
        return fixed
    return random_target(g, skills, rng, weight, exclude=exclude, extra=extra)


def initialize(
    skills: SkillSet, rng: np.random.Generator, nodes: int, weight: float = 1.0
) -> Genome:
    """Section 3.5: ``nodes`` random nodes with random edges, a start, then pruning (at
    most ``skills.max_nodes``: what an FSA file holds)."""
    nodes = min(nodes, skills.max_nodes)
    g = Genome({}, 0, 0)
    choices = [skills.draw(rng) for _ in range(nodes)]
    for k in choices:
        c = skills.choices[k]
        g.nodes[g.new_id()] = Node(k, [float(x) for x in rng.random(c.genes)], [])
    for n in g.nodes.values():
        n.edges = [
            edge_for(g, skills, rng, weight, n.skill, o)
            for o in range(len(skills.choices[n.skill].outcomes))
        ]
    eligible = _start_candidates(g)
    pool = eligible or list(g.nodes)
    g.start = pool[int(rng.integers(len(pool)))]
    g.prune()
    return g


def _start_candidates(g: Genome, exclude: int | None = None) -> list[int]:
    """Nodes with an edge to another node (section 3.6: "at least one outgoing edge and not
    all the edges are self-loops"). An edge into a terminal outcome does not count: a start
    whose every edge ends the run or loops back is an FSA of one state, such as a lone
    terminating CheckSuccess."""
    return [
        k for k, n in g.nodes.items()
        if k != exclude and any(t >= 0 and t != k for t in n.edges)
    ]


def fix_start(g: Genome, rng: np.random.Generator) -> bool:
    """Re-choose the start when it has no edge to another node (a mutation or a crossover
    rewired it), among the nodes that have one. Call it before pruning, which would
    otherwise cut the genome down to the stranded start. Returns whether the start moved;
    a genome with no such node keeps its start."""
    n = g.nodes.get(g.start)
    if n is not None and any(t >= 0 and t != g.start for t in n.edges):
        return False
    pool = _start_candidates(g)
    if not pool:
        return False
    g.start = pool[int(rng.integers(len(pool)))]
    return True


def add_node(g: Genome, skills: SkillSet, rng: np.random.Generator, weight: float = 1.0,
             split: bool = False) -> bool:
    """Figure 3: a new random node takes over one incoming edge of a node that has two or
    more; when no node has, it takes over an edge into a terminal outcome. With ``split``
    the new node's outcomes all lead where that edge led (its terminating outcomes stay
    fixed), else to random targets. Returns whether a node was added."""
    if len(g.nodes) >= skills.max_nodes:  # more would not fit an FSA file
        return False
    inc = g.incoming()
    crowded = [k for k, e in inc.items() if len(e) >= 2]
    if crowded:
        v = crowded[int(rng.integers(len(crowded)))]
        src, o = inc[v][int(rng.integers(len(inc[v])))]
    else:
        into_terminal = [
            (k, o) for k, n in g.nodes.items() for o, t in enumerate(n.edges)
            if t < 0 and skills.choices[n.skill].fixed_edge(o) is None
        ]
        if not into_terminal:
            return False
        src, o = into_terminal[int(rng.integers(len(into_terminal)))]
    new = g.new_id()
    old = g.nodes[src].edges[o]
    node = random_node(g, skills, rng, weight, new)
    if split:
        node.edges = [e if skills.choices[node.skill].fixed_edge(i) is not None else old
                      for i, e in enumerate(node.edges)]
    g.nodes[new] = node
    g.nodes[src].edges[o] = new
    g.prune()
    return True


def delete_node(
    g: Genome, skills: SkillSet, rng: np.random.Generator, weight: float = 1.0
) -> bool:
    """Remove a random node and re-route its incoming edges at random (section 3.6)."""
    if len(g.nodes) <= 1:
        return False
    ids = list(g.nodes)
    v = ids[int(rng.integers(len(ids)))]
    del g.nodes[v]
    for n in g.nodes.values():
        for o, t in enumerate(n.edges):
            if t == v:
                n.edges[o] = random_target(g, skills, rng, weight)
    if g.start == v:
        pool = _start_candidates(g) or list(g.nodes)
        g.start = pool[int(rng.integers(len(pool)))]
    fix_start(g, rng)
    g.prune()
    return True


def change_start(g: Genome, rng: np.random.Generator) -> bool:
    """Move the start to another node with an edge that is not a self-loop (section 3.6)."""
    pool = _start_candidates(g, exclude=g.start)
    if not pool:
        return False
    g.start = pool[int(rng.integers(len(pool)))]
    g.prune()
    return True


def mutate_node(
    g: Genome, node_id: int, skills: SkillSet, rng: np.random.Generator,
    p_mut: float, sigma: float, weight: float = 1.0,
) -> str:
    """Node mutation (section 3.6), applied to a node chosen with probability ``p_mut``.

    With probability ``p_mut`` (so ``p_mut**2`` overall) the node's skill changes and its
    parameters and edges are recreated; otherwise one outgoing edge is re-routed to a
    different random target and each parameter gets zero-mean Gaussian noise (standard
    deviation ``sigma``) with probability ``p_mut``, clipped to [0, 1]. Does not prune.
    """
    n = g.nodes[node_id]
    if rng.random() < p_mut:
        fresh = random_node(g, skills, rng, weight, node_id)
        n.skill, n.params, n.edges = fresh.skill, fresh.params, fresh.edges
        return "skill"
    c = skills.choices[n.skill]
    free = [o for o in range(len(n.edges)) if c.fixed_edge(o) is None]
    if free:
        o = free[int(rng.integers(len(free)))]
        n.edges[o] = random_target(g, skills, rng, weight, exclude=n.edges[o])
    mutate_genes(n.params, rng, p_mut, sigma)
    return "node"


def mutate_genes(
    genes: list[float], rng: np.random.Generator, p_mut: float, sigma: float
) -> None:
    """Gaussian noise on a node's parameter genes, in place, clipped to [0, 1].

    As the paper's library (PyEvolve's real Gaussian list mutator) did: when the expected
    number of mutations ``n * p_mut`` is below one, each gene mutates with probability
    ``p_mut``; otherwise ``round(n * p_mut)`` genes drawn at random (with repetition)
    mutate. A node with a few scalar parameters takes the first branch; a network's
    weights the second.
    """
    n = len(genes)
    expected = n * p_mut
    if expected < 1.0:
        for i in range(n):
            if rng.random() < p_mut:
                x = genes[i] + float(rng.normal(0.0, sigma))
                genes[i] = 0.0 if x < 0.0 else 1.0 if x > 1.0 else x
        return
    for _ in range(round(expected)):
        i = int(rng.integers(n))
        x = genes[i] + float(rng.normal(0.0, sigma))
        genes[i] = 0.0 if x < 0.0 else 1.0 if x > 1.0 else x


def mutate(
    g: Genome, skills: SkillSet, rng: np.random.Generator, cfg: EvolutionConfig
) -> list[str]:
    """The mutation step of algorithm 1 on one child; returns the operators applied.

    As in the paper's PyEvolve implementation, each node mutates with probability ``p_mut``;
    then a node is added with ``p_add``, one deleted with ``p_del`` and the start changes
    with ``p_mut``; unreachable nodes are pruned.
    """
    ops: list[str] = []
    w = cfg.terminal_weight
    for k in list(g.nodes):
        if k in g.nodes and rng.random() < cfg.p_mut:
            ops.append(mutate_node(g, k, skills, rng, cfg.p_mut, cfg.param_sigma, w))
    if cfg.p_param > 0.0:
        for n in g.nodes.values():
            if n.params and rng.random() < cfg.p_param:
                mutate_genes(n.params, rng, cfg.p_mut, cfg.param_sigma)
                ops.append("params")
    if fix_start(g, rng):  # before add_node prunes
        ops.append("fix-start")
    if rng.random() < cfg.p_add:
        split = cfg.p_split > 0.0 and rng.random() < cfg.p_split
        if add_node(g, skills, rng, w, split):
            ops.append("split" if split else "add")
    if rng.random() < cfg.p_del and delete_node(g, skills, rng, w):
        ops.append("delete")
    if rng.random() < cfg.p_mut and change_start(g, rng):
        ops.append("start")
    g.prune()
    return ops


def _bfs(g: Genome, source: int, n: int) -> list[int]:
    """Up to ``n`` node ids around ``source``, breadth first over edges in both directions."""
    nbrs: dict[int, list[int]] = {k: [] for k in g.nodes}
    for k, node in g.nodes.items():
        for t in node.edges:
            if t >= 0:
                nbrs[k].append(t)
                nbrs[t].append(k)
    order = [source]
    seen = {source}
    queue = deque(order)
    while queue and len(order) < n:
        for t in nbrs[queue.popleft()]:
            if t not in seen:
                seen.add(t)
                order.append(t)
                if len(order) >= n:
                    break
                queue.append(t)
    return order


def crossover(
    g1: Genome, g2: Genome, skills: SkillSet, rng: np.random.Generator, weight: float = 1.0
) -> int:
    """Algorithm 2 in place on two children (copies of the parents); returns the number of
    nodes swapped.

    A random number of nodes (1 to half the smaller genome) is taken by BFS around a random
    node of each genome; the two subgraphs' internal edges are removed, the nodes (skill and
    parameters) swapped pairwise in BFS order, the internal edges recreated between the
    corresponding positions, and each swapped node's missing outcome edges filled: first
    with the position's old edge to outside the subgraph for the same outcome, else at
    random. An edge into a terminal outcome travels with its node.
    """
    half = max(1, min(len(g1), len(g2)) // 2)
    num = int(rng.integers(1, half + 1))
    ids1, ids2 = list(g1.nodes), list(g2.nodes)
    sub1 = _bfs(g1, ids1[int(rng.integers(len(ids1)))], num)
    sub2 = _bfs(g2, ids2[int(rng.integers(len(ids2)))], num)
    num = min(len(sub1), len(sub2))
    sub1, sub2 = sub1[:num], sub2[:num]
    old1 = {k: g1.nodes[k].copy() for k in sub1}
    old2 = {k: g2.nodes[k].copy() for k in sub2}
    _implant(g1, sub1, sub2, old1, old2, skills, rng, weight)
    _implant(g2, sub2, sub1, old2, old1, skills, rng, weight)
    fix_start(g1, rng)
    fix_start(g2, rng)
    g1.prune()
    g2.prune()
    return num


def _implant(
    g: Genome, sub: list[int], other_sub: list[int], own: dict[int, Node],
    other: dict[int, Node], skills: SkillSet, rng: np.random.Generator, weight: float,
) -> None:
    """Put ``other``'s subgraph nodes at the positions ``sub`` of ``g`` (lines 8-17)."""
    pos = {k: i for i, k in enumerate(other_sub)}
    own_set = set(sub)
    for i, k in enumerate(sub):
        donor = other[other_sub[i]]
        before = own[k]
        c = skills.choices[donor.skill]
        kept = {  # the position's edges to outside its subgraph, by outcome name
            skills.choices[before.skill].outcomes[o]: t
            for o, t in enumerate(before.edges) if t >= 0 and t not in own_set
        }
        edges: list[int] = []
        for o, t in enumerate(donor.edges):
            fixed = c.fixed_edge(o)
            if fixed is not None:
                edges.append(fixed)  # a terminating skill's outcome ends the run
            elif t >= 0 and t in pos:
                edges.append(sub[pos[t]])  # an internal edge, recreated
            elif t < 0:
                edges.append(t)  # into a terminal outcome: travels with the node
            elif c.outcomes[o] in kept:
                edges.append(kept[c.outcomes[o]])
            else:
                edges.append(random_target(g, skills, rng, weight))  # line 17: repair
        g.nodes[k] = Node(donor.skill, donor.params[:], edges)
