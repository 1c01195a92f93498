"""Task types in stack files: one table (wbc.tasks.task.STACK_TYPES, written by register),
the package's types and a user's alike, and ``import = [...]`` naming the modules that define
a stack's own types, so that every command runs them."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from wbc import Kinematics, TaskError
from wbc.paths import stacks_dir
from wbc.stacks import build_stack, load_stack
from wbc.tasks import ComTask, Task
from wbc.tasks.task import STACK_TYPES, register

REPO = Path(__file__).resolve().parents[1]

#: a task type of one's own in one file: the CoM height (1 row), named ``{kind}`` in a stack
USER_TASKS = '''\
"""A task type of my own: the CoM height (1 row), nameable in a stack file."""

import numpy as np
from numba import njit

from wbc.tasks import Task


@njit(cache=True)
def com_height_rows(target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J):
    e[0] = target[0] - com[2]
    for k in range(Jcom.shape[1]):
        J[0, k] = Jcom[2, k]


class ComHeightTask(Task):
    dim = 1
    row_kernel = staticmethod(com_height_rows)
    target_fields = ("target",)
    stack_type = "{kind}"  # its `type` in stack files

    def __init__(self, robot, name="{kind}", gain=1.0, weight=1.0, mask=None):
        super().__init__(name, gain, weight, mask)
        self.target = np.zeros(1)

    def set_target_from(self, kin):  # the initial target: where the CoM is
        self.target[0] = kin.data.com[0][2]
'''


def _user_stack(folder: Path, module: str, kind: str, imports: str | None = None) -> Path:
    """``folder/<module>.py`` defining type ``kind``, and ``folder/my.toml``: the walk stack
    with a ``kind`` task beside the CoM's, importing ``module``."""
    (folder / f"{module}.py").write_text(USER_TASKS.format(kind=kind))
    walk = (stacks_dir() / "walk.toml").read_text()
    com = '    { type = "com", weight = 1000.0 },\n'
    assert com in walk
    walk = walk.replace(com, com + f'    {{ type = "{kind}", weight = 10.0 }},\n')
    walk = walk.replace('name = "walk"\n', f'name = "my"\nimport = {imports or [module]!r}\n')
    path = folder / "my.toml"
    path.write_text(walk.replace("'", '"'))
    return path


# ----------------------------------------------------------------------- the one table
def test_the_package_types_are_in_the_one_table():
    """Every type a shipped stack names is a class that names itself, in the one table."""
    for name, cls in STACK_TYPES.items():
        assert cls.__dict__["stack_type"] == name
    assert STACK_TYPES["com"] is ComTask
    assert {"contact", "frame_pose", "posture", "torso_orientation", "relative_position"} <= set(
        STACK_TYPES
    )
    with pytest.raises(TypeError):  # read-only: register() is its one writer
        STACK_TYPES["com"] = Task  # type: ignore[index]


def test_a_type_name_held_by_another_class_is_an_error_naming_both():
    """A user class named like a built-in was silently shadowed by it: now its definition
    fails, naming both classes, and the built-in keeps its name."""
    with pytest.raises(TaskError, match=r"'com' of .*\.Mine is already the type of "
                       r"wbc\.tasks\.com\.ComTask"):  # fmt: skip

        class Mine(Task):
            stack_type = "com"

    assert STACK_TYPES["com"] is ComTask

    class Other(ComTask):  # inherits "com": not registered unless asked, then refused
        pass

    with pytest.raises(TaskError, match=r"'com' of .*Other is already the type of .*ComTask"):
        register(Other)
    with pytest.raises(TaskError, match="stack_type must be a name"):

        class Bad(Task):
            stack_type = "no spaces"


def test_a_class_defined_again_replaces_itself():
    """The same module and qualified name (a notebook cell run again) is no collision."""

    def define() -> type:
        class Again(Task):
            stack_type = "test_defined_again"

        return Again

    first, second = define(), define()
    assert first is not second and STACK_TYPES["test_defined_again"] is second
    assert register(second) is second  # registering it again: nothing changes


# ------------------ task types named by their class
def _relative_spec(kind: str, **relative) -> dict:
    return {
        "solver": kind,
        "levels": [
            {"hard": True, "tasks": [{"type": "contact", "frame": "support"}]},
            {
                "tasks": [
                    {"type": "relative_position", "frame": "r_sole", "reference": "l_sole"}
                    | relative,
                    {"type": "posture", "weight": 1e-3},
                ]
            },
        ],
    }


@pytest.mark.parametrize("kind", ["weighted", "hierarchical"])
def test_a_task_class_with_a_stack_type_is_named_in_a_stack_file(robot, kind):
    """relative_position has no TASK_TYPES entry: its class's ``stack_type`` names it; the
    entry's keys reach its __init__, its target starts where the entry says (or at the
    current state), and the stack's tick runs on the compiled path and moves the sole."""
    from wbc.tasks.relative_position import RelativeFramePositionTask

    control = build_stack(_relative_spec(kind, target=[0.0, -0.08, 0.01]), robot)
    task = control.stack.task("relative_position_r_sole")
    assert isinstance(task, RelativeFramePositionTask)
    assert (task.frame, task.reference) == ("r_sole", "l_sole")
    np.testing.assert_array_equal(task.target, [0.0, -0.08, 0.01])
    q = robot.configuration("stand")
    kin = Kinematics(robot, q)
    before = np.abs(task.compute(kin)[1]).max()
    for _ in range(20):
        q = control.solver.step(q, 0.01)
    assert control.solver.fast is not None and control.solver.handed_back_ticks == 0
    assert np.abs(task.compute(Kinematics(robot, q))[1]).max() < 0.2 * before

    at_rest = build_stack(_relative_spec(kind), robot).stack.task("relative_position_r_sole")
    _, e = at_rest.compute(kin)  # no target given: the current relative position
    assert np.abs(e).max() < 1e-12


def test_a_task_type_defined_outside_the_package_joins_the_stack_files(robot):
    """A user's class (defined here) with a ``stack_type`` is nameable once defined."""
    from wbc.tasks import FramePositionTask

    class HandPosition(FramePositionTask):
        stack_type = "test_hand_position"

    spec = {"levels": [{"tasks": [{"type": "test_hand_position", "frame": "r_hand"}]}]}
    task = build_stack(spec, robot).stack.task("test_hand_position_r_hand")
    assert type(task) is HandPosition and task.frame == "r_hand"


def test_a_stack_type_entry_is_checked(robot):
    """Unknown keys and roles on a task without set_frame are one clear line each."""
    with pytest.raises(TaskError, match=r"relative_position.*unknown keys \['axis'\]"):
        build_stack(_relative_spec("weighted", axis=[1, 0, 0]), robot)
    with pytest.raises(TaskError, match=r"relative_position.*give a frame name"):
        build_stack(_relative_spec("weighted", frame="swing"), robot)
    with pytest.raises(TaskError, match=r"unknown task type 'nope'; known: \[.*relative_position"):
        build_stack({"levels": [{"tasks": [{"type": "nope"}]}]}, robot)


# ---------------------------------------------------------------------- import = [...]
def test_import_beside_the_stack_file(robot, tmp_path):
    """``import = ["module"]``: the module beside the file defines the type the stack names."""
    path = _user_stack(tmp_path, "test_user_tasks_a", "test_com_height_a")
    control = load_stack(path, robot)
    task = control.stack.task("test_com_height_a")
    assert type(task).__module__ == "test_user_tasks_a" and task.weight[0] == 10.0
    kin = Kinematics(robot, robot.configuration("stand"))
    assert task.target[0] == kin.data.com[0][2]  # its set_target_from: where the CoM is
    assert str(tmp_path) not in sys.path  # (on the path for the import only)
    assert load_stack(path, robot).stack.task("test_com_height_a") is not task  # loads again


def test_import_from_the_python_path(robot, tmp_path, monkeypatch):
    folder = tmp_path / "lib"
    folder.mkdir()
    _user_stack(folder, "test_user_tasks_b", "test_com_height_b")
    monkeypatch.syspath_prepend(str(folder))
    spec = {
        "import": ["test_user_tasks_b"],
        "levels": [{"tasks": [{"type": "test_com_height_b"}, {"type": "posture"}]}],
    }
    control = build_stack(spec, robot)  # (a dict: no file to look beside)
    assert type(control.stack.task("test_com_height_b")).__name__ == "ComHeightTask"


@pytest.mark.parametrize(
    ("imports", "message"),
    [
        ('"test_user_tasks_c"', r"import = 'test_user_tasks_c': import = \[\"module\", \.\.\.\]"),
        ("[3]", r"import = \[3\]: import = \[\"module\""),
        ('["no-dash"]', r"import = \['no-dash'\]: 'no-dash' is not a module name; import = \["),
        (
            '["test_no_such_module"]',
            r"import 'test_no_such_module': no such module beside the "
            r"file \(.*\) nor on the Python path; import = \[\"module\"",
        ),
        (
            '["json"]',
            r"import 'json' \(.*json.*\) defines no task type the stack names \(it "
            r"defines \[\]; the stack names \[.*'test_com_height_c'",
        ),
    ],
)
def test_a_bad_import_is_one_line_naming_the_file_and_key(robot, tmp_path, imports, message):
    path = _user_stack(tmp_path, "test_user_tasks_c", "test_com_height_c")
    text = path.read_text().replace('import = ["test_user_tasks_c"]', f"import = {imports}")
    path.write_text(text)
    with pytest.raises(TaskError, match=rf"^task stack {path}: {message}") as info:
        load_stack(path, robot)
    assert "\n" not in str(info.value)


def test_an_import_that_fails_is_one_line(robot, tmp_path):
    """A module whose type takes a built-in's name, or that fails to import, or a module of
    the same name already loaded from elsewhere: one line each, naming the file."""
    path = _user_stack(tmp_path, "test_user_tasks_d", "com")
    with pytest.raises(TaskError, match=rf"^task stack {path}: import 'test_user_tasks_d': "
                       r"stack_type 'com' of test_user_tasks_d.ComHeightTask is already the "
                       r"type of wbc.tasks.com.ComTask"):  # fmt: skip
        load_stack(path, robot)
    (tmp_path / "test_user_tasks_d.py").write_text("import numpy\n1 / 0\n")
    with pytest.raises(TaskError, match=r"import 'test_user_tasks_d' failed: ZeroDivisionError"):
        load_stack(path, robot)
    (tmp_path / "test_user_tasks_d.py").write_text("import test_not_installed_dependency\n")
    with pytest.raises(TaskError, match=r"No module named 'test_not_installed_dependency'"):
        load_stack(path, robot)
    other = tmp_path / "other"
    other.mkdir()
    first = _user_stack(tmp_path, "test_user_tasks_e", "test_com_height_e")
    load_stack(first, robot)
    second = _user_stack(other, "test_user_tasks_e", "test_com_height_e")
    with pytest.raises(TaskError, match=r"another module 'test_user_tasks_e' is loaded"):
        load_stack(second, robot)


def test_the_command_line_names_the_bad_import(tmp_path, capsys):
    from wbc.cli import main

    path = _user_stack(tmp_path, "test_user_tasks_f", "test_com_height_f", ["test_nope_f"])
    assert main(["walk", "--stack", str(path), "--trajectory", "thesis_step"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"wbc walk: task stack {path}: import 'test_nope_f': no such module")
    assert len(err.splitlines()) == 1


@pytest.mark.long(12)
def test_walk_and_bench_run_a_users_task_from_its_stack_file(tmp_path):
    """``wbc walk --stack my.toml`` (and ``wbc bench --stack my.toml``) run a task type
    defined in ``my_tasks.py`` beside the file: its error is recorded at every tick and
    stays small (it is solved for), the walk and the benchmark fail no tick."""
    path = _user_stack(tmp_path, "my_tasks", "com_height")
    wbc = [sys.executable, "-m", "wbc.cli"]
    out = subprocess.run(
        [*wbc, "walk", "--stack", "my.toml", "--trajectory", "thesis_step", "--out", "run.npz"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    assert "my (HierarchicalQP, daqp) on thesis_step" in out.stdout
    with np.load(tmp_path / "run.npz", allow_pickle=True) as rec:
        err = rec["err/com_height"]
    assert err.shape == (100, 1) and np.isfinite(err).all()
    assert np.abs(err).max() < 1e-3  # (m) the CoM height held
    out = subprocess.run(
        [*wbc, "bench", "--stack", str(path), "--trajectories", "thesis_step", "--solvers",
         "hqp-daqp"],
        cwd=REPO, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    row = next(line for line in out.stdout.splitlines() if line.startswith("hqp-daqp@my"))
    assert row.split()[-1] == "0"  # no failed tick
