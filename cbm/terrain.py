"""Terrain-aware path cost: the elastic energy each stance stores in its soft supports.

The quantity is the deformation energy of the soft bodies a stance loads,
``1/2 F_P . U_P`` summed over them (joules), read from the posture's
verification (``deformation energy of <body>``, :mod:`stances.deformable`):
by Clapeyron's theorem it is ``1/2 U^T K U``, the strain energy of the
paper's weak form (eq. 6 with w = u), and with the condensed stiffness of a
print (eq. 27's ``S_P``) it is ``1/2 U_P^T S_P U_P = 1/2 F_P^T C_P F_P``.
It is chosen over the deepest indentation (metres) because:

- it ranks supports by stiffness at equal load (``F^2 / 2k`` for a spring:
  a mat twice as stiff stores half the energy) and by load on one support (a
  sole carrying the whole weight stores four times the energy of one carrying
  half), where a depth misses how many nodes and how much force go down;
- it adds up: over the bodies of one stance (two mats at once) and over the
  stances of a plan, so the path cost of a plan is its total energy, in one
  unit, while a deepest print is a maximum and says nothing of how widely or
  how often the ground is pressed;
- it is zero on rigid supports, so rigid plans pay nothing, and it is
  non-negative (``C_P`` is positive definite), as a lower-bounded search needs.

The paper's own deformation term (its note 2: the norm of the nodal reaction
forces, in the posture objective) acts within one stance; this acts between
stances, in the search's priority. The weight is in metres of goal distance
per joule, the heuristic's unit (:func:`cbm.plan`'s ``terrain_weight``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import CbmError

__all__ = ["TerrainCost", "deformation_energy", "deepest_indentation", "terrain_weight"]

_ENERGY = "deformation energy of "
_INDENTATION = "indentation of "


def terrain_weight(scenario_options=None, weight=None) -> float:
    """The terrain weight of a plan: the caller's, else the scenario's option, else 0.

    Parameters
    ----------
    scenario_options : mapping or None
        A scenario's ``options`` (``terrain_weight``, validated on loading).
    weight : float, optional
        The caller's weight, metres of goal distance per joule; wins.

    Returns
    -------
    float
        >= 0 and finite.

    Raises
    ------
    CbmError
        If the weight taken is not a finite number >= 0.

    Examples
    --------
    >>> terrain_weight({"terrain_weight": 2.0}), terrain_weight({"terrain_weight": 2.0}, 0.5), terrain_weight()
    (2.0, 0.5, 0.0)
    """
    if weight is None:
        weight = (scenario_options or {}).get("terrain_weight", 0.0)
    if isinstance(weight, bool) or not isinstance(weight, (int, float)) or not math.isfinite(weight) or weight < 0:
        raise CbmError(f"terrain_weight must be a finite number >= 0 (metres of goal distance per joule), got {weight!r}")
    return float(weight)


def _measures(result):
    verification = getattr(result, "verification", None)
    if verification is None:
        raise CbmError(
            "the terrain cost reads the soft bodies' energy from a posture's verification; "
            f"this result has none (stance {getattr(result, 'stance', None)})"
        )
    return verification.measures


def deformation_energy(result) -> float:
    """Elastic energy the posture stores in the soft bodies it presses, joules.

    Parameters
    ----------
    result : stances PostureResult
        A verified result (its ``verification.measures``).

    Returns
    -------
    float
        Sum over the soft bodies, >= 0; 0.0 for a stance on rigid supports.

    Raises
    ------
    CbmError
        If the result carries no verification.
    """
    measures = _measures(result)
    total = sum(value for key, value in measures.items() if key.startswith(_ENERGY))
    # F . C F >= 0 exactly; its rounding may dip below 0 by an ulp when F is ~0.
    return max(float(total), 0.0)


def deepest_indentation(result) -> float:
    """Deepest print node of the posture, metres along the surface normal, 0.0 if rigid.

    Raises
    ------
    CbmError
        If the result carries no verification.
    """
    depths = [value for key, value in _measures(result).items() if key.startswith(_INDENTATION)]
    return max([0.0, *map(float, depths)])


@dataclass(frozen=True)
class TerrainCost:
    """A stance's terrain cost for the search: ``weight`` times its deformation energy.

    The search's ``node_cost`` (:func:`cbm.search.best_first_search`): known
    only once the stance is solved, added to the priority of every path through
    it, in metres of goal distance.

    Parameters
    ----------
    weight : float
        Metres of goal distance per joule, finite and >= 0.

    Raises
    ------
    CbmError
        If ``weight`` is not a finite number >= 0.
    """

    weight: float

    def __post_init__(self):
        object.__setattr__(self, "weight", terrain_weight(None, self.weight))

    def __call__(self, stance, check) -> float:
        """Cost of a feasible stance from its oracle answer (a StanceCheck)."""
        return self.weight * deformation_energy(check.result)
