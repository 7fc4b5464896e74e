"""Suites: the schema of a suite file, reading it with line numbers, expanding it into
typed cells."""

from senbench.suite.cell import CURVE_VERSION, Cell
from senbench.suite.expand import Suite, load_suite  # noqa: I001 - after cell

__all__ = ["CURVE_VERSION", "Cell", "Suite", "load_suite"]
