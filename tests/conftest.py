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
    _skip_without_a_namespace(items)


# -- tests that start Ray on this machine ------------------------------------------------------
# A Ray started without a cluster (ray.init) listens on every interface in the Ray versions we
# support, and offers no setting that keeps it on 127.0.0.1. So the tests marked
# ``private_network`` run in a child pytest inside a network namespace of its own (loopback
# only; ``unshare --net``, as root): nothing they listen on can be reached from elsewhere.
# Without such a namespace they are skipped before their fixtures run (a fixture may start
# Ray itself), never run in the open.
#
# All of them run in one child pytest, started by the first of them this process reaches: one
# interpreter and one collection instead of one per test. The child writes each of its reports
# as pytest-xdist ships them (pytest_report_to_serializable), and the parent logs them under
# its own tests' names, so outcomes, skip reasons, tracebacks and durations are the child's.
# A test the child never reported (it crashed or ran out of time) fails with the child's output.

_INSIDE = "SKILLCOMPOSE_TEST_PRIVATE_NET"
_REPORTS = "SKILLCOMPOSE_TEST_REPORTS"
_BATCH_TIMEOUT = 900  # seconds for every namespace test together (they take about a minute)
_batch: dict[str, list[pytest.TestReport]] | None = None  # node id -> reports, once run
_batch_output = ""


def _plain(nodeid: str) -> str:
    return nodeid.removesuffix(f"@{HEAVY}")


def _in_namespace(item: pytest.Item) -> bool:
    """Whether this process must hand ``item`` to the namespace rather than run it."""
    return item.get_closest_marker("private_network") is not None and not os.environ.get(_INSIDE)


def _skip_without_a_namespace(items: list[pytest.Item]) -> None:
    if not any(_in_namespace(item) for item in items):
        return
    from skillcompose.evolve.ray_local import private_network

    if not private_network():
        skip = pytest.mark.skip(reason="starts Ray, which listens on every interface: needs a "
                                       "private network namespace (unshare --net, as root)")
        for item in items:
            if _in_namespace(item):
                item.add_marker(skip)


def _run_batch(session: pytest.Session) -> dict[str, list[pytest.TestReport]]:
    import json
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    from skillcompose.evolve.ray_local import PRIVATE_NET

    global _batch_output
    config = session.config
    nodeids = [_plain(item.nodeid) for item in session.items if _in_namespace(item)]
    with tempfile.TemporaryDirectory(prefix="skillcompose-netns-") as tmp:
        out = Path(tmp) / "reports.jsonl"
        try:
            done = subprocess.run(
                [*PRIVATE_NET, sys.executable, "-m", "pytest", "-q", "-rs", "-p",
                 "no:cacheprovider", "-n", "0", *nodeids],
                cwd=str(config.rootpath), env={**os.environ, _INSIDE: "1", _REPORTS: str(out)},
                capture_output=True, text=True, timeout=_BATCH_TIMEOUT, check=False)
            _batch_output = (done.stdout + done.stderr)[-4000:]
        except subprocess.TimeoutExpired as late:
            text = (late.stdout or b"") + (late.stderr or b"")
            tail = text.decode(errors="replace") if isinstance(text, bytes) else text
            _batch_output = (f"the namespace's pytest ran past {_BATCH_TIMEOUT} s and was "
                             f"killed\n" + tail[-4000:])
        lines = out.read_text().splitlines() if out.exists() else []
    reports: dict[str, list[pytest.TestReport]] = {}
    for line in lines:
        report = config.hook.pytest_report_from_serializable(config=config, data=json.loads(line))
        if isinstance(report.longrepr, list):  # a skip's (path, line, reason), a list in JSON
            report.longrepr = tuple(report.longrepr)
        reports.setdefault(_plain(report.nodeid), []).append(report)
    return reports


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """Inside the namespace's child pytest: each report, for the parent (see above)."""
    if _reports_to:
        import json

        config, path = _reports_to[0]
        data = config.hook.pytest_report_to_serializable(config=config, report=report)
        with open(path, "a", encoding="utf-8") as out:
            out.write(json.dumps(data) + "\n")


_reports_to: list[tuple[pytest.Config, str]] = []  # the child's config and its reports' file


def pytest_configure(config: pytest.Config) -> None:
    path = os.environ.pop(_REPORTS, None)  # taken, so that no pytest a test starts writes there
    if path and os.environ.get(_INSIDE):
        _reports_to[:] = [(config, path)]


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> bool | None:
    if not _in_namespace(item) or item.get_closest_marker("skip") is not None:
        return None  # an ordinary test, inside the namespace already, or skipped without one
    global _batch
    if _batch is None:
        _batch = _run_batch(item.session)
    ihook = item.ihook
    ihook.pytest_runtest_logstart(nodeid=item.nodeid, location=item.location)
    reports = _batch.get(_plain(item.nodeid), [])
    if not any(report.when == "teardown" for report in reports):  # never finished there
        keywords = dict.fromkeys(item.keywords, 1)
        missing = (f"no report from the private network namespace's pytest for this test; "
                   f"its output:\n{_batch_output}")
        reports = [
            pytest.TestReport(item.nodeid, item.location, keywords, "failed", missing, "setup",
                              [], 0.0),
            pytest.TestReport(item.nodeid, item.location, keywords, "passed", None, "teardown",
                              [], 0.0)]
    for report in reports:
        report.nodeid, report.location = item.nodeid, item.location
        ihook.pytest_runtest_logreport(report=report)
    ihook.pytest_runtest_logfinish(nodeid=item.nodeid, location=item.location)
    return True
