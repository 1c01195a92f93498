"""The committed robot files: URDF = generator output, Annex A limit widths, masses."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest

from wbc.paths import robots_dir

BIOLOID = robots_dir() / "bioloid"


@pytest.fixture(scope="module")
def generator():
    spec = importlib.util.spec_from_file_location("make_urdf", BIOLOID / "make_urdf.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_committed_urdf_equals_generator_output(generator):
    assert (BIOLOID / "bioloid.urdf").read_text() == generator.build_urdf()


def test_joint_range_widths_equal_annex_a(robot, generator):
    sm = robot.servo_map
    for i, name in enumerate(robot.joint_names):
        thesis_name, lo, hi = generator.ANNEX_A[sm.specs[i].id]
        width = robot.q_max[i] - robot.q_min[i]
        assert width == pytest.approx(math.radians(hi - lo), abs=1e-8), (name, thesis_name)


def test_limits_map_back_to_annex_a_servo_degrees(robot, generator):
    sm = robot.servo_map
    ticks_lo = sm.angles_to_ticks_float(robot.q_min)
    ticks_hi = sm.angles_to_ticks_float(robot.q_max)
    for i in range(robot.n_joints):
        _, lo, hi = generator.ANNEX_A[sm.specs[i].id]
        got = sorted((np.array([ticks_lo[i], ticks_hi[i]]) - 512) * 300 / 1023)
        assert got == pytest.approx([lo, hi], abs=1e-6)


def test_masses_are_the_cad_set_not_the_x5_set(robot):
    masses = {
        robot.model.names[i]: robot.model.inertias[i].mass for i in range(robot.model.njoints)
    }
    assert masses["root_joint"] == pytest.approx(0.6954, abs=1e-4)  # torso
    assert robot.total_mass == pytest.approx(1.9144, abs=1e-4)
    for inertia in robot.model.inertias[1:]:
        eig = np.linalg.eigvalsh(inertia.inertia)
        assert np.all(eig > 0)
        # triangle inequality of principal moments (physically realisable)
        a, b, c = eig
        assert a + b >= c - 1e-12
