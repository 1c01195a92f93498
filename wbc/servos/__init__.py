"""wbc.servos."""
