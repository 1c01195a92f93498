"""Recordings: round trip, and loading never uses pickle (one clear line for a bad file)."""

from __future__ import annotations

import zipfile

import numpy as np
import pytest

from wbc import TrajectoryError
from wbc.recording import Recording


def _rec() -> Recording:
    t = np.arange(3) * 0.01
    q = np.zeros((3, 9))
    q[:, 6] = 1.0
    return Recording(t, q, ("a", "b"), {"com": np.ones((3, 3))}, {"solver": "x"})


def test_round_trip(tmp_path):
    path = _rec().save(tmp_path / "r.npz")
    back = Recording.load(path)
    np.testing.assert_array_equal(back.q, _rec().q)
    np.testing.assert_array_equal(back["com"], np.ones((3, 3)))
    assert back.joint_names == ("a", "b") and back.meta == {"solver": "x"}


def test_not_an_npz_file_is_named_without_pickle_advice(tmp_path):
    path = tmp_path / "r.npz"
    path.write_bytes(b"\x80\x04garbage that numpy would try to unpickle")
    with pytest.raises(TrajectoryError) as exc:
        Recording.load(path)
    message = str(exc.value)
    assert str(path) in message and "not a .npz file" in message
    assert "allow_pickle" not in message and "\n" not in message


def test_a_truncated_archive_is_corrupted(tmp_path):
    path = _rec().save(tmp_path / "r.npz")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(TrajectoryError, match=r"r\.npz is corrupted"):
        Recording.load(path)


def test_pickled_arrays_are_refused(tmp_path):
    path = tmp_path / "r.npz"
    np.savez(path, t=np.arange(2.0), q=np.zeros((2, 8)), joint_names=np.array(["a"]),
             evil=np.array([{"x": 1}], dtype=object))  # fmt: skip
    assert zipfile.is_zipfile(path)
    with pytest.raises(TrajectoryError, match=r"pickled \(object\) arrays") as exc:
        Recording.load(path)
    assert "allow_pickle" not in str(exc.value)


def test_bad_meta_is_named(tmp_path):
    path = tmp_path / "r.npz"
    np.savez(path, t=np.arange(2.0), q=np.zeros((2, 8)), joint_names=np.array(["a"]),
             meta=np.array("{not json"))  # fmt: skip
    with pytest.raises(TrajectoryError, match="'meta' is not valid JSON"):
        Recording.load(path)
