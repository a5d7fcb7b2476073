"""Checks shared by the readers of YAML files (scenarios here, robot descriptions in stances).

Each reader has its own error type (with its file); these helpers take the
reader's ``error(key, message)`` factory, so every message names the dotted key
path at fault and says what would be valid.
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["join_key", "kind_of", "checked_mapping"]


def join_key(key: str, name) -> str:
    """Dotted key path of ``name`` inside ``key`` (``"objects[1]"`` + ``"size"``)."""
    return f"{key}.{name}" if key else str(name)


def kind_of(value) -> str:
    """A short description of a value for messages: ``"a mapping"``, ``"a list of 2"``, ``"int 3"``."""
    if value is None:
        return "nothing"
    if isinstance(value, Mapping):
        return "a mapping"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    return f"{type(value).__name__} {value!r}"


def checked_mapping(value, key: str, allowed, required, error) -> dict:
    """A mapping with only ``allowed`` keys and every ``required`` one, as a dict.

    Parameters
    ----------
    value : object
        The YAML value.
    key : str
        Its dotted key path.
    allowed, required : sequence of str
        Valid keys, and those that must be present.
    error : callable
        ``error(key, message)`` returns the exception to raise.

    Raises
    ------
    Exception
        What ``error`` returns, for a non-mapping, an unknown or a missing key.
    """
    if not isinstance(value, Mapping):
        raise error(key, f"must be a mapping with keys {', '.join(allowed)}; got {kind_of(value)}")
    for name in value:
        if name not in allowed:
            raise error(join_key(key, name), f"unknown key {name!r}; valid keys: {', '.join(allowed)}")
    for name in required:
        if name not in value:
            raise error(key, f"missing key {name!r}")
    return dict(value)
