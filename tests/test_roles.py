"""Joint roles from the kinematic tree (wbc.roles): any names, overrides, refusals, no Bioloid
names left in the controller."""

from __future__ import annotations

import ast
import re
import tokenize
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from wbc.exceptions import ModelError
from wbc.model import STANDARD_FRAMES, load_robot
from wbc.paths import robots_dir
from wbc.roles import LEG_ROLES
from wbc.urdf_writer import transform_urdf

BIOLOID_URDF = robots_dir() / "bioloid" / "bioloid.urdf"
#: ROBOTIS's OP3 joint names for the Bioloid's joints
OP3 = {
    "hip_yaw": "hip_yaw",
    "hip_roll": "hip_roll",
    "hip_pitch": "hip_pitch",
    "knee": "knee",
    "ankle_pitch": "ank_pitch",
    "ankle_roll": "ank_roll",
    "shoulder_pitch": "sho_pitch",
    "shoulder_roll": "sho_roll",
    "elbow": "el",
}


def bioloid_names() -> tuple[list[str], list[str]]:
    root = ET.parse(BIOLOID_URDF).getroot()
    joints = [j.get("name") for j in root.iter("joint") if j.get("type") != "fixed"]
    links = [lk.get("name") for lk in root.iter("link")]
    return joints, links


def write_robot(folder: Path, text: str, toml: str = "") -> Path:
    folder.mkdir()
    (folder / f"{folder.name}.urdf").write_text(text)
    if toml:
        (folder / "robot.toml").write_text(toml)
    return folder


def renamed(prefix: str = "J") -> dict[str, str]:
    """Every Bioloid joint and link (but the standard frames) renamed."""
    joints, links = bioloid_names()
    out = {j: f"{prefix}{i}" for i, j in enumerate(joints)}
    out.update({lk: f"link{i}" for i, lk in enumerate(links) if lk not in STANDARD_FRAMES})
    for lk in ("l_hand", "r_hand"):
        out.pop(lk)
    return out


def test_bioloid_and_kokone_roles_match_their_names():
    for name in ("bioloid", "kokone"):
        robot = load_robot(name)
        for side, p in (("left", "l"), ("right", "r")):
            assert robot.roles.leg(side) == tuple(f"{p}_{r}" for r in LEG_ROLES)
            assert robot.roles.joint(side, "shoulder_roll") == f"{p}_shoulder_roll"
    kokone = load_robot("kokone")
    assert set(kokone.roles.arm("left")) == {
        "l_shoulder_pitch",
        "l_shoulder_roll",
        "l_elbow_yaw",
        "l_elbow_pitch",
    }


def test_renamed_joints_get_the_same_roles(tmp_path):
    names = renamed()
    robot = load_robot(
        write_robot(tmp_path / "anon", transform_urdf(BIOLOID_URDF.read_text(), 1.0, names))
    )
    bioloid = load_robot("bioloid")
    for side in ("left", "right"):
        assert robot.roles.leg(side) == tuple(names[j] for j in bioloid.roles.leg(side))
        assert robot.roles.arm(side) == tuple(names[j] for j in bioloid.roles.arm(side))


def test_op3_names(tmp_path):
    joints, _ = bioloid_names()
    names = {j: j[:2] + OP3[j[2:]] for j in joints}
    robot = load_robot(
        write_robot(tmp_path / "op3ish", transform_urdf(BIOLOID_URDF.read_text(), 1.0, names))
    )
    assert robot.roles.leg("left") == (
        "l_hip_yaw", "l_hip_roll", "l_hip_pitch", "l_knee", "l_ank_pitch", "l_ank_roll"
    )  # fmt: skip
    assert robot.roles.joint("right", "elbow") == "r_el"


def _knee_about_x(text: str) -> str:
    root = ET.fromstring(text)
    for joint in root.iter("joint"):
        if joint.get("name") == "l_knee":
            joint.find("axis").set("xyz", "1 0 0")
    return ET.tostring(root, encoding="unicode")


def test_a_leg_that_cannot_be_parsed_is_refused_in_one_line(tmp_path):
    robot = load_robot(write_robot(tmp_path / "odd", _knee_about_x(BIOLOID_URDF.read_text())))
    with pytest.raises(ModelError) as err:
        robot.roles  # noqa: B018
    msg = str(err.value)
    assert "\n" not in msg
    assert "cannot understand the left leg" in msg and "2 pitch joints" in msg
    assert "[joints.left]" in msg


def test_robot_toml_names_the_roles_of_an_odd_leg(tmp_path):
    roles = "\n".join(f'{r} = "l_{r}"' for r in LEG_ROLES)
    folder = write_robot(
        tmp_path / "odd", _knee_about_x(BIOLOID_URDF.read_text()), f"[joints.left]\n{roles}\n"
    )
    robot = load_robot(folder)
    assert robot.roles.joint("left", "knee") == "l_knee"
    assert ("left", "knee") in robot.roles.named


def test_robot_toml_roles_are_checked(tmp_path):
    folder = write_robot(
        tmp_path / "bad", BIOLOID_URDF.read_text(), '[joints.left]\nknee = "no_such_joint"\n'
    )
    with pytest.raises(ModelError, match=r"\[joints.left\] knee = 'no_such_joint'"):
        load_robot(folder)


def test_robot_check_prints_the_roles(capsys):
    from wbc.robot_folder import check_folder

    text = "\n".join(str(f) for f in check_folder(robots_dir() / "kokone"))
    assert "left leg: hip_yaw=l_hip_yaw" in text
    assert "also l_elbow_yaw" in text
    assert "feet 70.0 x 40.0 mm" in text


def test_no_bioloid_joint_or_link_name_in_the_controller():
    joints, links = bioloid_names()
    # the project's own frame names (wbc.model.STANDARD_FRAMES and the hands) are not Bioloid's
    names = set(joints + links) - {*STANDARD_FRAMES, "l_hand", "r_hand"}
    pattern = re.compile(
        r"(?<![A-Za-z0-9_])("
        + "|".join(sorted(names, key=len, reverse=True))
        + r")(?![A-Za-z0-9_])"
    )
    wbc = Path(__file__).resolve().parent.parent / "wbc"
    hits = [
        f"{p.relative_to(wbc)}:{i + 1}: {m.group(1)}"
        for p in sorted(wbc.rglob("*"))
        if p.is_file() and p.suffix in (".py", ".toml", ".md", ".txt", ".json")
        for i, line in enumerate(p.read_text(encoding="utf-8").splitlines())
        for m in pattern.finditer(line)
    ]
    assert not hits, hits


def _strings(value: object) -> list[str]:
    """Every string in a parsed TOML value (keys and values, nested)."""
    if isinstance(value, str):
        return [value]
    if isinstance(value, dict):
        return [s for k, v in value.items() for s in (k, *_strings(v))]
    if isinstance(value, list):
        return [s for v in value for s in _strings(v)]
    return []


def test_no_bioloid_joint_or_link_name_in_the_stack_files():
    """The stack files (tasks/, what any robot runs) name no Bioloid joint or link: their
    self-collision pairs and frames are chosen per robot (issue 29, item 4); comments aside."""
    from wbc.paths import stacks_dir

    joints, links = bioloid_names()
    names = set(joints + links) - {*STANDARD_FRAMES, "l_hand", "r_hand"}
    hits = [
        f"{path.name}: {s}"
        for path in sorted(stacks_dir().rglob("*.toml"))
        for s in _strings(tomllib.loads(path.read_text()))
        if s in names
    ]
    assert not hits, hits
    assert len(list(stacks_dir().glob("*.toml"))) >= 8


#: the names the Bioloid's dimensions had in wbc/ (wbc.geometry, wbc.walking.legs, the viewer)
BIOLOID_CONSTANTS = (
    "FOOT_LENGTH", "FOOT_WIDTH", "THIGH", "SHIN", "HIP_HALF_WIDTH", "ANKLE_HEIGHT",
    "DEFAULT_SOLE_RECT",
)  # fmt: skip


def bioloid_dimensions() -> set[float]:
    """The Bioloid's dimensions (m, rad) as wbc measured and stated them: every number of its
    robot.toml [legs], its leg (thigh + shin), its foot and their halves."""
    legs = tomllib.loads((BIOLOID_URDF.parent / "robot.toml").read_text())["legs"]
    values = {abs(float(x)) for v in legs.values() for x in (v if isinstance(v, list) else [v])}
    length, width = load_robot("bioloid").foot_size
    return values | {legs["thigh"] + legs["shin"], length, width, length / 2, width / 2}


def bioloid_dimensions_in(package: Path) -> list[str]:
    """Where a Python file of ``package`` writes one of :func:`bioloid_dimensions` as a number
    or names one of :data:`BIOLOID_CONSTANTS` (code only: docstrings and comments may say
    what the Bioloid measures)."""
    values, hits = bioloid_dimensions(), []
    for path in sorted(package.rglob("*.py")):
        with open(path, "rb") as f:
            for tok in tokenize.tokenize(f.readline):
                number = ast.literal_eval(tok.string) if tok.type == tokenize.NUMBER else None
                if (isinstance(number, float) and number in values) or (
                    tok.type == tokenize.NAME and tok.string in BIOLOID_CONSTANTS
                ):
                    hits.append(f"{path.relative_to(package)}:{tok.start[0]}: {tok.string}")
    return hits


def test_no_bioloid_dimension_in_the_controller():
    """The walking design robot's sizes are data (tasks/walking/design.toml), a robot's come
    from its model or folder: no Bioloid length or angle is written in wbc/."""
    assert len(bioloid_dimensions()) >= 12
    hits = bioloid_dimensions_in(Path(__file__).resolve().parent.parent / "wbc")
    assert not hits, hits


def test_walking_a_robot_with_an_odd_leg_says_why_in_one_line(tmp_path, capsys):
    from wbc.cli import main

    folder = write_robot(tmp_path / "odd", _knee_about_x(BIOLOID_URDF.read_text()))
    assert main(["walk", "--robot", str(folder), "--trajectory", "walk10"]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if "note:" not in line]
    assert len(err) == 1 and "cannot understand the left leg" in err[0], err


def test_the_walking_design_robot_is_data(tmp_path, monkeypatch):
    """The robot the walking defaults were tuned on is read from tasks/walking/design.toml: the
    Bioloid, whose own measurements give λ = μ = 1; a bad file is refused in one line."""
    from wbc import roles
    from wbc.exceptions import ConfigurationError
    from wbc.walking.legs import LegGeometry

    design = roles.design_robot()
    assert design.robot == "bioloid"
    bioloid = load_robot("bioloid")
    legs = LegGeometry.from_robot(bioloid)
    assert roles.leg_ratio(legs.thigh + legs.shin) == 1.0 == roles.length_unit(bioloid)
    assert design.foot_width == bioloid.foot_size[1]
    assert roles.leg_length(2.0) == 2.0 * (design.thigh + design.shin)
    folder = tmp_path / "tasks"
    (folder / "walking").mkdir(parents=True)
    monkeypatch.setattr(roles, "stacks_dir", lambda: folder)
    read = roles.design_robot.__wrapped__  # (the package's file is read once and kept)
    for text, message in (
        ('robot = "x"\nthigh = 0.1\nshin = 0.1\n', r"foot_width = None: a length in \(0, 1\) m"),
        ('robot = "x"\nthigh = 0.1\nshin = -1\nfoot_width = 0.1\n', "shin = -1"),
        ('robot = "x"\nthigh = 0.1\nshin = 0.1\nfoot_width = 0.1\nhip = 1\n', "unknown keys"),
        ("thigh = 0.1\nshin = 0.1\nfoot_width = 0.1\n", "robot = None"),
    ):
        (folder / roles.DESIGN_FILE).write_text(text)
        with pytest.raises(ConfigurationError, match=message) as exc:
            read()
        assert "\n" not in str(exc.value) and "design.toml" in str(exc.value)
