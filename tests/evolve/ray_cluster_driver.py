"""Run by test_ray_cluster.py, in a private network namespace: starts a Ray cluster of two
nodes whose interpreter cannot import this project, evolves on it, and prints what it saw
as one line of JSON.

    python ray_cluster_driver.py WORK_DIR

The task module is written into ``WORK_DIR/task`` (on this driver's import path only), so
it and the skill it defines reach the workers through Ray's runtime environment alone.
The cluster's tag (see skillcompose.evolve.ray_local) is written to ``WORK_DIR/tag`` as soon as the
nodes start, for the test to stop whatever this script leaves behind.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import sysconfig
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from skillcompose import FSA

TASK_MODULE = '''
"""The toy task, each episode slowed by a few milliseconds, with one skill of its own."""
import time
from dataclasses import replace
from typing import Literal

from examples import toy_task
from skillcompose import Blackboard, Registry, skill


@skill
def wait_a_moment(bb: Blackboard, rng) -> Literal["success"]:
    """Do nothing for a moment."""
    time.sleep(0.001)
    return "success"


def make_task(delay: float = 0.0, **settings):
    base = toy_task.make_task(**settings)
    registry = Registry()
    toy_task.register(registry)
    registry.add(wait_a_moment)

    def setup(rng):
        time.sleep(delay)
        return base.setup(rng)

    return replace(base, registry=registry, setup=setup, name="shipped_toy")
'''


def without_delay(fsa: FSA) -> FSA:
    """The FSA with the delay left out of its record of the task's settings: the serial
    reference runs without it, since it only sleeps (the same episodes)."""
    evolved = dict(fsa.meta["evolved"])
    evolved["task_settings"] = {k: v for k, v in evolved["task_settings"].items()
                                if k != "delay"}
    return dataclasses.replace(fsa, meta={**fsa.meta, "evolved": evolved})


def main() -> None:
    work = Path(sys.argv[1])
    (work / "task").mkdir(parents=True, exist_ok=True)
    (work / "task" / "shipped_task.py").write_text(TASK_MODULE)
    sys.path.insert(0, str(work / "task"))
    sys.path.append(str(Path(__file__).resolve().parents[2]))  # the examples, for this driver
    os.chdir(work)

    from skillcompose.evolve import (
        EvolutionConfig,
        Job,
        RayEvaluator,
        SerialEvaluator,
        SkillSet,
        evolve,
        initialize,
    )
    from skillcompose.evolve.ray_local import local_cluster
    from skillcompose.task import load_task

    # the nodes: this interpreter without this environment's start-up files (which make
    # the project importable), its installed packages on PYTHONPATH, a directory of their own
    python = getattr(sys, "_base_executable", sys.executable)
    node_env = {k: v for k, v in os.environ.items()
                if k in ("PATH", "HOME", "LANG", "LC_ALL", "TMPDIR")}
    node_env["PYTHONPATH"] = sysconfig.get_paths()["purelib"]
    report: dict[str, object] = {}
    with local_cluster(2, python=python, env=node_env) as cluster:
        (work / "tag").write_text(cluster.tag)
        report["pids"] = cluster.pids()
        for module in ("skillcompose", "evolve", "examples", "shipped_task"):
            probe = subprocess.run([python, "-c", f"import {module}"], env=node_env,
                                   cwd=cluster.temp_dirs[0], capture_output=True, check=False)
            report[f"nodes import {module}"] = probe.returncode == 0
        os.environ.update(cluster.env)
        os.environ["RAY_ADDRESS"] = cluster.address
        import ray

        # tolerance 0: never solved, so the run goes on after the node is lost
        task = load_task("shipped_task", p_fail=0.2, delay=0.002, tolerance=0.0)
        skills = SkillSet.from_task(task)
        rng = __import__("numpy").random.default_rng(0)
        jobs = [Job.of(initialize(skills, rng, 10), 0, (1, 0, i), 2) for i in range(120)]
        serial = SerialEvaluator(task, skills).evaluate(jobs)
        ev = RayEvaluator(task, skills)
        try:
            report["workers"] = ev.workers
            report["cluster nodes"] = sorted(n["NodeID"] for n in ray.nodes())

            @ray.remote(num_cpus=0)
            def where() -> list[str]:
                import shipped_task

                import skillcompose

                return [skillcompose.__file__ or "", shipped_task.__file__ or ""]

            report["workers import from"] = ray.get(where.remote())
            got = ev.evaluate(jobs)
            report["jobs equal serial"] = got == serial
            report["nodes used"] = sorted(set(ev.nodes))
            report["jobs per node"] = sorted(ev.nodes.count(x) for x in set(ev.nodes))
            ev.groups = 2  # two islands: the first half of the jobs, the second half
            got = ev.evaluate(jobs)
            report["islands equal serial"] = got == serial
            halves = [ev.nodes[:60], ev.nodes[60:]]
            report["island homes"] = [max(set(h), key=h.count) for h in halves]
            report["island jobs at home"] = [max(h.count(x) for x in set(h)) for h in halves]
        finally:
            ev.close()

        # episodes slow enough (30 ms: a generation takes over a second on two nodes) that
        # the node dies with jobs of its own in flight, not between two generations
        task = load_task("shipped_task", p_fail=0.2, delay=0.03, tolerance=0.0)
        cfg = EvolutionConfig(population=40, trials=2, generations=5, initial_nodes=8,
                              elitism=1)
        t = time.perf_counter()
        # the serial reference without the delay (see without_delay)
        alone = evolve(load_task("shipped_task", p_fail=0.2, delay=0.0, tolerance=0.0), cfg,
                       seed=5, simplify_result=False, check_trials=0)
        report["serial run s"] = round(time.perf_counter() - t, 2)
        killed: list[float] = []

        def kill_second_node(rec: object) -> None:
            if getattr(rec, "generation", 0) == 2 and not killed:
                def kill() -> None:
                    killed.append(time.perf_counter())
                    cluster.kill(1)
                threading.Timer(0.4, kill).start()

        t = time.perf_counter()
        report["second node before"] = len(cluster.pids(1))
        on_ray = evolve(task, cfg, seed=5, backend="ray", simplify_result=False,
                        check_trials=0, on_generation=kill_second_node)
        end = time.perf_counter()
        report["ray run s"] = round(end - t, 2)
        report["killed in run"] = bool(killed) and killed[0] < end
        report["second node after"] = len(cluster.pids(1))
        report["generations"] = [len(alone.history), len(on_ray.history)]
        report["run equals serial"] = (
            [(r.best, r.mean, r.median, r.best_size) for r in alone.history]
            == [(r.best, r.mean, r.median, r.best_size) for r in on_ray.history]
            and without_delay(alone.best_fsa) == without_delay(on_ray.best_fsa))
        report["faults"] = on_ray.faults.to_dict()
        ray.shutdown()
    report["left running"] = cluster.pids()
    print(json.dumps(report))


if __name__ == "__main__":
    main()
