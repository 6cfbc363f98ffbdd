"""Shared pytest configuration: the ``slow`` marker (tests over ~20 s; CI runs them all)."""

from __future__ import annotations

import pytest


def pytest_configure(config: pytest.Config) -> None:
    """Register the markers used across the suite."""
    config.addinivalue_line("markers", "slow: takes more than ~20 s (deselect with -m 'not slow')")
