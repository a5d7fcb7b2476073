"""Why stances were rejected: the search's infeasible answers summarised by cause.

A failed plan is only useful if it says what stood in the way. Each rejected
stance's reason names the constraint that could not hold (see
:func:`stances.solve`); grouped by constraint family, the counts say whether a
scene fails on reach, torque, collision, the soft supports or the time budget.
"""

from __future__ import annotations

from collections import Counter

__all__ = ["CAUSES", "INPUT_CAUSES", "cause_of", "summarise"]

# Constraint families, matched in this order against the text a reason starts
# with once its qualifiers ("held rigid, ", "print unreachable: ") are removed.
CAUSES = (
    ("time", ("time budget", "time limit")),
    ("verification", ("verification failed",)),
    ("reach (placement)", ("placement",)),
    ("balance (static equilibrium)", ("static equilibrium",)),
    ("torque limit", ("torque limit",)),
    ("collision", ("collision",)),
    ("friction", ("friction cone", "node contact")),
    ("soft support (indentation, strain, contact)", ("indentation", "strain", "touch", "contact of")),
    ("normal load", ("normal load",)),
)
# Input the scene and robot do not fit (a StanceError's text), matched anywhere in it.
INPUT_CAUSES = (
    ("soft mesh too coarse for the print", (" mesh node(s); at least",)),
    ("prints overlap", ("prints of ",)),
    ("print off its surface", ("lies off surface",)),
)
_QUALIFIERS = ("held rigid, ", "print unreachable: ")


def cause_of(reason: str) -> str:
    """The constraint family a rejection reason names ("other" if none).

    Examples
    --------
    >>> cause_of("held rigid, print unreachable: placement of left_sole on floor (x) violated by 0.5 m")
    'reach (placement)'
    >>> cause_of("torque limit of arm_right_2_joint less its 10 % margin violated by 3.1 N m")
    'torque limit'
    >>> cause_of("StanceError: the print of right_front_foot on foam_top holds 2 mesh node(s); at least 3 are needed")
    'soft mesh too coarse for the print'
    """
    text = str(reason)
    for cause, fragments in INPUT_CAUSES:
        if any(fragment in text for fragment in fragments):
            return cause
    for qualifier in _QUALIFIERS:
        if text.startswith(qualifier):
            text = text[len(qualifier):]
    for cause, prefixes in CAUSES:
        if text.startswith(prefixes):
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
