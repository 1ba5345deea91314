"""Wall time of the command line: ``--help``, ``validate``, ``skills`` and a one-trial ``run``.

::

    python benchmarks/bench_cli.py            # 5 repetitions each, median and range
    python benchmarks/bench_cli.py --reps 11

Each command runs in a fresh process (``python -m skillcompose ...``), as a user's shell
would start it, so the time includes the interpreter's start and every import. The table
gives the median wall time, its range, and the median CPU time (user + system) of the
process: on a busy machine the wall time waits for a core and spreads, the CPU time does
not; on an idle one the two agree.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FSA = str(ROOT / "examples" / "pour_water_reference.fsa.yaml")

COMMANDS: list[tuple[str, list[str]]] = [
    ("python -c pass (the interpreter alone)", ["-c", "pass"]),
    ("skillcompose --help", ["-m", "skillcompose", "--help"]),
    ("skillcompose validate FILE", ["-m", "skillcompose", "validate", FSA]),
    ("skillcompose validate FILE --task T", ["-m", "skillcompose", "validate", FSA,
                                             "--task", "examples.pour_water"]),
    ("skillcompose skills --task T", ["-m", "skillcompose", "skills", "--task",
                                      "examples.pour_water"]),
    ("skillcompose run FILE --task T --trials 1", ["-m", "skillcompose", "run", FSA,
                                                   "--task", "examples.pour_water",
                                                   "--trials", "1"]),
    ("skillcompose robot --help", ["-m", "skillcompose", "robot", "--help"]),
]


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def times_s(argv: list[str], reps: int) -> tuple[list[float], list[float]]:
    """Wall and CPU times [s] of ``reps`` runs of ``python argv``."""
    wall, cpu = [], []
    for _ in range(reps):
        cpu_before = _children_cpu_s()
        start = time.perf_counter()
        proc = subprocess.run([sys.executable, *argv], cwd=ROOT, capture_output=True,
                              timeout=120)
        wall.append(time.perf_counter() - start)
        cpu.append(_children_cpu_s() - cpu_before)
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(argv)} failed: {proc.stderr.decode()[-500:]}")
    return wall, cpu


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--reps", type=int, default=5, help="runs of each command (default 5)")
    args = p.parse_args(argv)
    if args.reps < 1:
        p.error("--reps must be at least 1")
    print(f"{args.reps} runs each; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} "
          "CPUs at the start\n")
    print("| command | wall median [s] | wall min [s] | wall max [s] | CPU median [s] |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for name, command in COMMANDS:
        wall, cpu = times_s(command, args.reps)
        print(f"| `{name}` | {statistics.median(wall):.3f} | {min(wall):.3f} | "
              f"{max(wall):.3f} | {statistics.median(cpu):.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
