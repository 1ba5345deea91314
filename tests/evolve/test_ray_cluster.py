"""The Ray backend on a real cluster of two nodes, started by the test on this machine
inside a private network namespace (nothing it listens on is reachable from elsewhere),
with an interpreter that cannot import this project: the task module, its skills and the
project reach the workers through Ray's runtime environment alone."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from skillcompose.evolve.ray_local import PRIVATE_NET, private_network

pytestmark = [pytest.mark.slow, pytest.mark.ray]

DRIVER = Path(__file__).with_name("ray_cluster_driver.py")


def test_two_nodes_ship_the_code_share_the_work_and_survive_a_lost_node(
    tmp_path: Path,
) -> None:
    pytest.importorskip("ray")
    if not private_network():
        pytest.skip("needs a private network namespace (unshare --net, as root)")
    from skillcompose.evolve.ray_local import _tagged

    try:
        done = subprocess.run([*PRIVATE_NET, sys.executable, str(DRIVER), str(tmp_path)],
                              capture_output=True, text=True, timeout=600, check=False)
    finally:  # whatever the driver left running, by the cluster's tag
        tag_file = tmp_path / "tag"
        tag = tag_file.read_text() if tag_file.exists() else None
        left = sorted(_tagged(f"{tag}-")) if tag else []
        for pid in left:
            subprocess.run(["kill", "-9", str(pid)], check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert left == [] and report["left running"] == []  # no process outlived the cluster

    # the nodes cannot import the project or the task: what the workers ran was shipped
    for module in ("skillcompose", "evolve", "examples", "shipped_task"):
        assert report[f"nodes import {module}"] is False
    skillcompose_file, task_file = report["workers import from"]
    assert "runtime_resources" in skillcompose_file and "runtime_resources" in task_file

    # one actor per node, both did work, and the same fitnesses as serially
    assert report["workers"] == 2
    assert report["nodes used"] == report["cluster nodes"]
    assert min(report["jobs per node"]) > 0
    assert report["jobs equal serial"]

    # islands map onto nodes: with two groups of jobs, each runs (mostly: a node with nothing
    # left of its own helps the other) on a node of its own, with the same fitnesses
    assert report["islands equal serial"]
    assert sorted(report["island homes"]) == report["cluster nodes"]
    assert min(report["island jobs at home"]) > 30  # of 60

    # the second node killed in the middle of a run: its actor died, and the run is the
    # serial one all the same (its unfinished jobs ran again elsewhere, none scored worst)
    assert report["generations"] == [6, 6]  # the initial population and 5 generations
    assert report["killed in run"] and report["second node before"] > 0
    assert report["second node after"] == 0
    assert report["faults"]["worker_deaths"] >= 1
    assert report["faults"]["lost"] == 0
    assert report["run equals serial"]
