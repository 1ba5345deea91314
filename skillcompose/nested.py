"""FSAs as skills: how an evolved FSA becomes an action of a new one (the paper's 4.3).

The nested FSA runs on the caller's blackboard with the caller's random generator; its
terminal outcomes are the skill's outcomes. It is compiled lazily, once per backend, with the
registry it was registered in, so swapping a backend swaps it inside the nested FSA as well.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .activation import Starter
from .blackboard import Blackboard
from .errors import RegistryError, one_line
from .executor import CompiledFSA, FSARun, compile_fsa
from .fsa import FSA, TIMEOUT
from .skill import Skill, SkillFn, SkillSpec

if TYPE_CHECKING:
    from .lookup import SkillLookup

__all__ = ["MAX_NESTING", "FSASkill", "fsa_skill"]

MAX_NESTING = 50
"""How deep FSAs may nest (an FSA whose state runs an FSA whose state runs ...): each level
takes several of Python's stack frames when it compiles and runs; 150 levels still ran
where 200 exhausted the stack."""


class FSASkill(Skill):
    """A skill whose implementation is an FSA: long-running, ticked state by state."""

    __slots__ = ("_compiled", "depth", "fsa", "registry", "timeout_outcome")
    long_running = True

    def __init__(
        self, spec: SkillSpec, fsa: FSA, registry: SkillLookup, timeout_outcome: str,
        depth: int = 1,
    ) -> None:
        super().__init__(spec, None, backend="default")
        self.fsa = fsa
        self.registry = registry
        self.timeout_outcome = timeout_outcome
        self.depth = depth  # 1: its states run plain skills; k + 1: one runs an FSA of k
        self._compiled: dict[str, CompiledFSA] = {}

    def compiled(self, backend: str | None = None) -> CompiledFSA:
        """The nested FSA compiled for ``backend`` (once per backend)."""
        be = backend or self.registry.backend
        if be not in self._compiled:
            try:
                self._compiled[be] = compile_fsa(self.fsa, self.registry, be)
            except RecursionError:  # a skill swapped in (replace=True) closed a circle
                raise RegistryError(
                    f"FSA skill {self.name}: its nested FSAs run one another in a circle: an "
                    "FSA cannot contain itself; replace the skill that closes the circle"
                ) from None
        return self._compiled[be]

    def starter(self, backend: str | None = None) -> Starter:
        child = self.compiled(backend)
        timeout_outcome = self.timeout_outcome

        def start_nested(bb: Blackboard, rng: np.random.Generator) -> _NestedActivation:
            return _NestedActivation(FSARun(child, bb, rng, propagate=True), timeout_outcome)

        return start_nested

    def bind(self, registry: Any = None, backend: str | None = None) -> SkillFn:
        """Run-to-completion form: the nested FSA run in one call."""
        run = self.compiled(backend).outcome
        timeout_outcome = self.timeout_outcome

        def run_nested(bb: Blackboard, rng: np.random.Generator) -> str:
            outcome, _ = run(bb, rng)
            return timeout_outcome if outcome == TIMEOUT else outcome

        run_nested.__qualname__ = run_nested.__name__ = f"fsa_{self.name}"
        return run_nested


@dataclass(slots=True, eq=False)
class _NestedActivation:
    """A nested FSA ticked state by state; cancelling it preempts the child run."""

    run: FSARun
    timeout_outcome: str

    def tick(self) -> str:
        out = self.run.tick()
        if out == TIMEOUT and self.run.done:
            return self.timeout_outcome
        return out

    def cancel(self) -> None:
        self.run.preempt()


def fsa_skill(
    fsa: FSA,
    registry: SkillLookup,
    *,
    name: str | None = None,
    on_timeout: str | None = None,
) -> FSASkill:
    """Make a skill of ``fsa`` whose states' skills come from ``registry``."""
    skill_name = name or fsa.name
    if not skill_name or not skill_name.isidentifier():
        if fsa.path and name is None:  # a file: say where
            at = fsa.source.at("name") if fsa.source is not None and fsa.name else ""
            raise RegistryError(
                f"{one_line(fsa.path)}{at}: an FSA file used as a skill needs a `name:` that "
                f"is an identifier (the skill's name, e.g. FetchJug), got {skill_name!r}"
            )
        raise RegistryError(
            f"an FSA registered as a skill needs an identifier name, got {skill_name!r}; "
            "set `name:` in the file or pass name=..."
        )
    fsa.validate(registry)
    depth = 1 + max((impl.depth for st in fsa.states.values()
                     for backend in registry.backends(st.skill)
                     if isinstance(impl := registry.resolve(st.skill, backend), FSASkill)),
                    default=0)
    if depth > MAX_NESTING:  # compiling and running it would exhaust Python's stack
        where = f"{one_line(fsa.path)}: " if fsa.path else ""
        raise RegistryError(
            f"{where}the FSA {skill_name} nests FSAs {depth} deep, more than the "
            f"{MAX_NESTING} a run can hold; flatten some levels into one FSA"
        )
    outcomes = list(fsa.terminals)
    if on_timeout is None:
        on_timeout = "failure" if "failure" in outcomes else TIMEOUT
    if on_timeout not in outcomes:
        outcomes.append(on_timeout)
    specs = [registry.spec(st.skill) for st in fsa.states.values()]
    spec = SkillSpec(
        name=skill_name,
        outcomes=tuple(outcomes),
        reads=frozenset().union(*(s.reads for s in specs)),
        writes=frozenset().union(*(s.writes for s in specs)),
        key_types={k: t for s in specs for k, t in s.key_types.items()},
        doc=f"FSA {skill_name} ({len(fsa.states)} states, start {fsa.start})",
    )
    return FSASkill(spec, fsa, registry, on_timeout, depth)
