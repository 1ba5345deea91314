from __future__ import annotations

import pytest

from skillcompose import Registry
from tests.skillcompose import demo_skills


@pytest.fixture
def registry() -> Registry:
    return Registry.from_modules([demo_skills])
