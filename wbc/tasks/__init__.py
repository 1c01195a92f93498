"""wbc.tasks."""
