"""Measurements that print the figures quoted in docs/benchmarks.md: ``python -m benchmarks.NAME`` from the
repository root, or ``python benchmarks/NAME.py``."""
