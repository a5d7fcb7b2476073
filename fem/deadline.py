"""A wall-clock deadline for the long parts of a body's setup, set by whoever waits.

A print on a large soft body needs its nodes' compliance columns, one sparse solve
per node the first time (on a foam mat: 24 solves of 70 ms, 1.7 s for one print
from a cold cache). A caller with a time budget (a planner's posture solve) sets a
deadline around its work with :func:`deadline`; the setup checks it between those
solves (:func:`check_deadline`) and stops with a :class:`SetupTimeout` once it has
passed. What was computed stays cached, so the next call goes on from there.

The deadline is a context variable, not an argument threaded through every layer
between a posture solve and a body's columns: like numpy's ``errstate``, it holds
within the ``with`` block of the thread (or task) that set it.
"""

from __future__ import annotations

import contextlib
import contextvars
import time

from .errors import FemError

__all__ = ["SetupTimeout", "check_deadline", "deadline"]

_DEADLINE = contextvars.ContextVar("softcbm_fem_deadline", default=None)


class SetupTimeout(FemError):
    """The deadline set with :func:`deadline` passed during a body's setup."""


@contextlib.contextmanager
def deadline(when):
    """Within the block, setups stop once ``time.perf_counter()`` passes ``when``.

    Parameters
    ----------
    when : float or None
        A ``time.perf_counter()`` value; None: no deadline (the block's setups run
        to the end).
    """
    token = _DEADLINE.set(None if when is None else float(when))
    try:
        yield
    finally:
        _DEADLINE.reset(token)


def check_deadline(what: str) -> None:
    """Raise :class:`SetupTimeout` if the deadline of the enclosing :func:`deadline` block has passed.

    Parameters
    ----------
    what : str
        What was under way, for the message (e.g. "the compliance columns of 24
        nodes of a print (9 ready)").
    """
    when = _DEADLINE.get()
    if when is not None and time.perf_counter() > when:
        raise SetupTimeout(f"the deadline passed during {what}; what was computed is kept for the next call")
