"""Recordings: a run's joint trajectory with its references, saved as one ``.npz`` file.

Every tool (benchmark, viewer, servo deployment, physics) reads this one format. Required
arrays: ``t`` (N,), ``q`` (N, nq) full floating-base configurations and ``joint_names``.
Optional channels use these names when present:

``com`` / ``com_ref`` (N, 3), ``swing`` / ``swing_ref`` (N, 3) swing-sole position (the sole
with the swing role; ``swing_is_left`` (N,) says which), ``l_sole`` / ``r_sole`` and
``l_sole_ref`` / ``r_sole_ref`` (N, 7) sole placements as xyz + quaternion (x, y, z, w),
``support`` (N,) int8 (:data:`SUPPORT_DOUBLE`, :data:`SUPPORT_LEFT`, :data:`SUPPORT_RIGHT`),
``zmp`` / ``zmp_ref`` (N, 2), ``com_margin`` / ``zmp_margin`` (N,) signed distance (m) to the
support polygon's edge (positive inside), ``limit_margin`` (N, n_joints) distance (rad) to the
nearest joint limit (negative = violated), ``swing_lowest`` (N,) height of the swing sole's
lowest corner (m), ``torso_yaw_ref`` (N,), ``solve_time`` (N,) seconds, ``iterations`` and
``failed`` (N,), ``err/<task>`` (N, k) task errors (m for position rows, rad for
orientation and joint rows: :meth:`wbc.solvers.TaskStack.errors`). ``meta`` is a JSON dict (solver,
trajectory, robot, ...).

**Validity.** A run's recording carries ``meta["validity"]`` (:func:`assess`): ``valid``,
``failed_ticks`` (ticks whose solve raised), ``hard_failed_ticks`` (of those, a hard level
could not be met), ``limit_violations`` (ticks with a joint beyond its limits by more than
1e-3 rad), ``first_failure``, and the ``stack``, ``robot`` and ``wbc_version`` that made it.
:meth:`Recording.problems` says why a recording is not fit to play (``wbc deploy`` refuses it
without ``--force``); a recording without validity (written by hand) is judged by its
``failed`` channel when it has one.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .exceptions import TrajectoryError
from .types import SUPPORT_DOUBLE as SUPPORT_DOUBLE
from .types import SUPPORT_LEFT as SUPPORT_LEFT
from .types import SUPPORT_NAMES as SUPPORT_NAMES
from .types import SUPPORT_RIGHT as SUPPORT_RIGHT
from .version import __version__


@dataclass
class Recording:
    """A time-indexed joint trajectory plus named channels and metadata."""

    t: np.ndarray
    q: np.ndarray
    joint_names: tuple[str, ...]
    channels: dict[str, np.ndarray] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float)
        self.q = np.asarray(self.q, dtype=float)
        self.joint_names = tuple(self.joint_names)
        _check_shapes(self.t.shape, self.q.shape, len(self.joint_names))
        if not np.all(np.isfinite(self.t)) or np.any(np.diff(self.t) <= 0):
            raise TrajectoryError("recording: t must be finite and strictly increasing")
        for name, values in self.channels.items():
            arr = np.asarray(values)
            if arr.shape[:1] != (self.t.size,):
                raise TrajectoryError(
                    f"recording: channel {name!r} has {arr.shape[:1]} rows, expected {self.t.size}"
                )
            self.channels[name] = arr

    def __len__(self) -> int:
        return self.t.size

    def problems(self) -> list[str]:
        """Why this recording is from a failed run (empty if valid or unknown), one phrase
        each: failed ticks, hard levels not met, joint-limit violations."""
        failed = None
        if "failed" in self.channels:
            failed = int(np.count_nonzero(self.channels["failed"]))
        return validity_problems(self.meta, failed, len(self))

    @property
    def joints(self) -> np.ndarray:
        """(N, n_joints) actuated joint angles."""
        return self.q[:, 7:]

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.channels[name]
        except KeyError:
            raise KeyError(
                f"recording has no channel {name!r}; channels: {sorted(self.channels)}"
            ) from None

    def save(self, path: str | Path) -> Path:
        """Write the recording as ``.npz`` (no pickled objects)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {
            "t": self.t,
            "q": self.q,
            "joint_names": np.array(self.joint_names),
            "meta": np.array(json.dumps(self.meta, default=_json_default)),
        }
        for name, values in self.channels.items():
            if name in arrays:
                raise TrajectoryError(f"recording: channel name {name!r} is reserved")
            arrays[name] = values
        np.savez_compressed(path, **arrays)
        return path

    @classmethod
    def load(cls, path: str | Path) -> Recording:
        """Read a recording written by :meth:`save`; names what is missing if malformed."""
        path = Path(path)
        if not path.is_file():
            raise TrajectoryError(f"recording not found: {path}")
        with open(path, "rb") as f:
            magic = f.read(4)
        if magic != b"PK\x03\x04" and magic != b"PK\x05\x06":  # zip local header / empty zip
            raise TrajectoryError(
                f"recording {path} is not a .npz file (a zip archive of arrays written by "
                "wbc walk --out / wbc bench --record); it is never loaded as a pickle"
            )
        try:
            with open(path, "rb") as f, np.load(f, allow_pickle=False) as data:
                arrays = {k: data[k] for k in data.files}
        except ValueError as exc:  # an object (pickled) array inside the archive
            raise TrajectoryError(
                f"recording {path} holds pickled (object) arrays; a recording holds only "
                "numeric and string arrays and is never loaded with pickle"
            ) from exc
        except Exception as exc:  # truncated or corrupted archive
            raise TrajectoryError(f"recording {path} is corrupted ({exc})") from exc
        missing = [k for k in ("t", "q", "joint_names") if k not in arrays]
        if missing:
            raise TrajectoryError(f"recording {path} lacks required arrays {missing}")
        meta = _parse_meta(path, str(arrays.pop("meta"))) if "meta" in arrays else {}
        t = arrays.pop("t")
        q = arrays.pop("q")
        names = tuple(str(n) for n in arrays.pop("joint_names"))
        return cls(t, q, names, arrays, meta)


def _check_shapes(t_shape: tuple[int, ...], q_shape: tuple[int, ...], n_joints: int) -> None:
    """A recording's ``t`` (N,) and ``q`` (N, 7 + ``n_joints``) shapes, in memory or still in
    its file (:class:`RecordingReader`)."""
    if len(t_shape) != 1 or t_shape[0] == 0:
        raise TrajectoryError(f"recording: t must be a non-empty 1-D array, got {t_shape}")
    if len(q_shape) != 2 or q_shape[0] != t_shape[0]:
        raise TrajectoryError(f"recording: q must have shape (N={t_shape[0]}, nq), got {q_shape}")
    if q_shape[1] != 7 + n_joints:
        raise TrajectoryError(
            f"recording: q has {q_shape[1]} columns but {n_joints} joint names "
            f"(expected 7 + {n_joints})"
        )


def _parse_meta(path: Path, text: str) -> dict[str, Any]:
    """A recording's ``meta`` array (JSON text) as a dict."""
    try:
        meta = json.loads(text)
    except json.JSONDecodeError as exc:
        raise TrajectoryError(f"recording {path}: 'meta' is not valid JSON ({exc})") from exc
    if not isinstance(meta, dict):
        raise TrajectoryError(f"recording {path}: 'meta' must be a JSON object")
    return meta


class RecordingReader:
    """A recording's rows read in order, a chunk at a time, without loading the file: what a
    long playback needs (memory independent of the recording's length). Checks the file as
    :meth:`Recording.load` does (a zip of ``.npy`` arrays, no pickles, ``t``/``q``/
    ``joint_names`` present, shapes consistent); :meth:`chunks` yields ``(t, q)`` blocks."""

    def __init__(self, path: str | Path, chunk_rows: int = 4096) -> None:
        import zipfile

        self.path = path = Path(path)
        self.chunk_rows = int(chunk_rows)
        if not path.is_file():
            raise TrajectoryError(f"recording not found: {path}")
        try:
            self._zip = zipfile.ZipFile(path)
            members = {n[:-4]: n for n in self._zip.namelist() if n.endswith(".npy")}
        except (zipfile.BadZipFile, OSError) as exc:
            raise TrajectoryError(
                f"recording {path} is not a .npz file (a zip archive of arrays written by "
                f"wbc walk --out / wbc bench --record) ({exc})"
            ) from None
        self._members = members
        missing = [k for k in ("t", "q", "joint_names") if k not in members]
        if missing:
            raise TrajectoryError(f"recording {path} lacks required arrays {missing}")
        self.joint_names = tuple(str(n) for n in self._small("joint_names"))
        self.meta: dict[str, Any] = (
            _parse_meta(path, str(self._small("meta"))) if "meta" in members else {}
        )
        t_shape, _ = self._header("t")
        q_shape, _ = self._header("q")
        _check_shapes(t_shape, q_shape, len(self.joint_names))
        self.n = int(t_shape[0])
        self.nq = int(q_shape[1])

    def __len__(self) -> int:
        return self.n

    def close(self) -> None:
        self._zip.close()

    def _small(self, name: str) -> np.ndarray:
        with self._zip.open(self._members[name]) as f:
            try:
                return np.lib.format.read_array(f, allow_pickle=False)
            except ValueError as exc:
                raise TrajectoryError(
                    f"recording {self.path} holds pickled (object) arrays; a recording holds "
                    "only numeric and string arrays and is never loaded with pickle"
                ) from exc

    def _open(self, name: str):
        f = self._zip.open(self._members[name])
        fmt = np.lib.format
        try:
            version = fmt.read_magic(f)
            read_header = (
                fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
            )
            shape, fortran, dtype = read_header(f)
        except ValueError as exc:  # not an .npy member, or an unknown format version
            f.close()
            raise TrajectoryError(f"recording {self.path} is corrupted ({name}: {exc})") from None
        if dtype.hasobject:
            f.close()
            raise TrajectoryError(
                f"recording {self.path} holds pickled (object) arrays; a recording holds only "
                "numeric and string arrays and is never loaded with pickle"
            )
        if fortran and len(shape) > 1:
            f.close()
            raise TrajectoryError(f"recording {self.path}: {name} is stored column-major")
        return f, shape, dtype

    def _header(self, name: str) -> tuple[tuple[int, ...], np.dtype]:
        f, shape, dtype = self._open(name)
        f.close()
        return shape, dtype

    def _rows(self, name: str):
        f, shape, dtype = self._open(name)
        width = int(np.prod(shape[1:], dtype=int))
        row_bytes = width * dtype.itemsize
        with f:
            left = shape[0]
            while left:
                k = min(self.chunk_rows, left)
                raw = f.read(k * row_bytes)
                if len(raw) != k * row_bytes:
                    raise TrajectoryError(f"recording {self.path} is truncated ({name})")
                yield np.frombuffer(raw, dtype=dtype).reshape((k, *shape[1:])).astype(float)
                left -= k

    def chunks(self):
        """``(t, q)`` blocks of up to ``chunk_rows`` rows, in order."""
        yield from zip(self._rows("t"), self._rows("q"), strict=True)

    def count(self, name: str) -> int | None:
        """Non-zero entries of a channel (e.g. ``failed``), streamed; None if absent."""
        if name not in self._members:
            return None
        return int(sum(np.count_nonzero(block) for block in self._rows(name)))

    def problems(self) -> list[str]:
        """As :meth:`Recording.problems`, without loading the arrays."""
        failed = None if isinstance(self.meta.get("validity"), dict) else self.count("failed")
        return validity_problems(self.meta, failed, self.n)


def validity_problems(meta: dict[str, Any], failed: int | None, n: int) -> list[str]:
    """Why a recording of ``n`` ticks is from a failed run: its ``meta["validity"]``, else
    the count of its ``failed`` channel (None: no such channel)."""
    v = meta.get("validity")
    if not isinstance(v, dict):
        v = {} if failed is None else {"failed_ticks": failed}
    out = []
    if v.get("failed_ticks"):
        hard = v.get("hard_failed_ticks") or 0
        text = f"{v['failed_ticks']} of {n} ticks failed"
        if hard:
            text += f" ({hard} with a hard level not met)"
        if v.get("first_failure"):
            text += f", first {v['first_failure']}"
        out.append(text)
    if v.get("limit_violations"):
        out.append(f"{v['limit_violations']} ticks beyond the joint limits")
    if v.get("valid") is False and not out:
        out.append("marked invalid")
    return out


#: a joint beyond its limit by more than this (rad) makes a tick a limit violation
PLAYABLE_LIMIT_TOL = 1e-3


def assess(rec: Recording, hard_failed_ticks: int = 0, first_failure: str = "") -> dict[str, Any]:
    """The validity record of a run (module docstring), from its ``failed`` and
    ``limit_margin`` channels and its ``meta`` (``controller``, ``robot``)."""
    failed = int(np.count_nonzero(rec.channels["failed"])) if "failed" in rec.channels else 0
    limits = 0
    if "limit_margin" in rec.channels:
        margin = np.asarray(rec.channels["limit_margin"], dtype=float)
        limits = int(np.count_nonzero(np.any(~(margin >= -PLAYABLE_LIMIT_TOL), axis=1)))
    return {
        "valid": failed == 0 and limits == 0,
        "failed_ticks": failed,
        "hard_failed_ticks": int(hard_failed_ticks),
        "limit_violations": limits,
        "first_failure": str(first_failure)[:300],
        "stack": rec.meta.get("controller", ""),
        "robot": rec.meta.get("robot", ""),
        "wbc_version": __version__,
    }


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
