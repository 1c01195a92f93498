"""Run a benchmark script with the ``walk`` stack file's keys changed (issue 30, nineteenth
session: the landing options screened without editing tasks/walk.toml): ``WBC_STACK`` is a
JSON object of top-level keys (e.g. ``{"on_infeasible": "relax"}``), its ``support_switch``
entry merged into the file's ``[support_switch]`` table.

    WBC_STACK='{"support_switch": {"landing_fallback": true}}' nice -n 5 \\
        python benchmarks/with_stack.py benchmarks/pushes.py --solvers wqp-daqp \\
        --trajectory walk10_wb --loops step --screen backward:0.70:0.03
"""

from __future__ import annotations

import json
import os
import runpy
import sys
from typing import Any

import wbc.stacks as stacks

CHANGES: dict[str, Any] = json.loads(os.environ.get("WBC_STACK", "{}"))
_build = stacks.build_stack


def build_stack(spec: dict, robot: Any, *args: Any, **kw: Any) -> Any:
    """:func:`wbc.stacks.build_stack` with the ``walk`` stack's keys changed."""
    if spec.get("name") == "walk":
        table = {**spec.get("support_switch", {}), **CHANGES.get("support_switch", {})}
        spec = {**spec, **CHANGES, "support_switch": table}
    return _build(spec, robot, *args, **kw)


if __name__ == "__main__":
    stacks.build_stack = build_stack  # type: ignore[assignment]
    script = sys.argv[1]
    sys.argv = sys.argv[1:]
    sys.path.insert(0, os.path.dirname(os.path.abspath(script)))
    runpy.run_path(script, run_name="__main__")
