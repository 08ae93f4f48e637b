"""mitlc: Metric Interval Temporal Logic tasks, compiled to timed LDGBA, checked and learned."""

__version__ = "0.1.0"
