"""wbc.pinv."""
