"""Posture results that cross a process boundary.

A :class:`~stances.results.PostureResult` keeps its displacement fields lazy:
closures over the solve's contact models, which cannot be pickled. A worker
process sends :func:`portable` results (no fields, everything else to the
bit); the receiving process, which holds the same robot and scene, gets the
fields back, still lazy, with :func:`restore_deformations`.
"""

from __future__ import annotations

from dataclasses import replace
from functools import cache

from .problem import build_problem
from .results import LazyDeformations, PostureResult
from .sqp import deformation_fields
from .stages import posture_options

__all__ = ["portable", "restore_deformations"]


def portable(result: PostureResult) -> PostureResult:
    """The result without its displacement fields, so that it pickles.

    Parameters
    ----------
    result : PostureResult

    Returns
    -------
    PostureResult
        Same values; ``deformations`` empty.
    """
    return replace(result, deformations={})


def restore_deformations(robot, scene, result: PostureResult) -> PostureResult:
    """The result with its displacement fields computed again on access.

    The fields are those the solve would have given (eq. 36 at ``result.q``
    under ``result.point_forces``); the posture problem is built again, with
    the options the solve recorded, only when a field is first read.

    Parameters
    ----------
    robot : stances.Robot
    scene : environments.Scene
        The robot and scene the result was solved with.
    result : PostureResult
        A :func:`portable` result (any result: its fields are replaced).

    Returns
    -------
    PostureResult
    """
    stance = result.stance
    names = [obj.name for obj in _touched(scene, stance)]
    if not names:
        return replace(result, deformations={})

    @cache
    def fields():
        options = posture_options(dict(result.statistics.get("options", {})))
        problem = build_problem(robot, scene, stance, options)
        return deformation_fields(problem, result.q, result.point_forces)

    return replace(result, deformations=LazyDeformations({name: _field_of(fields, name) for name in names}))


def _touched(scene, stance):
    """Deformable objects under the stance's prints, each once, in contact order."""
    touched = {}
    for contact in stance:
        obj = scene.deformable_of_surface(contact.contact_print.surface)
        if obj is not None:
            touched.setdefault(obj.name, obj)
    return list(touched.values())


def _field_of(fields, name):
    return lambda: fields()[name]
