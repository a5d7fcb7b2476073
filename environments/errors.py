"""Exceptions of the environments package.

``SceneError`` is the one base exception: a caller passed something wrong (a
polygon that is not convex, an unknown surface name, ...). ``ScenarioError``
adds where, in a scenario file, the fault is.
"""

from __future__ import annotations

import os

__all__ = ["SceneError", "ScenarioError"]


class SceneError(ValueError):
    """Invalid scene data: a bad shape, an unknown name, a print off its surface."""


class ScenarioError(SceneError):
    """Invalid scenario file, with the file, the key path and the line at fault.

    Parameters
    ----------
    path : str or os.PathLike or None
        The scenario file (None for data that did not come from a file).
    key : str
        Dotted key path inside the file, e.g. ``"stances.stand.left_sole.surface"``;
        empty for the whole document.
    message : str
        What is wrong and what would be valid.
    line : int or None
        1-based line in the file, when known.

    Examples
    --------
    >>> str(ScenarioError("foo.yaml", "stances.walk.left_sole.surface",
    ...                   "unknown surface 'flor'; known surfaces: floor", line=12))
    "foo.yaml:12: stances.walk.left_sole.surface: unknown surface 'flor'; known surfaces: floor"
    """

    def __init__(
        self,
        path: str | os.PathLike | None,
        key: str,
        message: str,
        line: int | None = None,
    ) -> None:
        self.path = None if path is None else os.fspath(path)
        self.key = key
        self.message = message
        self.line = line
        where = self.path if self.path is not None else "<scenario>"
        if line is not None:
            where = f"{where}:{line}"
        text = f"{where}: {key}: {message}" if key else f"{where}: {message}"
        super().__init__(text)


def known_names(names) -> str:
    """Format a collection of valid names for an error message.

    Parameters
    ----------
    names : iterable of str
        The valid names.

    Returns
    -------
    str
        Sorted names separated by commas, or ``"(none)"``.
    """
    names = sorted(names)
    return ", ".join(names) if names else "(none)"
