"""srpb-gym: human-aware robot navigation environments scored by the SRPB metrics."""

__version__ = "0.1.0"
