"""Why stances were rejected: the search's infeasible answers summarised by cause.

A failed plan is only useful if it says what stood in the way. Each rejected
stance's reason names the constraint that could not hold (see
:func:`stances.solve`); grouped by constraint family, the counts say whether a
scene fails on reach, torque, collision, the soft supports or the time budget.
"""

from __future__ import annotations

import re
from collections import Counter

from stances.deformable import PIVOTING_REFUSAL, PIVOTING_ROW
from stances.sqp import SOFT_SUPPORT_GIVES, SOFT_SUPPORT_ROWS
from stances.stages import HELD_AT_NODES, HELD_RIGID

__all__ = [
    "CAUSES", "INPUT_CAUSES", "UNRESOLVED_BALL", "cause_of", "finer_grid_hint", "pivoting_print_hint", "soft_support_hint",
    "stiff_reach_hint", "strain_bound_hint", "summarise", "unresolved_ball_hint",
]

#: The cause of a ball foot's refusal for a contact the soft body's mesh does not resolve.
UNRESOLVED_BALL = "ball foot with no converged force on the soft mesh"

_SOFT_SUPPORT = "soft support (indentation, strain, contact)"
# Constraint families, matched in this order against the text a reason starts
# with once its qualifiers (HELD_RIGID, HELD_AT_NODES, "print unreachable: ") are removed.
CAUSES = (
    ("time", ("time budget", "time limit")),
    ("verification", ("verification failed",)),
    ("reach (placement)", ("placement",)),
    ("balance (static equilibrium)", ("static equilibrium", "centre of pressure")),
    ("torque limit", ("torque limit",)),
    ("collision", ("collision",)),
    ("friction", ("friction cone", "node contact")),
    (_SOFT_SUPPORT, ("indentation", "strain", "touch", "contact of", "tilt of the face", "mesh overlap",
                     SOFT_SUPPORT_GIVES)),
    ("normal load", ("normal load",)),
)
# Input the scene and robot do not fit (a StanceError's text), matched anywhere in it.
INPUT_CAUSES = (
    ("soft mesh too coarse for the print", (" mesh node(s); at least", " cells of the mesh under it; at least")),
    # A ball foot's contact the mesh does not resolve (stances.deformable, ball_force_error):
    # the mesh, not the start, decides it.
    (UNRESOLVED_BALL, ("resolve a ball's contact", "smaller than the mesh resolves")),
    ("prints overlap", ("prints of ",)),
    ("print off its surface", ("lies off surface",)),
)
_QUALIFIERS = (HELD_RIGID, HELD_AT_NODES, "print unreachable: ")
# The soft support's rows that can stand between a print and its placement (a sole on a soft
# block's edge, whose partly covered nodes would bulge past its face: a new user's soft step,
# 19 of 38 rejections read as reach): where the conflict names one, the soft support is the cause
# (stances.sqp names those reasons so, SOFT_SUPPORT_GIVES, where the placement is a soft print's).
_SOFT_BLOCKS = SOFT_SUPPORT_ROWS
# The solver's list of constraints no step meets together (stances.sqp), after the reason.
_CONFLICT = "; no step meets together: "


def cause_of(reason: str) -> str:
    """The constraint family a rejection reason names ("other" if none).

    Examples
    --------
    >>> cause_of("even with its soft supports held rigid: print unreachable: placement of left_sole on floor (x) "
    ...          "violated by 0.5 m")
    'reach (placement)'
    >>> cause_of("torque limit of arm_right_2_joint less its 10 % margin violated by 3.1 N m")
    'torque limit'
    >>> cause_of("StanceError: the print of right_front_foot on foam_top holds 2 mesh node(s); at least 3 are needed")
    'soft mesh too coarse for the print'

    A print left unreached because a collision stands in the way (the solver names
    both among the constraints no step meets together) is a collision: a user's
    mats end to end gave 30 "reach (placement)" rejections, each a foot that could
    not land without its heel meeting the next mat.

    >>> cause_of("even with its soft supports held rigid: print unreachable: placement of left_sole on mat_b_top (z) "
    ...          "violated by 0.001 m "
    ...          "or rad; no step meets together: collision between leg_left_6_link_0 and mat_a, placement of "
    ...          "left_sole on mat_b_top (x)")
    'collision'

    So is one whose soft support's own rows stand in the way (a sole on a soft block's edge):

    >>> cause_of("print unreachable: placement of left_sole on block_top (z, elastic) violated by 0.000118 m or rad; "
    ...          "no step meets together: placement of left_sole on block_top (z, elastic), mesh overlap bound "
    ...          "(0.002 m, max_mesh_overlap) at node 4353 of block")
    'soft support (indentation, strain, contact)'
    >>> cause_of("soft support cannot hold the print: placement of left_sole on mat_top (z, elastic) violated by "
    ...          "0.000567 m or rad; no step meets together: strain bound (compression) of tet 10968 of mat")
    'soft support (indentation, strain, contact)'
    """
    text = str(reason)
    for cause, fragments in INPUT_CAUSES:
        if any(fragment in text for fragment in fragments):
            return cause
    text, _, conflict = text.partition(_CONFLICT)
    for qualifier in _QUALIFIERS:
        if text.startswith(qualifier):
            text = text[len(qualifier):]
    for cause, prefixes in CAUSES:
        if text.startswith(prefixes):
            if cause == "reach (placement)":
                # A print left unreached because something stands in its way: that thing.
                blocking = conflict.split(", ")
                if any(c.startswith("collision") for c in blocking):
                    return "collision"
                if any(c.startswith(_SOFT_BLOCKS) for c in blocking):
                    return _SOFT_SUPPORT
            return cause
    return "other"


def summarise(reasons) -> dict:
    """Counts of rejections by cause, most frequent first, with one example each.

    Parameters
    ----------
    reasons : iterable of str

    Returns
    -------
    dict
        ``{cause: {"count": int, "example": str}}``, ordered by count (then
        cause name, so the order is the same on every run).
    """
    reasons = [str(r) for r in reasons]
    counts = Counter(cause_of(r) for r in reasons)
    examples = {}
    for reason in reasons:
        examples.setdefault(cause_of(reason), reason)
    ordered = sorted(counts, key=lambda cause: (-counts[cause], cause))
    return {cause: {"count": counts[cause], "example": examples[cause]} for cause in ordered}


#: Share of a failed search's rejected stances that collide from which a finer grid is suggested.
COLLIDING_SHARE = 0.5
#: Finest print grid suggested, metres.
FINEST_GRID = 0.02


def finer_grid_hint(reasons, spacing: float) -> str:
    """What to add to a search's reason when it ran out of budget among colliding stances.

    Where most rejected stances collide, the prints that clear the obstacles may lie
    between the grid's points: a user's mattress before a step, on a 0.1 m grid, spent
    200 expansions on stances whose links hit the step, and planned in 0.7 s on a 0.05 m
    grid.

    Parameters
    ----------
    reasons : iterable of str
        The rejected stances' reasons.
    spacing : float
        The print grid the search used, metres.

    Returns
    -------
    str
        ``""``, or a clause starting with ``"; "`` that names the share and a grid half
        as fine (not below :data:`FINEST_GRID`).

    Examples
    --------
    >>> finer_grid_hint(["collision between a and b"] * 3 + ["torque limit of j"], 0.1)
    '; 3 of the 4 stances rejected collide: a finer print grid offers prints between the obstacles (print_spacing 0.05, cbm plan --print-spacing 0.05)'
    >>> finer_grid_hint(["torque limit of j"] * 3, 0.1)
    ''
    """
    reasons = [str(r) for r in reasons]
    colliding = sum(cause_of(r) == "collision" for r in reasons)
    finer = spacing / 2.0
    if not reasons or colliding < COLLIDING_SHARE * len(reasons) or finer < FINEST_GRID:
        return ""
    return (
        f"; {colliding} of the {len(reasons)} stances rejected collide: a finer print grid offers prints between "
        f"the obstacles (print_spacing {finer:.3g}, cbm plan --print-spacing {finer:.3g})"
    )


#: Share of a failed search's rejected stances whose reason names a soft object's strain
#: bound (as the worst row or among the rows no step meets together) from which it is said.
STRAINED_SHARE = 0.5
#: The same share for stances refused for a ball foot the soft mesh does not resolve.
UNRESOLVED_SHARE = 0.5
#: The same share for stances whose sole or palm on a soft body could not keep its whole face down.
PIVOTING_SHARE = 0.5
#: The same share for stances refused on a stiff soft body where its prints' nodes reach.
STIFF_REACH_SHARE = 0.5
#: The same share for stances whose soft print sank deeper than its body's own rows allow.
SOFT_SUPPORT_SHARE = 0.5
# The solver's whole-print row (stances.deformable, max_corner_lift) and verify's refusal.
_PIVOTING = (PIVOTING_ROW, PIVOTING_REFUSAL)
# A soft print's strain row, a layer ball's converged one, and the equilibrium filter's ball
# that cannot carry its least load within the strain bound.
_STRAIN_ROW = re.compile(r"strain bound \((?:compression|tension)\) of tet \d+ of ([\w.-]+)"
                         r"|\(([\w.-]+)'s converged field\)|within ([\w.-]+)'s strain bound")


def strain_bound_hint(reasons) -> str:
    """What to add to a failed search's reason when most rejected stances ran into a soft
    object's strain bound, in their worst row or in the rows no step meets together.

    A soft support too soft for the robot's weight shows in every cause at once (balance,
    reach, the soft support itself: a new user's 12 cm block of 3e5 Pa foam to step onto),
    so the counts by cause do not name it.

    Parameters
    ----------
    reasons : iterable of str
        The rejected stances' reasons.

    Returns
    -------
    str
        ``""``, or a clause starting with ``"; "`` that names the object(s) and the share.

    Examples
    --------
    >>> strain_bound_hint(["static equilibrium (fx) violated by 2 N; no step meets together: "
    ...                    "strain bound (compression) of tet 7 of block, placement of a (x)",
    ...                    "strain bound (tension) of tet 9 of block violated by 0.02", "torque limit of j"])
    '; 2 of the 3 stances rejected meet the strain bound of block (the worst row or among those no step meets together): it may be too soft to stand on; a stiffer material or a larger strain_limit would carry more (the strain under a print follows its pressure over the stiffness: a thicker body lowers it little, if at all)'
    >>> strain_bound_hint(["torque limit of j"])
    ''
    """
    reasons = [str(r) for r in reasons]
    objects = [sorted({name for groups in _STRAIN_ROW.findall(r) for name in groups if name}) for r in reasons]
    strained = sum(bool(names) for names in objects)
    if not reasons or strained < STRAINED_SHARE * len(reasons):
        return ""
    named = ", ".join(sorted({name for names in objects for name in names}))
    return (
        f"; {strained} of the {len(reasons)} stances rejected meet the strain bound of {named} (the worst row or "
        "among those no step meets together): it may be too soft to stand on; a stiffer material or a larger "
        "strain_limit would carry more (the strain under a print follows its pressure over the stiffness: a thicker "
        "body lowers it little, if at all)"
    )


def unresolved_ball_hint(reasons) -> str:
    """What to add to a failed search's reason when most rejected stances put a ball foot where
    the soft mesh does not resolve its contact (:data:`UNRESOLVED_BALL`): on a soft body that is
    no layer for the ball's law (a step's tread, near an edge) no mesh gives a converged force.

    Parameters
    ----------
    reasons : iterable of str
        The rejected stances' reasons.

    Returns
    -------
    str
        ``""``, or a clause starting with ``"; "`` that gives the share and what to do.

    Examples
    --------
    >>> unresolved_ball_hint(["verification failed: lf presses 2 mesh node(s) of step, sunk 0.001 m, where no "
    ...                       "continuum estimate ...: the mesh's node contact does not resolve a ball's contact, "
    ...                       "...", "torque limit of j"])
    "; 1 of the 2 stances rejected put a ball foot where the soft mesh does not resolve its contact: keep the balls on soft bodies that are layers held on their base (a soft_box on the floor, away from its edges), where the layer's law gives their force, or plan with --solver-option ball_force_error=inf (solver_options={'ball_force_error': inf}) to accept such contacts"
    >>> unresolved_ball_hint(["torque limit of j"])
    ''
    """
    return _share_hint(
        reasons, lambda reason: cause_of(reason) == UNRESOLVED_BALL, UNRESOLVED_SHARE,
        "put a ball foot where the soft mesh does not resolve its contact: keep the balls on soft bodies that are "
        "layers held on their base (a soft_box on the floor, away from its edges), where the layer's law gives their "
        "force, or plan with --solver-option ball_force_error=inf (solver_options={'ball_force_error': inf}) to "
        "accept such contacts",
    )


def _share_hint(reasons, counts, share: float, what: str) -> str:
    """``"; N of the M stances rejected <what>"`` when the reasons ``counts(reason)`` holds for
    are at least ``share`` of them, else ``""``."""
    reasons = [str(r) for r in reasons]
    count = sum(bool(counts(r)) for r in reasons)
    if not reasons or count < share * len(reasons):
        return ""
    return f"; {count} of the {len(reasons)} stances rejected {what}"


def soft_support_hint(reasons) -> str:
    """What to add to a failed search's reason when most rejected stances had a soft print's
    sinking held back by its body's own rows (:data:`stances.sqp.SOFT_SUPPORT_GIVES`: its
    strain, or its mesh reaching into the link past ``max_mesh_overlap``): an audit's plan on
    cross-two-mats at half its stiffness ended "budget exhausted" after 73 s, all 60 of its
    rejections such. Parameters and return as :func:`unresolved_ball_hint`'s.

    Examples
    --------
    >>> soft_support_hint([SOFT_SUPPORT_GIVES + "placement of a on mat_top (z, elastic) violated by 0.0007 m",
    ...                    "torque limit of j"])
    '; 1 of the 2 stances rejected sank a print deeper than its soft support holds it (its strain bound, or its mesh reaching into the link): a stiffer material carries more, and a finer mesh under the prints reaches less far into the links'
    >>> soft_support_hint(["torque limit of j"])
    ''
    """
    return _share_hint(
        reasons, lambda reason: SOFT_SUPPORT_GIVES in reason, SOFT_SUPPORT_SHARE,
        "sank a print deeper than its soft support holds it (its strain bound, or its mesh reaching into the link): "
        "a stiffer material carries more, and a finer mesh under the prints reaches less far into the links",
    )


def stiff_reach_hint(reasons) -> str:
    """What to add to a failed search's reason when most rejected stances were refused on a
    steel-stiff soft body because its prints' nodes do not reach where the centre of pressure
    must be (:data:`stances.stages.HELD_AT_NODES`): on a body too stiff to give, a print carries
    loads only where its mesh nodes lie, and a coarse mesh stops them short of a print's edge (a
    leaning stance 5 mm from the soles' toe edge on a 1e10 Pa slab: refused at 22.5 mm, solved
    at 11 mm, ``bench/bench_stiff_slab.py``). Parameters and return as
    :func:`unresolved_ball_hint`'s.

    Examples
    --------
    >>> stiff_reach_hint([HELD_AT_NODES + "static equilibrium (fx) violated by 0.9 N", "torque limit of j"])
    "; 1 of the 2 stances rejected could not be held on a stiff soft body where its prints' nodes reach: a finer mesh under the prints (the soft_box's resolution and refine) lets them carry a centre of pressure nearer a print's edge, and a body that stiff can be a rigid one"
    >>> stiff_reach_hint(["torque limit of j"])
    ''
    """
    return _share_hint(
        reasons, lambda reason: reason.startswith(HELD_AT_NODES), STIFF_REACH_SHARE,
        "could not be held on a stiff soft body where its prints' nodes reach: a finer mesh under the prints "
        "(the soft_box's resolution and refine) lets them carry a centre of pressure nearer a print's edge, and a "
        "body that stiff can be a rigid one",
    )


def pivoting_print_hint(reasons) -> str:
    """What to add to a failed search's reason when most rejected stances could not keep a
    sole or palm on a soft body flat on it (``corner_sinking``, ``max_corner_lift``): a print
    pivoting on its edge presses a strip narrower than the mesh resolves, whose force is no
    converged one. Parameters and return as :func:`unresolved_ball_hint`'s.

    Examples
    --------
    >>> pivoting_print_hint(["contact of right_palm on cube_top (corner 1 lifted: pivoting on an edge) violated by 0.1",
    ...                      "torque limit of j"])
    "; 1 of the 2 stances rejected could not press a sole or palm on a soft body with its whole face: one that must lean on its edge is refused (its force on the mesh is no converged one); plan with --solver-option max_corner_lift=inf (solver_options={'max_corner_lift': inf}) to let prints pivot"
    >>> pivoting_print_hint(["torque limit of j"])
    ''
    """
    return _share_hint(
        reasons, lambda reason: any(fragment in reason for fragment in _PIVOTING), PIVOTING_SHARE,
        "could not press a sole or palm on a soft body with its whole face: one that must lean on its edge is "
        "refused (its force on the mesh is no converged one); plan with --solver-option max_corner_lift=inf "
        "(solver_options={'max_corner_lift': inf}) to let prints pivot",
    )
