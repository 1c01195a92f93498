"""benchmarks/pushes.py: the loops' specs (``--gains sized``: the closed loop's default)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest


@pytest.fixture(scope="module")
def pushes(benchmark_script):
    return benchmark_script("pushes")


def test_gains_sized_leaves_the_gains_to_the_closed_loop(pushes):
    from wbc.balance.stabilizer import Gains

    entry = SimpleNamespace(make=lambda robot: None)
    assert pushes.gains_arg("sized") == "sized"
    assert pushes.gains_arg('{"k_p": 2.0}') == {"k_p": 2.0}
    sized, comp = pushes.loop_spec("step", entry, None, {}, "sized", {}, 1.0, {})
    assert sized.gains is None and sized.stepping is not None and comp == 1.0
    given, _ = pushes.loop_spec("step", entry, None, {}, {"k_p": 2.0}, {}, 1.0, {})
    assert given.gains == Gains(k_p=2.0)
    plain, _ = pushes.loop_spec("closed", entry, None, {}, None, {}, 1.0, {})
    assert plain.gains == Gains() and plain.stepping is None
    nohip, _ = pushes.loop_spec("nohip", entry, None, {}, "sized", {}, 1.0, {})
    assert nohip.gains == Gains(k_hip=0.0)
