"""The hierarchy's compiled cascade alone, replayed on a walk's captured inputs.

Capture (a walk through the controller's loop, each tick's ``cascade_solve`` inputs kept: the
rows, bounds, inequality rows, the warm active sets after the tick's own forgetting and the
carried rows, and its answer)::

    python benchmarks/cascade_replay.py --capture OUT.pkl --trajectory walk10 --stack walk_strict

Replay (each tick's ``cascade_solve`` from the captured inputs through the compiled entry point,
best of ``--reps`` per tick on the thread CPU clock, its own overhead taken off; ``--rounds``
separate processes, each tick's minimum over them)::

    python benchmarks/cascade_replay.py OUT.pkl [--reps 9] [--rounds 3] [--slowest 8]

prints the median, p99 and total, the first tick of each support phase, and the slowest ticks
with each ``solve_level_in`` call's subproblems (the level, its rows, whether it was a
continued call, fresh subproblems in the normal and the row form, updates, declines: counted
in a process with ``NUMBA_DISABLE_JIT=1``, the kernels as Python). ``--against ROOT``: the
rounds alternate between this checkout and the one at ROOT (``PYTHONPATH=ROOT``, e.g. main
exported) on the same captured inputs, and both are printed side by side with the largest
difference of their answers (Δq) and of their statuses. The replayed answer is checked
against the captured one (``--check``: the largest |Δq − Δq captured| over the ticks;
tests/test_cascade_replay.py: 1e-12). ``--cold MB``: that much of another array read before
each call (the caches evicted, as after a tick's Python). ``--footprint``: per call, the
bytes of its inputs and work arrays, its allocations and the solve's machine code (each
checkout); a checkout with a work space (:mod:`wbc.compiled.space`) gets one for the replay,
allocated once.
"""

from __future__ import annotations

import argparse
import os
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path and not os.environ.get("WBC_REPLAY_CHILD"):
    sys.path.insert(0, str(ROOT))

#: cascade_solve's arguments, in order (those written by the solve are copied for each call)
ARGS = (
    "J", "b", "level_rows", "level_hard", "G", "h", "g_rows", "q", "q_min", "q_max", "params",
    "lower", "upper", "states", "working", "h_eff", "achieved", "dq", "q_next",
)  # fmt: skip
WRITTEN = ("states", "working", "h_eff", "achieved", "dq", "q_next")


def capture(
    trajectory: str, stack: str, robot_name: str = "bioloid", release_small: float = 0.0
) -> dict:
    """Walk ``trajectory`` with ``tasks/<stack>.toml`` (hierarchical, compiled) and keep each
    tick's cascade inputs and answer: {"ticks": [dict per tick], "support": per tick, ...}.
    ``release_small``: the solver's option (:mod:`wbc.compiled.lsq_release`; its marks in the
    captured states, which a checkout without it reads as the last tick's set)."""
    from wbc import load_robot
    from wbc.bench.trajectories import build
    from wbc.solvers.carry import CarriedRows
    from wbc.solvers.plan import CascadePlan, _Plan, start_package_ticks, wait_for_package_ticks
    from wbc.stacks import build_stack
    from wbc.walking.loop import StackController, run

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from self_collision import walk_spec

    robot = load_robot(robot_name)
    ref = build(trajectory, robot)
    start_package_ticks(announce=False)
    wait_for_package_ticks()
    ticks: list[dict] = []
    snap: dict = {}
    done = [0]  # (the loop's ticks done: a solve belongs to the next)
    forget, carry, solve = _Plan.forget_warm_start, CarriedRows.carry, CascadePlan.solve

    def forget_kept(self, keep_damped=False, rows=None):
        forget(self, keep_damped, rows)
        if isinstance(self, CascadePlan):  # the warm sets the tick's solve starts from
            snap["states"] = self.states.copy()
            snap["working"] = self.inequalities.working.copy()

    def carry_kept(self, G, h, p, working):
        n = carry(self, G, h, p, working)
        snap["carried"] = working.copy()  # (the damped level's rows carried in)
        return n

    def solve_kept(self, kin, dt):
        snap.clear()
        status = solve(self, kin, dt)
        g = self.inequalities
        working = snap["working"]
        if "carried" in snap:
            working[self.damped_level] = snap["carried"]
        arrays = dict(
            J=self.rows.J, b=self.rows.b, level_rows=self.level_rows, level_hard=self.level_hard,
            G=g.G, h=g.h, g_rows=g.g_rows, q=kin.q, q_min=self.q_min, q_max=self.q_max,
            params=self.params, lower=self.lower, upper=self.upper, states=snap["states"],
            working=working, h_eff=np.zeros_like(g.h_eff), achieved=np.zeros_like(self.achieved),
            dq=np.zeros_like(self.dq), q_next=np.zeros_like(self.q_next),
        )  # fmt: skip
        tick = {k: np.array(v, copy=True) for k, v in arrays.items()}
        tick.update(status=int(status), dq_out=self.dq.copy(), tick=done[0])
        ticks.append(tick)
        return status

    patches = ((_Plan, "forget_warm_start", forget_kept), (CarriedRows, "carry", carry_kept),
               (CascadePlan, "solve", solve_kept))  # fmt: skip
    # each class's own attribute, or None where it is inherited (then deleted again after:
    # CascadePlan's solve is _Plan's, and one set on CascadePlan would hide any later patch of
    # _Plan.solve in the same process)
    saved = [(cls, name, cls.__dict__.get(name)) for cls, name, _ in patches]
    for cls, name, wrapped in patches:
        setattr(cls, name, wrapped)
    try:
        controller = StackController(
            build_stack({**walk_spec(True, stack), "solver": "hierarchical"}, robot)
        )
        if release_small:
            controller.solver.release_small = release_small
        rec = run(controller, robot, ref, on_tick=lambda i, q, t: done.__setitem__(0, i + 1))
    finally:
        for cls, name, own in saved:
            if own is None:
                delattr(cls, name)
            else:
                setattr(cls, name, own)
    support = np.asarray(rec["support"])
    if {t["tick"] for t in ticks} != set(range(len(support))):
        raise RuntimeError(f"captured {len(ticks)} solves of {len(support)} ticks (compiled?)")
    return dict(
        ticks=ticks, support=support, trajectory=trajectory, stack=stack, robot=robot_name,
        handed_back=int(controller.solver.handed_back_ticks),
    )  # fmt: skip


def work_space(ticks: list[dict]) -> tuple:
    """The work space of a checkout whose cascade_solve takes one (:mod:`wbc.compiled.space`:
    allocated once for the capture's largest tick, as a solver's plans share theirs), else ()."""
    try:
        from wbc.compiled.space import cascade_space_size
    except ImportError:  # (a checkout before the work space: its solve allocates its own)
        return ()
    f, i = np.max(
        [cascade_space_size(t["level_rows"], t["dq"].shape[0], t["g_rows"][-1]) for t in ticks],
        axis=0,
    )
    return np.zeros(f), np.zeros(i, np.int64)


def call_args(tick: dict, space: tuple = ()) -> list[np.ndarray]:
    """The tick's cascade_solve arguments (fresh copies of those the solve writes), then the
    work space ``space`` if given (:func:`work_space`)."""
    return [tick[k].copy() if k in WRITTEN else tick[k] for k in ARGS] + list(space)


def _entry(tick: dict, space: tuple = ()):
    """The compiled cascade_solve's entry point for the tick's argument types."""
    from numba import typeof

    from wbc.compiled.ticks import cascade_solve

    args = call_args(tick, space)
    cascade_solve(*args)
    try:
        return cascade_solve.overloads[tuple(typeof(a) for a in args)].entry_point
    except (KeyError, AttributeError):  # another numba: the dispatcher
        return cascade_solve


def _clock_overhead() -> float:
    """The smallest time between two reads of the thread CPU clock, ns."""
    clock = time.thread_time_ns
    best = 1 << 62
    for _ in range(2000):
        s = clock()
        best = min(best, clock() - s)
    return float(best)


def replay(ticks: list[dict], reps: int, cold: float = 0.0) -> dict[str, np.ndarray]:
    """Each tick's cascade_solve, best of ``reps`` on the thread CPU clock (µs, the clock's
    overhead off), its answer Δq and status. ``cold`` (MB): that much of another array read
    before each call (its arguments copied first), which evicts the solve's code and data
    from the caches as the Python of a tick does before its compiled part."""
    space = work_space(ticks)
    entry = _entry(ticks[0], space)
    clock = time.thread_time_ns
    overhead = _clock_overhead()
    t = np.zeros(len(ticks))
    dq = np.zeros((len(ticks), ticks[0]["dq"].shape[0]))
    status = np.zeros(len(ticks), dtype=np.int64)
    other = np.ones(int(cold * (1 << 20)) // 8)
    for i, tick in enumerate(ticks):
        best = 1 << 62
        for _ in range(reps):
            args = call_args(tick, space)
            if other.size:
                other.sum()
            s = clock()
            st = entry(*args)
            best = min(best, clock() - s)
        t[i] = max(best - overhead, 0.0) / 1e3
        dq[i] = args[ARGS.index("dq")]
        status[i] = st
    return dict(t=t, dq=dq, status=status)


def _lines(a: np.ndarray) -> int:
    """The bytes of the 64-byte cache lines an array spans."""
    start = a.ctypes.data
    return ((start + a.nbytes + 63) // 64 - start // 64) * 64 if a.nbytes else 0


def footprint(ticks: list[dict]) -> dict[str, np.ndarray]:
    """Per tick: the bytes of the inputs cascade_solve reads or writes (the cache lines of
    J, b, the first ``g_rows[-1]`` inequality rows, the bounds, the sets, the outputs), its work
    arrays' (the work space for the tick's own rows, where the checkout has one:
    :func:`wbc.compiled.space.cascade_space_size`, else 0), the arrays it allocated
    (numba's NRT allocations in the call, the arguments' records not counted: when
    ``NUMBA_NRT_STATS=1``, else -1), and
    the machine code of the compiled solve (its cached object's .text/.ltext, one figure)."""
    from numba.core.runtime import rtsys

    space = work_space(ticks)
    entry = _entry(ticks[0], space)
    try:
        from wbc.compiled.space import cascade_space_size
    except ImportError:
        cascade_space_size = None
    stats = os.environ.get("NUMBA_NRT_STATS") == "1"
    inputs, work, allocs = (np.zeros(len(ticks), dtype=np.int64) for _ in range(3))
    for i, tick in enumerate(ticks):
        g = int(tick["g_rows"][-1])
        args = call_args(tick, space)
        sizes = {k: _lines(a) for k, a in zip(ARGS, args, strict=False)}
        for k in ("G", "h", "h_eff"):
            sizes[k] = _lines(tick[k][:g])
        sizes["working"] = _lines(tick["working"][:, :g])
        inputs[i] = sum(sizes.values())
        if cascade_space_size is not None:
            f, n = cascade_space_size(tick["level_rows"], tick["dq"].shape[0], g)
            work[i] = 8 * (f + n)
        before = rtsys.get_allocation_stats().alloc if stats else 0
        entry(*args)
        # (less one an argument: numba wraps each array it is passed in an NRT record)
        allocs[i] = rtsys.get_allocation_stats().alloc - before - len(args) if stats else -1
    return dict(inputs=inputs, work=work, allocs=allocs, code=np.array([_code_bytes()]))


def _code_bytes() -> int:
    """The machine code of the compiled cascade_solve: the .text and .ltext sections of its
    cached object (numba's cache of ticks.py; -1 if not found or no ``size`` tool)."""
    import glob
    import shutil

    from wbc.compiled.ticks import cascade_solve

    path = getattr(getattr(cascade_solve, "_cache", None), "cache_path", None)
    files = sorted(glob.glob(f"{path}/ticks.cascade_solve-*.nbc"), key=os.path.getmtime)
    if not files or not shutil.which("size"):
        return -1
    data = Path(files[-1]).read_bytes()
    with tempfile.NamedTemporaryFile(suffix=".o") as f:
        f.write(data[data.find(b"\x7fELF") :])
        f.flush()
        out = subprocess.run(["size", "-A", f.name], capture_output=True, text=True).stdout
    return sum(int(x.split()[1]) for x in out.splitlines() if x.startswith((".text", ".ltext")))


def counts(ticks: list[dict], which: list[int]) -> dict[int, list[dict]]:
    """Each ``solve_level_in`` call of the ticks ``which``: its level, rows of A and B,
    continued or not, status, subproblems, and by kind (``fresh`` normal form, ``fresh row``
    row form, ``factored`` its right-hand sides on factors kept, ``upd`` updated, ``decl``
    declined, ``dep`` a joined row depending). Needs the kernels as Python
    (``NUMBA_DISABLE_JIT=1`` before numba is imported)."""
    from wbc.compiled import lsq, lsq_update
    from wbc.compiled import ticks as T

    if os.environ.get("NUMBA_DISABLE_JIT") != "1":
        raise RuntimeError("counts(): run with NUMBA_DISABLE_JIT=1")
    kinds: dict[str, int] = {}
    names = {
        lsq_update._UPDATED: "upd",
        lsq_update._DECLINED: "decl",
        lsq_update._ROW_DEPENDS: "dep",
    }
    out: dict[int, list[dict]] = {}
    current: dict = {}
    sub, upd, sli = lsq._subproblem, lsq._updated, T.solve_level_in

    def sub_counted(*a):
        result = sub(*a)
        ind = a[13]  # (then its factors, if in the work space already: lsq._FACTORED)
        nf = int((ind[lsq._I_FIXED] == 0).sum())
        key = "fresh row" if a[2].shape[0] < nf - result[1] else "fresh"
        key = "factored" if len(a) > 14 and a[14] > 0 else key
        kinds[key] = kinds.get(key, 0) + 1
        return result

    def upd_counted(*a):
        code = upd(*a)
        key = names.get(int(code), str(code))
        kinds[key] = kinds.get(key, 0) + 1
        return code

    def sli_counted(A, a, B, r, ridge, lower, upper, state, x, rtol, max_iter, space, cont, *ties):
        kinds.clear()
        st, c = sli(A, a, B, r, ridge, lower, upper, state, x, rtol, max_iter, space, cont, *ties)
        J, rows = current["J"], current["level_rows"]
        level = -1
        if B.base is not None and B.shape[0] and J.shape[0]:
            r0 = (B.ctypes.data - J.ctypes.data) // J.strides[0]
            if 0 <= r0 < J.shape[0]:
                level = int(np.searchsorted(rows, r0, side="right") - 1)
        if level < 0 and cont and current["calls"]:  # (the level of the call it continues)
            level = current["calls"][-1]["level"]
        current["calls"].append(
            dict(level=level, m=A.shape[0], p=B.shape[0], cont=bool(cont), status=int(st),
                 count=int(c), kinds=dict(kinds))
        )  # fmt: skip
        return st, c

    lsq._subproblem, lsq._updated, T.solve_level_in = sub_counted, upd_counted, sli_counted
    space = work_space(ticks)
    try:
        for i in which:
            args = call_args(ticks[i], space)
            current.update(J=args[0], level_rows=args[2], calls=[])
            T.cascade_solve(*args)
            out[i] = current["calls"]
    finally:
        lsq._subproblem, lsq._updated, T.solve_level_in = sub, upd, sli
    return out


def _child(path: str, out: str, reps: int, which: str, cold: float = 0.0) -> None:
    """A round in this process: times (``which`` empty), counts of the ticks ``which`` or
    (``which`` "footprint") the footprint."""
    with open(path, "rb") as f:
        cap = pickle.load(f)
    if which == "footprint":
        result: dict = footprint(cap["ticks"])
    elif which:
        result = {"counts": counts(cap["ticks"], [int(i) for i in which.split(",")])}
    else:
        result = replay(cap["ticks"], reps, cold)
    with open(out, "wb") as f:
        pickle.dump(result, f)


def _run_child(root: Path, path: str, reps: int, which: str = "", cold: float = 0.0) -> dict:
    """One round in a separate process on the checkout at ``root``."""
    env = dict(os.environ, PYTHONPATH=str(root), WBC_REPLAY_CHILD="1")
    if which == "footprint":
        env["NUMBA_NRT_STATS"] = "1"
    elif which:
        env["NUMBA_DISABLE_JIT"] = "1"
    with tempfile.NamedTemporaryFile(suffix=".pkl", delete=False) as f:
        out = f.name
    try:
        cmd = [sys.executable, str(Path(__file__).resolve()), path, "--child", out]
        cmd += ["--reps", str(reps), "--which", which, "--cold", str(cold)]
        subprocess.run(cmd, env=env, check=True)
        with open(out, "rb") as f:
            return pickle.load(f)
    finally:
        Path(out).unlink(missing_ok=True)


def phase_firsts(support: np.ndarray) -> list[int]:
    """The first tick of each support phase (after the walk's first)."""
    return (np.flatnonzero(support[1:] != support[:-1]) + 1).tolist()


def _fmt_calls(calls: list[dict]) -> str:
    parts = []
    for c in calls:
        k = " ".join(f"{v} {n}" for n, v in sorted(c["kinds"].items()))
        tag = "+" if c["cont"] else ""
        parts.append(f"L{c['level']}{tag}(m{c['m']} p{c['p']}: {c['count']} = {k})")
    return "; ".join(parts)


def report(cap: dict, runs: dict[str, list[dict]], slowest: int, calls: dict) -> None:
    """Median, p99, total; the phases' first ticks; the slowest ticks (of the first label)."""
    tick_of = np.array([x["tick"] for x in cap["ticks"]])
    support = cap["support"][tick_of]  # (per solve: a tick may solve more than once)
    switch = set(phase_firsts(cap["support"]))
    firsts = [i for i, k in enumerate(tick_of.tolist()) if k in switch]
    labels = list(runs)
    t = {k: np.min([r["t"] for r in v], axis=0) for k, v in runs.items()}
    print(
        f"{cap['stack']} {cap['trajectory']} ({cap['robot']}): {len(cap['support'])} ticks, "
        f"{len(support)} solves, {len(switch)} phase switches, handed back at capture "
        f"{cap['handed_back']}; "
        f"each tick's minimum over {len(runs[labels[0]])} rounds, µs (tick 0 aside)"
    )
    print("| | " + " | ".join(labels) + " |")
    print("|---|" + "---|" * len(labels))
    rows = {
        "median": lambda x: np.median(x[1:]),
        "p99": lambda x: np.percentile(x[1:], 99),
        "max": lambda x: x[1:].max(),
        "total": lambda x: x[1:].sum(),
        "first of a phase: max": lambda x: x[firsts].max() if firsts else np.nan,
        "first of a phase: sum": lambda x: x[firsts].sum() if firsts else np.nan,
        "first of a phase: max / median": lambda x: (
            x[firsts].max() / np.median(x[1:]) if firsts else np.nan
        ),
    }
    for name, f in rows.items():
        print(f"| {name} | " + " | ".join(f"{f(t[k]):.2f}" for k in labels) + " |")
    if len(labels) > 1:
        a, b = (runs[k][0] for k in labels[:2])
        dq = np.abs(a["dq"] - b["dq"]).max()
        differ = int((a["status"] != b["status"]).sum())
        print(
            f"answers: max |Δdq| {labels[0]} vs {labels[1]} {dq:.2e}, statuses differing {differ}"
        )
        for lo, hi in ((0, 15), (15, 30), (30, 45), (45, np.inf)):
            sel = (t[labels[1]] >= lo) & (t[labels[1]] < hi)
            sel[0] = False
            if sel.any():
                d = np.mean(t[labels[0]][sel] - t[labels[1]][sel])
                print(
                    f"  {labels[1]}'s ticks {lo}-{hi} µs ({int(sel.sum())}): "
                    f"{labels[0]} − {labels[1]} {d:+.2f} µs a tick"
                )
    ref = cap["ticks"]
    err = max(
        float(np.abs(r["dq"] - np.array([x["dq_out"] for x in ref])).max()) for r in runs[labels[0]]
    )
    print(f"replayed vs captured ({labels[0]}): max |Δdq| {err:.2e}")
    print(f"\nfirst ticks of the phases ({labels[0]}, µs; support 0 double, 1 / 2 single):")
    print(", ".join(f"{tick_of[i]} {t[labels[0]][i]:.1f} ({support[i]})" for i in firsts))
    order = np.argsort(t[labels[0]][1:])[::-1][:slowest] + 1
    print(f"\nthe {slowest} slowest ticks ({labels[0]}), µs; each solve_level_in call:")
    for i in order.tolist():
        others = " ".join(f"{k} {t[k][i]:.1f}" for k in labels[1:])
        first = "*" if i in firsts else ""
        print(
            f"- tick {tick_of[i]}{first} ({support[i]}; solve {i}): {t[labels[0]][i]:.1f} {others}"
        )
        if i in calls:
            print(f"    {_fmt_calls(calls[i])}")


def report_footprint(cap: dict, runs: dict[str, dict]) -> None:
    """The footprint of each checkout (:func:`footprint`): median and max over the ticks, and
    the phases' first ticks' medians, kB (allocations: counts)."""
    tick_of = np.array([x["tick"] for x in cap["ticks"]])
    switch = set(phase_firsts(cap["support"]))
    firsts = np.array([k in switch for k in tick_of.tolist()])
    print(f"{cap['stack']} {cap['trajectory']}: cascade_solve's footprint per call")
    print("| | " + " | ".join(runs) + " |")
    print("|---|" + "---|" * len(runs))
    for key, unit in (("inputs", 1e3), ("work", 1e3), ("allocs", 1)):
        cells = []
        for r in runs.values():
            x = r[key][1:] / unit
            cells.append(
                f"{np.median(x):.1f} / {x.max():.1f} / {np.median(r[key][firsts] / unit):.1f}"
            )
        print(f"| {key} (median / max / first of a phase) | " + " | ".join(cells) + " |")
    print(
        "| ticks that allocate | "
        + " | ".join(f"{int((r['allocs'][1:] > 0).sum())}" for r in runs.values())
        + " |"
    )
    print("| code (kB) | " + " | ".join(f"{r['code'][0] / 1e3:.1f}" for r in runs.values()) + " |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("path", nargs="?", help="a capture to replay")
    parser.add_argument("--capture", metavar="OUT", help="capture a walk into OUT (a pickle)")
    parser.add_argument("--trajectory", default="walk10")
    parser.add_argument("--stack", default="walk_strict")
    parser.add_argument("--robot", default="bioloid")
    parser.add_argument("--reps", type=int, default=9, help="calls per tick, the best kept")
    parser.add_argument("--rounds", type=int, default=3, help="processes per checkout")
    parser.add_argument("--slowest", type=int, default=8)
    parser.add_argument("--no-counts", action="store_true", help="no subproblem counts")
    parser.add_argument("--against", metavar="ROOT", help="another checkout, alternated")
    parser.add_argument(
        "--cold", type=float, default=0.0, metavar="MB",
        help="read MB of another array before each replayed call (the caches evicted)",
    )  # fmt: skip
    parser.add_argument(
        "--footprint", action="store_true",
        help="the bytes of each call's inputs and work arrays, its allocations, the code's",
    )  # fmt: skip
    parser.add_argument(
        "--release-small", type=float, default=0.0, metavar="R",
        help="capture with the solver's release_small = R (wbc.compiled.lsq_release)",
    )  # fmt: skip
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--which", default="", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _child(args.path, args.child, args.reps, args.which, args.cold)
        return
    if args.capture:
        cap = capture(args.trajectory, args.stack, args.robot, args.release_small)
        with open(args.capture, "wb") as f:
            pickle.dump(cap, f)
        st = {x["status"] for x in cap["ticks"]}
        print(f"{len(cap['ticks'])} ticks into {args.capture}; statuses {sorted(st)}")
        return
    if not args.path:
        parser.error("a capture to replay, or --capture OUT")
    with open(args.path, "rb") as f:
        cap = pickle.load(f)
    roots = {"this": ROOT}
    if args.against:
        roots["against"] = Path(args.against).resolve()
    if args.footprint:
        report_footprint(
            cap, {k: _run_child(r, args.path, 1, "footprint") for k, r in roots.items()}
        )
        return
    runs: dict[str, list[dict]] = {k: [] for k in roots}
    for _ in range(args.rounds):
        for name, root in roots.items():
            runs[name].append(_run_child(root, args.path, args.reps, cold=args.cold))
    calls: dict = {}
    if not args.no_counts and args.slowest:
        t = np.min([r["t"] for r in runs["this"]], axis=0)
        order = (np.argsort(t[1:])[::-1][: args.slowest] + 1).tolist()
        calls = _run_child(ROOT, args.path, 1, ",".join(map(str, order)))["counts"]
    report(cap, runs, args.slowest, calls)


if __name__ == "__main__":
    main()
