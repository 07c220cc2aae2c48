"""The core tests' registry: the default one plus the test-only node types, fresh per test."""

import pytest

from core_helpers import TEST_TYPES
from flowmc.plugins import default_registry


@pytest.fixture
def registry():
    reg = default_registry().copy()
    for cls in TEST_TYPES:
        reg.add(cls)
    return reg
