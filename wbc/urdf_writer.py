"""Write box-model URDF links: what a robot folder's ``make_urdf.py`` generator shares.

A small servo humanoid's model is a tree of links, each a point of mass with a solid-box
inertia and a few boxes to draw and to collide with. The generators of ``robots/bioloid`` and
``robots/kokone`` (and a user's own robot) build :class:`Link` values in SI units and write them
with :func:`link_xml`; the joints stay in each generator, since their conventions differ.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

Vec3 = tuple[float, float, float]


def box_inertia(mass: float, size: Vec3) -> Vec3:
    r"""Principal inertias of a solid box of mass ``m`` and size ``(x, y, z)``.

    :math:`I_{xx} = m (y^2 + z^2) / 12`, and so on by symmetry.
    """
    x, y, z = size
    return (
        mass * (y * y + z * z) / 12.0,
        mass * (x * x + z * z) / 12.0,
        mass * (x * x + y * y) / 12.0,
    )


@dataclass(frozen=True)
class Link:
    """One URDF link in SI units: mass (kg), CoM (m, link frame), inertias ``(ixx, iyy, izz)``
    and products ``(ixy, ixz, iyz)`` about the CoM (kg·m²), and its boxes ``(centre m, size m,
    material name)``."""

    name: str
    mass: float
    com: Vec3
    inertia: Vec3
    boxes: list[tuple[Vec3, Vec3, str]] = field(default_factory=list)
    products: Vec3 = (0.0, 0.0, 0.0)
    #: collision boxes ``(centre, size)`` if they differ from the visual ``boxes``
    collision: list[tuple[Vec3, Vec3]] | None = None

    @classmethod
    def scaled(
        cls,
        name: str,
        mass: float,
        com: Iterable[float],
        inertia_box: Iterable[float],
        boxes: Iterable[tuple[Iterable[float], Iterable[float], str]],
        length_unit: float,
    ) -> Link:
        """A link from lengths in ``length_unit`` metres (1e-3 for mm, 1e-2 for cm); its
        inertia is the solid box ``inertia_box`` of mass ``mass`` (kg)."""

        def m(values: Iterable[float]) -> Vec3:
            x, y, z = (v * length_unit for v in values)
            return (x, y, z)

        return cls(
            name,
            mass,
            m(com),
            box_inertia(mass, m(inertia_box)),
            [(m(centre), m(size), material) for centre, size, material in boxes],
        )


def fmt(values: Iterable[float]) -> str:
    """Numbers as URDF writes them: six significant digits, exact zeros for |v| <= 1e-12."""
    return " ".join(f"{v:.6g}" if abs(v) > 1e-12 else "0" for v in values)


def link_xml(link: Link, collision_inset: float = 0.0) -> str:
    """The ``<link>`` element: inertial, then a visual and a collision box per box; each
    collision box is ``collision_inset`` metres inside its visual box on every side."""
    ixx, iyy, izz = link.inertia
    ixy, ixz, iyz = (f"{v:.6g}" if v else "0" for v in link.products)
    out = [f'  <link name="{link.name}">', "    <inertial>"]
    out.append(f'      <origin xyz="{fmt(link.com)}" rpy="0 0 0"/>')
    out.append(f'      <mass value="{link.mass:.6g}"/>')
    out.append(
        f'      <inertia ixx="{ixx:.6g}" ixy="{ixy}" ixz="{ixz}" iyy="{iyy:.6g}" iyz="{iyz}" '
        f'izz="{izz:.6g}"/>'
    )
    out.append("    </inertial>")
    visual = [(centre, size, "visual", material) for centre, size, material in link.boxes]
    collision = [(c, s, "collision", "") for c, s, _ in link.boxes]
    if link.collision is not None:
        collision = [(c, s, "collision", "") for c, s in link.collision]
    order = visual + collision if link.collision is not None else _interleave(visual, collision)
    for centre, size, tag, material in order:
        box = size if tag == "visual" else tuple(v - 2 * collision_inset for v in size)
        out.append(f"    <{tag}>")
        out.append(f'      <origin xyz="{fmt(centre)}" rpy="0 0 0"/>')
        out.append(f'      <geometry><box size="{fmt(box)}"/></geometry>')
        if tag == "visual":
            out.append(f'      <material name="{material}"/>')
        out.append(f"    </{tag}>")
    out.append("  </link>")
    return "\n".join(out)


def _interleave(a: list, b: list) -> list:
    """a[0], b[0], a[1], b[1], ... (each box's visual, then its collision)."""
    return [x for pair in zip(a, b, strict=True) for x in pair]


def transform_urdf(
    text: str,
    scale: float | Callable[[str], float] = 1.0,
    rename: Mapping[str, str] | None = None,
    torque_exponent: float = 4.0,
    speed_exponent: float = 0.0,
) -> str:
    """A URDF with its lengths scaled and its joints and links renamed.

    ``scale``: one factor, or a function of the link name. A link scaled by ``s`` has its
    geometry, inertial origin and the origin of the joint above it scaled by ``s``, its mass by
    ``s³`` and its inertia by ``s⁵`` (a geometrically similar body of the same density); the
    joint above it has its effort limit scaled by ``s**torque_exponent`` (``s⁴``: the same
    share of the torque gravity asks for) and its velocity limit by ``s**speed_exponent``
    (``s^-½``: the same motion, slowed by ``√s`` as a pendulum ``s`` times as long).
    ``rename``: old -> new name, for joints and links.
    """
    import xml.etree.ElementTree as ET

    names = dict(rename or {})
    factor = scale if callable(scale) else (lambda _name, s=float(scale): s)
    root = ET.fromstring(text)

    def _num(v: float) -> str:
        return repr(float(v))

    def scaled(values: str | None, s: float) -> str:
        return " ".join(_num(float(v) * s) for v in (values or "0 0 0").split())

    for link in root.iter("link"):
        s = factor(link.get("name", ""))
        for origin in link.iter("origin"):
            origin.set("xyz", scaled(origin.get("xyz"), s))
        for mass in link.iter("mass"):
            mass.set("value", _num(float(mass.get("value", "0")) * s**3))
        for inertia in link.iter("inertia"):
            for key, value in inertia.attrib.items():
                inertia.set(key, _num(float(value) * s**5))
        for box in link.iter("box"):
            box.set("size", scaled(box.get("size"), s))
        for shape in (*link.iter("cylinder"), *link.iter("sphere")):
            for key in ("radius", "length"):
                if key in shape.attrib:
                    shape.set(key, _num(float(shape.attrib[key]) * s))
        for mesh in link.iter("mesh"):
            mesh.set("scale", scaled(mesh.get("scale", "1 1 1"), s))
        link.set("name", names.get(link.get("name", ""), link.get("name", "")))
    for joint in root.iter("joint"):
        child = joint.find("child")
        s = factor(child.get("link", "")) if child is not None else 1.0
        origin = joint.find("origin")
        if origin is not None:
            origin.set("xyz", scaled(origin.get("xyz"), s))
        limit = joint.find("limit")
        if limit is not None and "effort" in limit.attrib:
            limit.set("effort", _num(float(limit.get("effort", "0")) * s**torque_exponent))
        if limit is not None and "velocity" in limit.attrib:
            limit.set("velocity", _num(float(limit.get("velocity", "0")) * s**speed_exponent))
        joint.set("name", names.get(joint.get("name", ""), joint.get("name", "")))
        for tag in ("parent", "child"):
            el = joint.find(tag)
            if el is not None:
                el.set("link", names.get(el.get("link", ""), el.get("link", "")))
        mimic = joint.find("mimic")
        if mimic is not None:
            mimic.set("joint", names.get(mimic.get("joint", ""), mimic.get("joint", "")))
    return ET.tostring(root, encoding="unicode") + "\n"
