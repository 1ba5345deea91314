from __future__ import annotations

import os

import matplotlib
import pytest

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")


# -- parallel workers (pytest-xdist, `--dist loadgroup` in pyproject) ------------------------------
# A file's tests run in one worker (its module fixtures, a viewer or an evolution, are built
# once), and every test that starts Ray or a network namespace in one group of their own, so
# that two Ray clusters never share the machine's cores at once. The marks are set before
# pytest-xdist's own hook appends each test's group to its node id (test@group), the one thing
# its scheduler reads (tests/test_groups.py checks that it is there). The groups are handed
# out in the order of the items, so the longest go first (the Ray group, then by their number
# of slow tests) and the many short files even out the workers' ends.
HEAVY = "ray-and-namespaces"


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    groups: dict[str, str] = {}
    slow: dict[str, int] = {}
    for item in items:
        heavy = item.get_closest_marker("ray") or item.get_closest_marker("private_network")
        group = HEAVY if heavy else item.nodeid.split("::", 1)[0]
        item.add_marker(pytest.mark.xdist_group(group))
        groups[item.nodeid] = group
        slow[group] = slow.get(group, 0) + (item.get_closest_marker("slow") is not None)
    items.sort(key=lambda item: (groups[item.nodeid] != HEAVY, -slow[groups[item.nodeid]]))


# -- tests that start Ray on this machine ------------------------------------------------------
# A Ray started without a cluster (ray.init) listens on every interface in the Ray versions we
# support, and offers no setting that keeps it on 127.0.0.1. So a test marked
# ``private_network`` runs in a child pytest inside a network namespace of its own (loopback
# only; ``unshare --net``, as root): nothing it listens on can be reached from elsewhere.
# Without such a namespace the test is skipped, never run in the open.

_INSIDE = "SKILLCOMPOSE_TEST_PRIVATE_NET"


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> bool | None:
    if pyfuncitem.get_closest_marker("private_network") is None or os.environ.get(_INSIDE):
        return None  # an ordinary test, or already inside the namespace: run it here
    import subprocess
    import sys

    from skillcompose.evolve.ray_local import PRIVATE_NET, private_network

    if not private_network():
        pytest.skip("starts Ray, which listens on every interface: needs a private network "
                    "namespace (unshare --net, as root)")
    root = str(pyfuncitem.config.rootpath)
    done = subprocess.run(
        [*PRIVATE_NET, sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider",
         "-n", "0", pyfuncitem.nodeid.removesuffix(f"@{HEAVY}")],
        cwd=root, env={**os.environ, _INSIDE: "1"}, capture_output=True, text=True,
        timeout=900, check=False)
    skipped = [line for line in done.stdout.splitlines() if line.startswith("SKIPPED")]
    if done.returncode == 0 and " passed" not in done.stdout and skipped:
        pytest.skip(f"in the private network namespace: {skipped[-1]}")
    tail = (done.stdout + done.stderr)[-4000:]
    assert done.returncode == 0 and " passed" in done.stdout, tail
    return True  # the test ran (and passed) in the namespace
