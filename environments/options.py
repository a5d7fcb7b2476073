"""The planner options a scenario may carry (its ``options`` mapping), validated.

The scenario file holds them as plain data for the planner (:mod:`cbm`), but
they are checked here, with the rest of the file, so that a typo or a wrong type
is reported with the file, key and line instead of being ignored (an unknown
key), failing deep in the planner (a number where a list is expected) or being
silently misread (a string iterated letter by letter).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from .errors import ScenarioError

__all__ = ["SCENARIO_OPTIONS", "validate_options"]

#: Each option a scenario may set, with the value it takes.
SCENARIO_OPTIONS = {
    "print_spacing": "a number > 0, metres: step of the print grid on every surface",
    "theta_values_deg": "a non-empty list of numbers, degrees: print headings sampled",
    "print_margin": "a number >= 0, metres: distance prints keep inside their surface",
    "sampling_region": "a mapping {lower: [x, y], upper: [x, y]}, metres, world frame, lower <= upper",
    "robot_surfaces": "a non-empty list of robot surface names, e.g. [left_sole, right_sole]",
    "terrain_weight": "a number >= 0, metres of goal distance per joule of the soft supports' deformation energy",
}


def validate_options(options, path=None) -> dict:
    """Check a scenario's ``options`` and return them as plain, normalised data.

    Parameters
    ----------
    options : mapping or None
        The scenario's ``options`` (None: no options).
    path : str or os.PathLike, optional
        The scenario file, for messages.

    Returns
    -------
    dict
        The same keys; numbers as float, lists as lists, the region as
        ``{"lower": [x, y], "upper": [x, y]}``.

    Raises
    ------
    ScenarioError
        Naming ``options.<key>``, what is wrong and the valid keys or the value
        expected (:data:`SCENARIO_OPTIONS`).

    Examples
    --------
    >>> validate_options({"print_spacing": 0.1, "theta_values_deg": [0, 90]})
    {'print_spacing': 0.1, 'theta_values_deg': [0.0, 90.0]}
    >>> validate_options({"print_spacin": 0.1})
    Traceback (most recent call last):
    ...
    environments.errors.ScenarioError: <scenario>: options.print_spacin: unknown option 'print_spacin'; valid options: print_spacing, theta_values_deg, print_margin, sampling_region, robot_surfaces, terrain_weight
    """
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ScenarioError(path, "options", f"must be a mapping of {', '.join(SCENARIO_OPTIONS)}; got {_kind(options)}")
    checked = {}
    for name, value in options.items():
        key = f"options.{name}"
        if name not in SCENARIO_OPTIONS:
            raise ScenarioError(path, key, f"unknown option {name!r}; valid options: {', '.join(SCENARIO_OPTIONS)}")
        expected = SCENARIO_OPTIONS[name]
        if name == "print_spacing":
            checked[name] = _number(value, path, key, expected, lambda v: v > 0.0)
        elif name in ("print_margin", "terrain_weight"):
            checked[name] = _number(value, path, key, expected, lambda v: v >= 0.0)
        elif name == "theta_values_deg":
            if not isinstance(value, (list, tuple)) or not value:
                raise ScenarioError(path, key, f"must be {expected}; got {_kind(value)}")
            checked[name] = [_number(v, path, f"{key}[{i}]", expected) for i, v in enumerate(value)]
        elif name == "sampling_region":
            checked[name] = _region(value, path, key, expected)
        else:  # robot_surfaces
            if (
                not isinstance(value, (list, tuple))
                or not value
                or not all(isinstance(v, str) and v for v in value)
            ):
                raise ScenarioError(path, key, f"must be {expected}; got {_kind(value)}")
            checked[name] = list(value)
    return checked


def _number(value, path, key: str, expected: str, in_range=None) -> float:
    # YAML 1.1 reads "1e-1" (no dot) as a string, so strings float() reads pass,
    # as elsewhere in scenario files; booleans are not numbers here.
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise ScenarioError(path, key, f"must be {expected}; got {_kind(value)}")
    try:
        number = float(value)
    except ValueError:
        raise ScenarioError(path, key, f"must be {expected}; got {value!r}") from None
    if not math.isfinite(number) or (in_range is not None and not in_range(number)):
        raise ScenarioError(path, key, f"must be {expected}; got {value!r}")
    return number


def _region(value, path, key: str, expected: str) -> dict:
    if not isinstance(value, Mapping) or set(value) != {"lower", "upper"}:
        raise ScenarioError(path, key, f"must be {expected}; got {_kind(value)}")
    corners = {}
    for corner in ("lower", "upper"):
        pair = value[corner]
        if not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise ScenarioError(path, f"{key}.{corner}", f"must be a list [x, y] of 2 numbers, metres; got {_kind(pair)}")
        corners[corner] = [_number(v, path, f"{key}.{corner}[{i}]", "a number, metres") for i, v in enumerate(pair)]
    if any(low > high for low, high in zip(corners["lower"], corners["upper"])):
        raise ScenarioError(path, key, f"lower {corners['lower']} must be <= upper {corners['upper']} on x and y")
    return corners


def _kind(value) -> str:
    if value is None:
        return "nothing"
    if isinstance(value, Mapping):
        return f"a mapping with keys {', '.join(map(str, value)) or '(none)'}"
    if isinstance(value, (list, tuple)):
        return f"a list of {len(value)}"
    return f"{type(value).__name__} {value!r}"
