"""Benchmark figures: per trajectory, one figure per quantity with every solver (like the
thesis's Fig. 4.31); one run's reference vs achieved; time per tick across solvers. Every
figure is written as PNG and SVG."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..exceptions import ConfigurationError
from ..recording import Recording


def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ConfigurationError("--plots needs matplotlib: pip install 'wbc[plots]'") from exc
    return plt


#: file formats written beside each other for every figure
FORMATS = ("png", "svg")


def _save(fig, path: Path) -> Path:
    """Write ``path`` (PNG) and the same figure as SVG beside it; return the PNG path."""
    plt = _pyplot()
    path = Path(path).with_suffix(".png")
    path.parent.mkdir(parents=True, exist_ok=True)
    for fmt in FORMATS:
        fig.savefig(path.with_suffix(f".{fmt}"), dpi=90)
    plt.close(fig)
    return path


def colours(names: Sequence[str]) -> dict[str, tuple[float, ...]]:
    """One distinct colour per name (tab10, then Dark2 and Set1), in the given order."""
    plt = _pyplot()
    palette = [*(plt.get_cmap(m).colors for m in ("tab10", "Dark2", "Set1"))]
    palette = [c for group in palette for c in group]
    return {n: palette[i % len(palette)] for i, n in enumerate(names)}


def _label(rec: Recording) -> str:
    return str(rec.meta.get("solver", rec.meta.get("controller", "?")))


#: quantity -> (title, y label, recording -> (achieved, reference or None, axis names))
def _position(name: str):
    def get(rec: Recording):
        origin = rec[f"{name}_ref"][0]  # displacements: x, y and z share one scale
        return (rec[name] - origin) * 1e3, (rec[f"{name}_ref"] - origin) * 1e3, "xyz"

    return get


def _error(name: str):
    def get(rec: Recording):
        err = np.linalg.norm(rec[name] - rec[f"{name}_ref"], axis=1) * 1e3
        return err[:, None], None, ("",)

    return get


def _limit_margin(rec: Recording):
    return np.degrees(rec["limit_margin"].min(axis=1))[:, None], None, ("",)


def _time_per_tick(rec: Recording):
    return rec["solve_time"][:, None] * 1e6, None, ("",)


QUANTITIES = {
    "com": ("CoM, from its start", "mm", _position("com"), False),
    "swing": ("swing sole, from its start", "mm", _position("swing"), False),
    "com_error": ("CoM error |reference − achieved|", "mm", _error("com"), True),
    "swing_error": ("swing-sole position error", "mm", _error("swing"), True),
    "limit_margin": ("nearest joint limit (< 0: violated)", "deg", _limit_margin, False),
    "time": ("time per control tick", "µs", _time_per_tick, True),
}  # fmt: skip


def quantity_figures(recordings: Sequence[Recording], folder: Path) -> list[Path]:
    """Per trajectory, one figure per quantity with every solver (like the thesis's Fig. 4.31):
    time in seconds; a solver's reference dashed and achieved solid, in the same colour.

    Files: ``<folder>/<trajectory>__<quantity>.png`` and ``.svg``.
    """
    plt = _pyplot()
    from matplotlib.lines import Line2D

    paths = []
    by_traj: dict[str, list[Recording]] = {}
    for rec in recordings:
        by_traj.setdefault(str(rec.meta.get("trajectory", "?")), []).append(rec)
    for trajectory, recs in by_traj.items():
        colour = colours([_label(r) for r in recs])
        mode = recs[0].meta.get("mode", "?")
        same = _identical_runs(recs)
        for quantity, (title, unit, get, log) in QUANTITIES.items():
            # identical motions (one stack on several QP backends) are drawn once, labelled
            # with all their names; times differ, so every run has its own time curve
            shown = recs if quantity == "time" else [r for r in recs if _label(r) in same]
            usable = [r for r in shown if _has(r, quantity)]
            if not usable:
                continue
            axes_names = get(usable[0])[2]
            height = max(2.6 * len(axes_names) + 0.8, 0.16 * len(usable) + 1.0)
            fig, axes = plt.subplots(
                len(axes_names), 1, figsize=(14, height), sharex=True, squeeze=False
            )
            has_ref = False
            for rec in usable:
                achieved, ref, _ = get(rec)
                c = colour[_label(rec)]
                for k, ax in enumerate(axes[:, 0]):
                    y = achieved[:, k] + (1e-9 if log else 0.0)
                    label = _label(rec) if quantity == "time" else same[_label(rec)]
                    ax.plot(rec.t, y, "-", color=c, lw=1.0, label=label)
                    if ref is not None:
                        has_ref = True
                        ax.plot(rec.t, ref[:, k], "--", color=c, lw=1.0, alpha=0.8, zorder=1)
            for k, ax in enumerate(axes[:, 0]):
                ax.set_ylabel(f"{axes_names[k]} ({unit})" if axes_names[k] else unit)
                ax.grid(True, alpha=0.3)
                if log:
                    ax.set_yscale("log")
            axes[-1, 0].set_xlabel("time (s)")
            handles, labels = axes[0, 0].get_legend_handles_labels()
            if has_ref:
                handles += [
                    Line2D([], [], color="k", ls="-", lw=1.0),
                    Line2D([], [], color="k", ls="--", lw=1.0),
                ]
                labels += ["achieved", "reference"]
            fig.legend(handles, labels, loc="center right", fontsize=7, frameon=False)
            fig.suptitle(f"{trajectory} ({mode} mode): {title}")
            fig.tight_layout(rect=(0, 0, 0.72, 1))
            paths.append(_save(fig, Path(folder) / f"{trajectory}__{quantity}.png"))
    return paths


def _identical_runs(recs: Sequence[Recording]) -> dict[str, str]:
    """First run of each group of identical motions -> its label, e.g. ``"wqp-daqp (= wqp-osqp,
    wqp-proxqp)"``: runs whose configurations agree to 1e-9 (rad, m) at every tick."""
    groups: list[list[Recording]] = []
    for rec in recs:
        for group in groups:
            head = group[0]
            if head.q.shape == rec.q.shape and np.allclose(head.q, rec.q, rtol=0, atol=1e-9):
                group.append(rec)
                break
        else:
            groups.append([rec])
    out = {}
    for group in groups:
        names = [_label(r) for r in group]
        out[names[0]] = names[0] + (f" (= {', '.join(names[1:])})" if len(names) > 1 else "")
    return out


def _has(rec: Recording, quantity: str) -> bool:
    needs = {
        "com": ("com", "com_ref"),
        "swing": ("swing", "swing_ref"),
        "com_error": ("com", "com_ref"),
        "swing_error": ("swing", "swing_ref"),
        "limit_margin": ("limit_margin",),
        "time": ("solve_time",),
    }[quantity]
    return all(n in rec.channels for n in needs)


def run_figure(rec: Recording, path: Path) -> Path:
    """One run: reference (dashed) vs achieved (solid, same colour) CoM and swing sole, and
    their errors, over time (s); PNG and SVG."""
    plt = _pyplot()
    t = rec.t
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    axis_colour = dict(zip("xyz", ("tab:blue", "tab:orange", "tab:green"), strict=True))
    for ax, name in ((axes[0, 0], "com"), (axes[0, 1], "swing")):
        origin = rec[f"{name}_ref"][0]  # displacements: x, y and z share one scale
        for k, axis in enumerate("xyz"):
            c = axis_colour[axis]
            ax.plot(t, (rec[f"{name}_ref"][:, k] - origin[k]) * 1e3, "--", color=c,
                    label=f"{axis} reference")  # fmt: skip
            ax.plot(t, (rec[name][:, k] - origin[k]) * 1e3, "-", color=c, label=f"{axis}")
    axes[0, 0].set_title("CoM, from its start (mm)")
    axes[0, 1].set_title("swing sole, from its start (mm)")
    axes[1, 0].semilogy(t, np.linalg.norm(rec["com"] - rec["com_ref"], axis=1) * 1e3 + 1e-9)
    axes[1, 0].set_title("CoM error (mm)")
    axes[1, 1].semilogy(t, np.linalg.norm(rec["swing"] - rec["swing_ref"], axis=1) * 1e3 + 1e-9)
    axes[1, 1].set_title("swing-sole position error (mm)")
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=7, ncol=3)
    axes[0, 1].legend(fontsize=7, ncol=3)
    axes[1, 0].set_xlabel("time (s)")
    axes[1, 1].set_xlabel("time (s)")
    fig.suptitle(
        f"{rec.meta.get('solver', '?')} on {rec.meta.get('trajectory', '?')} "
        f"({rec.meta.get('mode', '?')} mode)"
    )
    fig.tight_layout()
    return _save(fig, path)


def timing_figure(records: Sequence[dict[str, Any]], path: Path) -> Path:
    """Median and p99 time per tick (µs, log scale) of every solver, per trajectory."""
    plt = _pyplot()
    trajectories = sorted({r["trajectory"] for r in records if "time_p99_us" in r})
    fig, axes = plt.subplots(
        len(trajectories), 1, figsize=(11, 3.2 * len(trajectories)), squeeze=False
    )
    for ax, traj in zip(axes[:, 0], trajectories, strict=True):
        rows = [r for r in records if r["trajectory"] == traj and "time_p99_us" in r]
        names = [r["solver"] for r in rows]
        x = np.arange(len(rows))
        ax.bar(x - 0.2, [r["time_median_us"] for r in rows], 0.4, label="median")
        ax.bar(x + 0.2, [r["time_p99_us"] for r in rows], 0.4, label="p99")
        ax.set_yscale("log")
        ax.set_xticks(x, names, rotation=60, ha="right", fontsize=7)
        clocks = dict.fromkeys(str(r.get("time_clock", "wall")) for r in rows)
        ax.set_ylabel(f"{'/'.join(clocks)} µs per tick")
        ax.set_title(traj)
        ax.grid(True, axis="y", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    return _save(fig, path)
