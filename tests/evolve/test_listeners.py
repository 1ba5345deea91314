"""The generational loop's listeners: the run directory persists, the progress line shows,
a caller's callback receives each generation, in that order, and none of them changes the
run."""

from __future__ import annotations

import io
import json
from pathlib import Path

from skillcompose.evolve import EvolutionConfig, GenerationRecord, evolve
from skillcompose.task import Task, load_task

CONFIG = EvolutionConfig(population=12, initial_nodes=4, generations=4, checkpoint_every=2)


def _task() -> Task:
    return load_task("examples.toy_task", p_fail=0.3, trials=2)


def test_the_callback_sees_each_generation_after_the_run_directory_wrote_it(
        tmp_path: Path) -> None:
    out = tmp_path / "run"
    seen: list[tuple[int, int]] = []

    def note(rec: GenerationRecord) -> None:  # history lines written when it is called
        lines = (out / "history.jsonl").read_text().splitlines()
        seen.append((rec.generation, json.loads(lines[-1])["generation"]))

    result = evolve(_task(), CONFIG, seed=3, out_dir=out, on_generation=note,
                    simplify_result=False, check_trials=0)
    assert seen == [(r.generation, r.generation) for r in result.history]
    assert (out / "best.yaml").is_file()


def test_listeners_do_not_change_the_run(tmp_path: Path) -> None:
    quiet = evolve(_task(), CONFIG, seed=3, simplify_result=False, check_trials=0)
    stream = io.StringIO()
    loud = evolve(_task(), CONFIG, seed=3, out_dir=tmp_path / "run", progress=stream,
                  on_generation=lambda rec: None, simplify_result=False, check_trials=0)
    assert [r.best for r in quiet.history] == [r.best for r in loud.history]
    assert quiet.best_genome.encode() == loud.best_genome.encode()
    assert "gen " in stream.getvalue()  # the progress line was shown

