"""A numba kernel's compiled entry point, so that a hot path skips the dispatcher.

numba's dispatcher types every argument at every call (2–6 µs a call, more when its code is
cold in a 50 Hz loop); the entry point of the overload for those types is the compiled
function itself. :func:`entry_point` is the one place that looks it up.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any


def entry_point(kernel: Any, args: Sequence[Any], compile: bool = False) -> Callable[..., Any]:
    """``kernel``'s (a numba dispatcher) compiled entry point for the types of ``args``: the
    caller has already called it on them, or with ``compile`` it is compiled (or loaded from
    numba's cache) for them here without running it. The dispatcher itself where this numba
    keeps no entry point."""
    from numba import typeof

    signature = tuple(typeof(a) for a in args)
    try:
        if compile and signature not in kernel.overloads:
            kernel.compile(signature)
        return kernel.overloads[signature].entry_point
    except (KeyError, AttributeError):  # another numba: keep the dispatcher
        return kernel
