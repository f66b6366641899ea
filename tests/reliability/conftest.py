"""Fixtures of the reliability tests: the random rigs of the I/O tests."""

from tests.io.conftest import make_rig  # noqa: F401  (a fixture: registered by being imported here)
