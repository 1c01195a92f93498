"""The package's version (a leaf of the base layer: :mod:`wbc.recording` stamps it on a run's
validity record without importing the package above it)."""

__version__ = "0.1.0"
