"""The suite's worker groups (tests/conftest.py) reach pytest-xdist's scheduler."""
from __future__ import annotations

import pytest


def test_a_test_carries_its_group_to_the_scheduler(request: pytest.FixtureRequest) -> None:
    """Under `--dist loadgroup` (pyproject's addopts) a test's node id ends with its group:
    that tag is all the scheduler reads to keep a file's tests in one worker and the Ray tests
    in one more. A pytest that drops it (9.2 with pytest-xdist 3.8) spreads every file over
    every worker and starts two Ray clusters at once, without a word."""
    if not getattr(request.config.option, "loadgroup", False):  # set in xdist workers only
        pytest.skip("not run by pytest-xdist with --dist loadgroup: no groups to keep")
    assert request.node.nodeid.endswith("@tests/test_groups.py"), request.node.nodeid
