"""FSAs as graphs (networkx): structure queries that help a person read an FSA.

:func:`to_networkx` gives the FSA as a ``networkx.MultiDiGraph`` (one edge per outcome, the
paper's figure 1), with the terminal outcomes as nodes of their own. :func:`trap_states`
finds the states from which no terminal outcome can be reached: a run that enters one can
only end in ``timeout``, which ``skillcompose validate`` reports.
"""

from __future__ import annotations

from typing import Any

import networkx as nx

from .fsa import FSA

__all__ = ["terminal_node", "to_networkx", "trap_states"]


def terminal_node(outcome: str) -> str:
    """The graph node of a terminal outcome (kept apart from state names)."""
    return f"<{outcome}>"


def to_networkx(fsa: FSA) -> Any:
    """A ``MultiDiGraph``: nodes are states (attributes ``skill``, ``params``, ``start``) and
    terminal outcomes (attribute ``terminal``); one edge per outcome, keyed by it."""
    g = nx.MultiDiGraph(name=fsa.name)
    for t in fsa.terminals:
        g.add_node(terminal_node(t), terminal=True)
    for sname, st in fsa.states.items():
        g.add_node(sname, skill=st.skill, params=dict(st.params), start=sname == fsa.start,
                   terminal=False)
    for sname, st in fsa.states.items():
        for outcome, target in st.transitions.items():
            node = terminal_node(target) if target in fsa.terminals else target
            g.add_edge(sname, node, key=outcome, outcome=outcome)
    return g


trap_states = FSA.trap_states
"""States reachable from the start from which no terminal outcome is reachable: the model's
one search (:meth:`FSA.trap_states <skillcompose.fsa.FSA.trap_states>`) as a function."""
