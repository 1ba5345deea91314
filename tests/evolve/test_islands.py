"""The island model and the diversity options: migration, restarts, unique children; the same
run on any backend and number of workers, and resumed as if never interrupted."""

from __future__ import annotations

from pathlib import Path

import pytest

from skillcompose.evolve import (
    PRESETS,
    EvolutionConfig,
    EvolutionConfigError,
    EvolutionResult,
    RunDir,
    evolve,
)
from skillcompose.evolve.cli import _config, build_parser
from skillcompose.task import Task, load_task

ISLANDS = EvolutionConfig(population=40, initial_nodes=8, generations=7, islands=4,
                          migration_interval=2, migrants=2, elitism=1, restart_after=2,
                          unique_children=True, cache=True, checkpoint_every=2)


def _task() -> Task:
    return load_task("examples.toy_task", p_fail=0.3, tolerance=0.002)


def _run(r: EvolutionResult) -> tuple[object, ...]:
    return ([(h.generation, h.best, h.mean, h.median, h.best_size, h.total_evaluations)
             for h in r.history], r.best_fitness, r.evaluations, r.evolved_fsa)


def test_islands_are_the_same_run_on_any_backend_and_number_of_workers() -> None:
    task = _task()
    serial = evolve(task, ISLANDS, seed=5, backend="serial", simplify_result=False,
                    check_trials=0)
    one = evolve(task, ISLANDS, seed=5, backend="process", workers=1,
                 simplify_result=False, check_trials=0)
    two = evolve(task, ISLANDS, seed=5, backend="process", workers=2,
                 simplify_result=False, check_trials=0)
    assert _run(serial) == _run(one) == _run(two)
    assert serial.generations == ISLANDS.generations  # unsolved: every generation ran


def test_an_interrupted_island_run_resumes_as_if_never_interrupted(tmp_path: Path) -> None:
    task = _task()
    full = evolve(task, ISLANDS, seed=6, out_dir=tmp_path / "full", simplify_trials=10,
                  check_trials=10)
    short = evolve(task, ISLANDS.replace(generations=3), seed=6, out_dir=tmp_path / "short",
                   simplify_trials=10, check_trials=10)
    assert short.generations == 3
    state = RunDir(tmp_path / "short").load_checkpoint()
    assert len(state["island_best"]) == 4  # restarts' bookkeeping is checkpointed
    resumed = evolve(task, ISLANDS, resume=tmp_path / "short")
    assert _run(resumed) == _run(full)
    assert resumed.best_fsa == full.best_fsa


def test_migrants_arrive_every_interval_from_the_ring_neighbour() -> None:
    from skillcompose.evolve.breeding import migrate  # the breeding step, seen from inside
    from skillcompose.evolve.state import RunState

    task = _task()
    cfg = EvolutionConfig(population=12, initial_nodes=6, islands=3, migrants=2,
                          migration_interval=1, topology="ring")
    from skillcompose.evolve.genome import SkillSet
    from skillcompose.evolve.operators import initialize

    skills = SkillSet.from_task(task)
    run = RunState(task, cfg, 0, skills, None, 1, {})
    for _ in range(cfg.population):
        g = initialize(skills, run.rng, cfg.initial_nodes)
        g.origin = {"uid": run.uid()}
        run.population.append(g)
    run.generation = 1
    fitness = [float(i) for i in range(cfg.population)]  # minimised: index 0 is the best
    moved, moved_fitness = migrate(run, run.population, fitness)
    # island 0 (0-3) gets island 2's best (8, 9) in place of its worst (3, 2); island 1
    # (4-7) gets island 0's best (0, 1); island 2 (8-11) gets island 1's best (4, 5)
    assert [g.origin["uid"] for g in moved] == [0, 1, 9, 8, 4, 5, 1, 0, 8, 9, 5, 4]
    assert moved_fitness == [0, 1, 9, 8, 4, 5, 1, 0, 8, 9, 5, 4]
    assert [g.origin.get("migrant_from") for g in moved[:4]] == [None, None, 2, 2]
    run.cfg = cfg.replace(migration_interval=2)
    run.generation = 3  # with an interval of 2, generation 3 has none
    assert migrate(run, run.population, fitness)[1] == fitness
    complete = cfg.replace(topology="complete")
    run.cfg = complete
    moved, moved_fitness = migrate(run, run.population, fitness)
    # island 0 receives from islands 1 and 2: the best two of each, capped at half (2)
    assert moved_fitness[:4] == [0, 1, 5, 4]


def test_unique_children_spend_evaluations_on_new_genomes() -> None:
    task = _task()
    base = EvolutionConfig(population=60, initial_nodes=6, generations=4, tournament=3,
                           cache=True)
    plain = evolve(task, base, seed=1, simplify_result=False, check_trials=0)
    unique = evolve(task, base.replace(unique_children=True), seed=1,
                    simplify_result=False, check_trials=0)
    assert plain.generations == unique.generations == 4  # neither solved: whole budgets
    # with the cache, an evaluation is a new genome: unique children evaluate more of them
    assert unique.evaluations > plain.evaluations


def test_neutral_elites_give_way_to_newer_genomes_of_equal_fitness() -> None:
    from skillcompose.evolve.breeding import breed
    from skillcompose.evolve.genome import SkillSet
    from skillcompose.evolve.operators import initialize
    from skillcompose.evolve.state import RunState

    task = _task()
    skills = SkillSet.from_task(task)

    def elites(neutral: bool) -> list[int]:
        cfg = EvolutionConfig(population=6, initial_nodes=4, elitism=2, neutral=neutral)
        run = RunState(task, cfg, 0, skills, None, 1, {})
        for _ in range(cfg.population):
            g = initialize(skills, run.rng, cfg.initial_nodes)
            g.origin = {"uid": run.uid()}
            run.population.append(g)
        fitness = [1.0, 0.5, 0.5, 2.0, 0.5, 0.5]  # minimised: four equal best
        return [g.origin["uid"] for g in breed(run, fitness) if g.origin.get("elite")]

    assert elites(False) == [1, 2]  # the first found stay
    assert elites(True) == [5, 4]  # the newest of the equals take their place


def test_a_neutral_run_is_the_same_on_a_pool_and_resumed(tmp_path: Path) -> None:
    task = _task()
    cfg = ISLANDS.replace(neutral=True, islands=1, restart_after=0)
    full = evolve(task, cfg, seed=2, out_dir=tmp_path / "full", simplify_result=False,
                  check_trials=0)
    pool = evolve(task, cfg, seed=2, backend="process", workers=2, simplify_result=False,
                  check_trials=0)
    assert _run(pool) == _run(full)
    evolve(task, cfg.replace(generations=3), seed=2, out_dir=tmp_path / "short",
           simplify_result=False, check_trials=0)
    resumed = evolve(task, cfg, resume=tmp_path / "short")
    assert _run(resumed) == _run(full)
    assert _run(full) != _run(evolve(task, cfg.replace(neutral=False), seed=2,
                                     simplify_result=False, check_trials=0))


def test_a_stagnant_island_restarts_around_its_best() -> None:
    task = _task()
    cfg = EvolutionConfig(population=20, initial_nodes=6, generations=6, islands=2,
                          restart_after=1, migrants=0)
    r = evolve(task, cfg, seed=3, simplify_result=False, check_trials=0)
    assert r.generations == 6
    # the toy task's best does not improve every generation, so some island restarted:
    # its children were drawn afresh ("restart"); the run stays whole and valid
    restarted = evolve(task, cfg.replace(generations=6, restart_after=0), seed=3,
                       simplify_result=False, check_trials=0)
    assert _run(r) != _run(restarted)


@pytest.mark.parametrize(("changes", "message"), [
    ({"population": 30, "islands": 4}, "cannot be split into 4 equal islands"),
    ({"population": 8, "islands": 4, "elitism": 2}, "smaller than an island"),
    ({"population": 8, "islands": 4, "migrants": 2}, "migrants = 2 must be smaller"),
    ({"topology": "star"}, "choose one of ring, complete"),
])
def test_bad_island_settings_are_refused_with_the_fix(
    changes: dict[str, object], message: str
) -> None:
    with pytest.raises(EvolutionConfigError, match=message):
        EvolutionConfig(**changes)  # type: ignore[arg-type]


def test_the_command_line_sets_islands_and_the_island_preset() -> None:
    args = build_parser().parse_args(
        ["evolve", "examples.toy_task", "--islands", "3", "--population", "30",
         "--migration-interval", "5", "--migrants", "1", "--topology", "complete",
         "--restart-after", "20", "--unique-children", "--neutral"])
    cfg = _config(args)
    assert (cfg.islands, cfg.population, cfg.migration_interval, cfg.migrants,
            cfg.topology, cfg.restart_after, cfg.unique_children, cfg.neutral) == (
        3, 30, 5, 1, "complete", 20, True, True)
    preset = _config(build_parser().parse_args(["evolve", "examples.toy_task", "--preset",
                                                "islands"]))
    assert preset == EvolutionConfig(**PRESETS["islands"])
    assert PRESETS["paper"] == {}  # the paper's table 1, untouched


def test_the_defaults_islands_follow_a_population_given_alone() -> None:
    """A noisy task's default runs 4 islands of 150; given another population it splits it
    into the most equal islands of 20 or more (up to 4), or keeps one population; an
    explicit --islands or preset is taken as given."""
    from skillcompose.evolve.config import ISLAND_LEAST, default_islands

    def islands(*argv: str) -> int:
        return _config(build_parser().parse_args(["evolve", "examples.toy_task", *argv])
                       ).islands

    assert islands() == 4 and islands("--population", "600") == 4
    assert islands("--population", "50") == 2  # 25 each
    assert islands("--population", "90") == 3 and islands("--population", "100") == 4
    assert islands("--population", "30") == 1 and islands("--population", "6") == 1
    assert islands("--population", "41") == 1  # a prime: no equal split
    assert islands("--population", "50", "--islands", "5") == 5
    with pytest.raises(EvolutionConfigError, match="cannot be split into 4"):
        islands("--population", "50", "--preset", "islands")
    for population in range(1, 2000):
        k = default_islands(population, 4)
        assert population % k == 0 and (k == 1 or population // k >= ISLAND_LEAST)


def test_a_resume_with_the_default_preset_keeps_its_islands(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run of the default preset with --population 50 has 2 islands; resuming it with
    --preset default and the same settings is not a change (the islands follow the
    population, as when it started), while another population is."""
    from skillcompose.cli import main

    d = tmp_path / "run"
    assert main(["evolve", "examples.toy_task", "--population", "50", "--generations", "1",
                 "--initial-nodes", "4", "--out", str(d), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["evolve", "--resume", str(d), "--preset", "default", "--population", "50",
                 "--initial-nodes", "4", "--generations", "2", "--quiet"]) == 0, \
        capsys.readouterr().err
    assert main(["evolve", "--resume", str(d), "--preset", "default", "--population", "60",
                 "--generations", "3", "--quiet"]) == 2
    assert "--population 60 (the run has 50)" in capsys.readouterr().err


_CONFIRMING = EvolutionConfig(population=40, initial_nodes=8, generations=12, islands=2,
                              elitism=1, trials=1, unique_children=True, cache=True,
                              cache_refresh=1, confirm_trials=30, confirm_rate=1.0,
                              checkpoint_every=2)
"""Island runs of the toy task (p_fail 0.3, tolerance 0.5) whose seed 1 fails confirmations."""


def _the_same_anywhere_and_resumed(cfg: EvolutionConfig, tmp_path: Path,
                                   solved_in: int) -> EvolutionResult:
    """Seed 1 of ``cfg``: solved in generation ``solved_in``, the same on a pool of two and
    resumed from a checkpoint of generation 6. Returns the serial run."""
    task = load_task("examples.toy_task", p_fail=0.3, tolerance=0.5)
    serial = evolve(task, cfg, seed=1, backend="serial", simplify_result=False,
                    check_trials=0)
    two = evolve(task, cfg, seed=1, backend="process", workers=2, simplify_result=False,
                 check_trials=0)
    assert serial.solved and serial.generations == solved_in
    assert _run(serial) == _run(two)
    short = evolve(task, cfg.replace(generations=6), seed=1, out_dir=tmp_path / "run",
                   simplify_result=False, check_trials=0)
    assert not short.solved and short.generations == 6
    resumed = evolve(task, cfg, resume=tmp_path / "run")
    assert _run(resumed) == _run(serial)
    return serial


@pytest.mark.slow
def test_failed_confirmations_fed_back_are_the_same_run_anywhere_and_after_resume(
        tmp_path: Path) -> None:
    """Seed 1 fails its confirmation in generations 4, 5, 7, 8, 9 and 10 and is solved in
    11: the feedback (population and cache) is the same on every backend and resumes."""
    _the_same_anywhere_and_resumed(_CONFIRMING.replace(confirm_feedback=True), tmp_path, 11)


@pytest.mark.slow
def test_several_candidates_confirmed_are_the_same_run_anywhere_and_after_resume(
        tmp_path: Path) -> None:
    """Seed 1 with three candidates a generation: failed confirmations in generations 4, 5
    and 7-9 (up to three a generation), none in 6 (every genome at the target had failed
    before), solved in 10. The memory of failed genomes is checkpointed: the run is the same
    on a pool and resumed from generation 6."""
    cfg = _CONFIRMING.replace(confirm_candidates=3)
    serial = _the_same_anywhere_and_resumed(cfg, tmp_path, 10)
    # without the memory (one candidate, confirmed again while it stays the best) the
    # same seed is another run
    task = load_task("examples.toy_task", p_fail=0.3, tolerance=0.5)
    assert _run(evolve(task, cfg.replace(confirm_candidates=0), seed=1, backend="serial",
                       simplify_result=False, check_trials=0)) != _run(serial)
