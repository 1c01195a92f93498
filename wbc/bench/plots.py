"""Figures like the thesis's Fig. 4.2-4.5, and a time-per-tick comparison across solvers."""

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


def run_figure(rec: Recording, path: Path) -> Path:
    """Reference vs achieved CoM and swing sole, and their errors, over the ticks."""
    plt = _pyplot()
    i = np.arange(len(rec))
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    for ax, name in ((axes[0, 0], "com"), (axes[0, 1], "swing")):
        origin = rec[f"{name}_ref"][0]  # displacements: x, y and z share one scale
        for k, axis in enumerate("xyz"):
            ax.plot(i, (rec[f"{name}_ref"][:, k] - origin[k]) * 1e3, "--", label=f"{axis} ref")
            ax.plot(i, (rec[name][:, k] - origin[k]) * 1e3, label=f"{axis}")
    axes[0, 0].set_title("CoM, from its start (mm)")
    axes[0, 1].set_title("swing sole, from its start (mm)")
    axes[1, 0].semilogy(i, np.linalg.norm(rec["com"] - rec["com_ref"], axis=1) * 1e3 + 1e-9)
    axes[1, 0].set_title("CoM error (mm)")
    axes[1, 1].semilogy(i, np.linalg.norm(rec["swing"] - rec["swing_ref"], axis=1) * 1e3 + 1e-9)
    axes[1, 1].set_title("swing-sole position error (mm)")
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=7, ncol=3)
    axes[0, 1].legend(fontsize=7, ncol=3)
    axes[1, 0].set_xlabel("tick / pose")
    axes[1, 1].set_xlabel("tick / pose")
    fig.suptitle(
        f"{rec.meta.get('solver', '?')} on {rec.meta.get('trajectory', '?')} "
        f"({rec.meta.get('mode', '?')} mode)"
    )
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


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
        ax.set_ylabel("µs per tick")
        ax.set_title(traj)
        ax.grid(True, axis="y", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
