"""wbc.bench."""
