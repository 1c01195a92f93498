"""wbc.limits."""
