"""Thin command-line entry points: ``python -m recipes.NAME`` or ``python recipes/NAME.py`` (docs/architecture.md)."""
