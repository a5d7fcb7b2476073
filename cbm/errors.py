"""Exceptions of the planner package."""

from __future__ import annotations

__all__ = ["CbmError", "MotionError", "UnknownScenario", "PlanFileError"]


class CbmError(ValueError):
    """Base class of the errors raised by :mod:`cbm` for bad input."""


class UnknownScenario(CbmError):
    """A scenario name that is neither built in nor an existing file.

    Parameters
    ----------
    name : str
        The name or path given.
    valid_names : sequence of str
        The built-in scenario names, listed in the message.
    """

    def __init__(self, name, valid_names):
        self.name = name
        self.valid_names = tuple(valid_names)
        listed = ", ".join(self.valid_names) if self.valid_names else "(none)"
        super().__init__(
            f"unknown scenario {name!r}: not a file and not one of the built-in "
            f"scenarios: {listed}"
        )


class PlanFileError(CbmError):
    """A plan file that cannot be read back (missing key, wrong version)."""


class MotionError(CbmError):
    """Stances that no motion joins (not differing by one contact, no posture)."""
