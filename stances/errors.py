"""Exceptions of the ``stances`` package.

Every error a caller can cause derives from :class:`StanceError`, a
``ValueError``, so ``except ValueError`` keeps working for generic callers while
``except StanceError`` catches exactly this package's complaints.
"""

from __future__ import annotations


class StanceError(ValueError):
    """Base class of the errors raised by :mod:`stances` on bad input."""


class RobotNotFound(StanceError):
    """The robot name is not one of the robots this package knows how to load."""


class FrameNotFound(StanceError):
    """A frame, link or robot contact surface name does not exist.

    Parameters
    ----------
    kind : str
        What was looked up ("frame", "robot surface", ...).
    name : str
        The name that was not found.
    known : iterable of str
        The valid names, listed in the message so the user can pick one.
    context : str, optional
        Who asked for the name (``"robot surface 'left_sole'"``), put first in the message.
    """

    def __init__(self, kind: str, name: str, known, context: str = "") -> None:
        known = sorted(known)
        shown = ", ".join(known[:40]) + (", ..." if len(known) > 40 else "")
        prefix = f"{context}: " if context else ""
        super().__init__(f"{prefix}unknown {kind} {name!r}; known {kind}s: {shown}")
        self.name = name
        self.known = known


class ConfigurationError(StanceError):
    """A configuration vector has the wrong size, NaNs, or a non-unit quaternion."""
