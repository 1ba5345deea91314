"""The two ways the grid tasks of the benchmark can be written for an FSA.

- ``form="reporting"`` (Jefferson et al.'s Tracker ant): every action reports the sensor
  after it (``food`` / ``empty`` ahead for the ant, ``wall`` / ``open`` for the maze robot),
  so the FSA senses on every step for free. A state is an action; its edges say what to do
  next given what the robot sees. One FSA step is one time step, and the task's step limit
  is the world's time limit.
- ``form="sensing"`` (the way many robot tasks are written, and Koza's ant, whose
  ``IF-FOOD-AHEAD`` costs no time): a sensing skill (``FoodAhead``, ``WallAhead``: ``yes`` /
  ``no``) separate from actions whose only outcome is ``done``. Sensing takes no time step;
  only actions do. The world counts its time steps and ends the run with the outcome
  ``time_up`` when the last action of the budget is done, so the engine's step limit (FSA
  steps, sensing included) must not cut a run short: it is set to
  :func:`sensing_step_limit`, which no controller that acts reaches.

A controller that senses again and again without acting never changes its world: after more
sensing steps in a row than an FSA can have states (:data:`MAX_SENSES`, the file format's
500), it must be going round a loop of sensing states for ever, and the world ends the run
there (``time_up``) with what it has done, as letting it run would: nothing more would ever
happen. So the bound changes no fitness; it only spares the engine the rest of the loop.

:func:`to_sensing` turns a reporting FSA into the sensing FSA that takes the same actions in
the same worlds (each state becomes its action followed by one sensing state), so that a
controller can be compared across the two forms.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final

from skillcompose import FSA, State
from skillcompose.fsa import MAX_STEP_LIMIT

FORMS = ("reporting", "sensing")
MAX_SENSES = 500
"""Sensing steps in a row after which the world ends the run: the most states an FSA file
holds, so only a loop of sensing states reaches it."""
TIME_UP: Final = "time_up"


def check_form(form: object) -> str:
    """``form`` if it names one of :data:`FORMS`, else a ``ValueError`` naming them."""
    if form not in FORMS:
        raise ValueError(f"form={form!r}: choose one of {', '.join(FORMS)}")
    return str(form)


def sensing_step_limit(actions: int) -> int:
    """The engine's step limit for ``actions`` time steps in the sensing form: every action
    preceded by the most sensing steps a run can make in a row, and a last run of them."""
    limit = actions * (MAX_SENSES + 1) + MAX_SENSES
    if limit > MAX_STEP_LIMIT:
        raise ValueError(f"{actions} time steps in the sensing form need a step limit of "
                         f"{limit:,}, above the engine's {MAX_STEP_LIMIT:,}; give at most "
                         f"{(MAX_STEP_LIMIT - MAX_SENSES) // (MAX_SENSES + 1):,}")
    return limit


def to_sensing(fsa: FSA, sense: str, seen: Mapping[str, str], step_limit: int,
               keep: tuple[str, ...] = ()) -> FSA:
    """The sensing form of the reporting FSA ``fsa``: each state ``S`` becomes its action
    (``done`` → ``S?``, ``time_up`` ends the run, the outcomes in ``keep`` as they were)
    followed by the state ``S?`` of the skill ``sense``, whose outcomes (the values of
    ``seen``, keyed by the reporting outcome they stand for) go where ``S``'s went."""
    states: dict[str, State] = {}
    for name, st in fsa.states.items():
        after = {"done": f"{name}?", TIME_UP: TIME_UP}
        after.update({o: st.transitions[o] for o in keep if o in st.transitions})
        states[name] = State(st.skill, transitions=after, params=dict(st.params))
        states[f"{name}?"] = State(sense, transitions={
            seen[o]: target for o, target in st.transitions.items() if o in seen}
            | {TIME_UP: TIME_UP})
    terminals = tuple(dict.fromkeys([*fsa.terminals, TIME_UP]))
    return FSA(name=f"{fsa.name}_sensing", start=fsa.start, states=states,
               terminals=terminals, step_limit=step_limit)
