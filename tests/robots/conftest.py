"""Shared fixtures for the robot tests (loaded once per session)."""

from __future__ import annotations

import pytest

from skillcompose.robots.model import RobotModel, load_pr2


@pytest.fixture(scope="session")
def pr2() -> RobotModel:
    return load_pr2()
