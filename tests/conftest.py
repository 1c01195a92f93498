"""Shared fixtures: one robot model per test session."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import settings

from wbc import load_robot

# derandomised and without the example database: every run checks the same examples
settings.register_profile("ci", max_examples=40, deadline=None, derandomize=True, database=None)
settings.register_profile("dev", max_examples=40, deadline=None)
settings.load_profile("ci")


@pytest.fixture(scope="session")
def robot():
    return load_robot("bioloid")


@pytest.fixture()
def rng():
    return np.random.default_rng(12345)
