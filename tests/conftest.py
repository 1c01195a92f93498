"""Shared fixtures: one robot model per test session."""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

from wbc import load_robot

# the tests count and compare compiled ticks: from a cold cache, a solver waits for its compiled
# tick rather than solving on the numpy path while it is built (wbc.compiled.dispatch.WAIT_ENV)
os.environ.setdefault("WBC_WAIT_FOR_COMPILE", "1")

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


@pytest.fixture(scope="session")
def window(robot):
    """The Bioloid's whole-body balance window (coarse: 6 samples), built once."""
    from wbc.walking.window import BalanceWindow

    return BalanceWindow.from_robot(robot, samples=6)


@pytest.fixture(scope="session")
def start(robot):
    """The Bioloid standing in its stand pose (the walks' start)."""
    from wbc.walking import StandingState

    return StandingState.from_robot(robot)


@pytest.fixture(scope="session")
def stress_script():
    """benchmarks/stress.py as a module (its draws and stacks replay the stress trials)."""
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "stress.py"
    spec = importlib.util.spec_from_file_location("wbc_stress_benchmark", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module
