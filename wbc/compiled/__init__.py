"""Compiled (numba) kernels for the solvers' hot path: task rows and the box/equality
least-squares level solver shared by the weighted and the hierarchical QP."""
