"""Registers the test-only node types per test inside registry.scoped(), so the registry stays clean."""

import pytest
from core_helpers import TEST_TYPES

from flowmc import registry
from flowmc.nodes import load_all


@pytest.fixture(autouse=True)
def clean_registry():
    load_all()
    with registry.scoped():
        for cls in TEST_TYPES:
            registry.register(cls)
        yield
    assert not any(t.startswith("test.") for t in registry.registered())
