"""wbc.viewer."""
