"""Naming what conflicts when a hard level cannot be met."""

from __future__ import annotations

import numpy as np

from .cascade import LevelProblem, LevelSolution


def conflicts(
    problem: LevelProblem, solution: LevelSolution, tol: float, tasks: bool = True
) -> list[tuple[str, float]]:
    """(name, size) of every task whose residual or constraint whose slack exceeds ``tol``."""
    out = []
    for name, sl in problem.task_rows if tasks else []:
        r = float(np.linalg.norm(solution.residual[sl]))
        if r > tol:
            out.append((name, r))
    for name, sl in problem.constraint_rows:
        s = float(np.max(solution.slack[sl], initial=0.0))
        if s > tol:
            out.append((name, s))
    return out


def infeasible_message(
    problem: LevelProblem, solution: LevelSolution, tol: float, label: str | None = None
) -> str:
    """'hard level 0 is infeasible: contact_l_sole (residual 1.2e-03), com_polygon (...)'."""
    found = conflicts(problem, solution, tol)
    what = label or f"hard level {problem.priority}"
    if not found:
        return f"{what} is infeasible (no single task or constraint stands out)"
    parts = ", ".join(f"{name} (residual {size:.3g})" for name, size in found)
    named = {name for name, _ in found}
    active = [name for name in active_constraints(problem, solution, tol) if name not in named]
    with_active = f" together with {', '.join(active)} (active)" if active else ""
    return f"{what} is infeasible: cannot satisfy {parts}{with_active}"


def active_constraints(problem: LevelProblem, solution: LevelSolution, tol: float) -> list[str]:
    """Constraints of the level at (or beyond) their bound in the solution."""
    return [
        name
        for name, sl in problem.constraint_rows
        if np.max(solution.margin[sl], initial=-np.inf) > -tol
    ]
