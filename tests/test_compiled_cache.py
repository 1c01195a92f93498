"""numba's disk cache around the compiled kernels (wbc.compiled._cache)."""

from __future__ import annotations

import importlib.util
import sys

import pytest

numba = pytest.importorskip("numba")

from numba.core import caching, codegen  # noqa: E402

from wbc.compiled._cache import lean_linking  # noqa: E402

SOURCE = """
from numba import njit


@njit(cache=True)
def inner(x):
    return 2.0 * x


@njit(cache=True)
def outer(x):
    return inner(x) + 1.0
"""


def _module(tmp_path, name):
    path = tmp_path / f"{name}.py"
    path.write_text(SOURCE)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # numba's cache finds a function's module by name
    spec.loader.exec_module(module)
    return module


def _cached(tmp_path, function):
    return any((tmp_path / "__pycache__").glob(f"*.{function}-*.nbi"))


def test_lean_linking_caches_the_entry_point_only_and_restores_numba(tmp_path):
    """Inside, the entry point (called from Python) is compiled and cached, its callee is
    linked into it without a cache entry of its own; afterwards numba is as before."""
    optimize = codegen.CPUCodeLibrary._optimize_final_module
    save = caching.Cache.save_overload
    module = _module(tmp_path, "wbc_test_lean_linking")
    try:
        with lean_linking() as active:
            assert active
            assert module.outer(3.0) == 7.0
        assert _cached(tmp_path, "outer") and not _cached(tmp_path, "inner")
        assert codegen.CPUCodeLibrary._optimize_final_module is optimize
        assert caching.Cache.save_overload is save
        # outside, as usual: a recompiled function is optimised and cached
        module.inner.recompile()
        assert module.inner(1.5) == 3.0
        assert _cached(tmp_path, "inner")
    finally:
        del sys.modules["wbc_test_lean_linking"]


def test_lean_linking_restores_numba_after_an_error():
    optimize = codegen.CPUCodeLibrary._optimize_final_module
    with pytest.raises(RuntimeError, match="inside"), lean_linking():
        raise RuntimeError("inside")
    assert codegen.CPUCodeLibrary._optimize_final_module is optimize
