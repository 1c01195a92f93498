"""The box-model URDF writer shared by the robots' generators."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from wbc.urdf_writer import Link, box_inertia, fmt, link_xml

positive = st.floats(1e-3, 10.0)


@given(positive, positive, positive, positive)
def test_box_inertia_is_a_solid_box(mass: float, x: float, y: float, z: float) -> None:
    ixx, iyy, izz = box_inertia(mass, (x, y, z))
    # principal inertias of a body obey the triangle inequality; a box meets it with
    # I_xx + I_yy - I_zz = m z^2 / 6
    assert np.isclose(ixx + iyy - izz, mass * z * z / 6.0)
    assert np.isclose(iyy + izz - ixx, mass * x * x / 6.0)
    assert np.isclose(ixx + izz - iyy, mass * y * y / 6.0)


def test_scaled_link_converts_units_and_xml_reads_back() -> None:
    link = Link.scaled(
        "shin", 0.2, (0, 0, -30), (40, 32, 60), [((0, 0, -30), (40, 32, 60), "servo")], 1e-3
    )
    assert link.com == (0.0, 0.0, -0.03)
    element = ET.fromstring(link_xml(link, collision_inset=0.001))
    assert element.get("name") == "shin"
    assert float(element.find("inertial/mass").get("value")) == 0.2
    visual = element.find("visual/geometry/box").get("size").split()
    collision = element.find("collision/geometry/box").get("size").split()
    np.testing.assert_allclose([float(v) for v in visual], [0.04, 0.032, 0.06])
    np.testing.assert_allclose([float(v) for v in collision], [0.038, 0.030, 0.058])
    assert element.find("visual/material").get("name") == "servo"
    assert element.find("collision/material") is None


def test_fmt_writes_exact_zeros() -> None:
    assert fmt([1e-13, -2.5e-3, 1.0]) == "0 -0.0025 1"
