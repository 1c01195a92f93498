"""The benchmark: every solver family on the same trajectories (``wbc bench``)."""
