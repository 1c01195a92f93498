"""wbc.solvers."""
