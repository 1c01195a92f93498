"""The background worker that compiles one tick of a kernel set other than the package's
(a stack with a task or limit type defined elsewhere): ``python -m wbc.compiled.worker JOB``.

``JOB`` (JSON, written by :meth:`wbc.compiled.dispatch.Ticks.start_build`) names the generated
module (its name and file), its kernels (module, source file and qualified name: each is
imported by module name, else loaded from its file under that name), the tick and its
argument types (pickled numba types, hex), and the package's solve that the split tick calls
next if it is not cached yet (``solve``, ``solve_signature``: compiled first). The worker
compiles that one signature, which
numba caches on disk, and exits; the solver meanwhile solves on the numpy path and loads the
tick from the cache once it is there. The kernels themselves are compiled once each and
cached beside their source (numba's ``cache=True``): the tick links them in.
"""

from __future__ import annotations

import importlib
import importlib.util
import json
import pickle
import sys
from pathlib import Path


def _load_module(name: str, file: str | None):
    """Module ``name``: imported, else (not on the path: a user's file) loaded from ``file``."""
    if name in sys.modules:
        return sys.modules[name]
    try:
        return importlib.import_module(name)
    except ImportError:
        if not file:
            raise
    spec = importlib.util.spec_from_file_location(name, file)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load the kernel module {name!r} from {file}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def load_kernel(entry: dict):
    """The kernel an entry of the job names (``module``, ``file``, ``qualname``)."""
    obj = _load_module(entry["module"], entry.get("file"))
    for part in entry["qualname"].split("."):
        obj = getattr(obj, part)
    return obj


def run(job: dict) -> None:
    """Compile (and so cache) the job's tick for its argument types."""
    from .dispatch import load_generated

    kernels = [load_kernel(e) for e in job["kernels"]]
    bounds = [load_kernel(e) for e in job["bounds"]]
    constraints = [load_kernel(e) for e in job.get("constraints", ())]
    module = load_generated(job["name"], Path(job["path"]), kernels, bounds, constraints)
    if "solve" in job:  # (first: the tick on disk then means both are ready)
        solve = load_kernel(job["solve"])
        solve.compile(pickle.loads(bytes.fromhex(job["solve_signature"])))
    signature = pickle.loads(bytes.fromhex(job["signature"]))
    getattr(module, job["tick"]).compile(signature)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m wbc.compiled.worker JOB.json", file=sys.stderr)
        return 2
    run(json.loads(Path(args[0]).read_text()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
