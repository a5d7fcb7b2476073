"""Contact prints, contacts and stances: what a robot touches, and where.

A contact print is the image of a robot contact surface placed on an
environment contact surface at ``(x, y, theta)`` in the surface frame (the
paper's ``S_print``, Sec. III). A stance is a set of contacts, at most one per
robot surface, kept in a canonical order so that equal stances hash equally.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

from .errors import SceneError
from .geometry import wrap_angle

__all__ = ["ContactPrint", "Contact", "Stance"]


def _finite_float(value, name: str) -> float:
    if isinstance(value, bool):
        raise SceneError(f"{name} must be a number, got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise SceneError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(number):
        raise SceneError(f"{name} must be finite, got {number}")
    return number


def _name(value, what: str) -> str:
    if not isinstance(value, str) or not value:
        raise SceneError(f"{what} must be a non-empty string, got {value!r}")
    return value


@dataclass(frozen=True)
class ContactPrint:
    """A robot surface's image placed on an environment surface.

    Parameters
    ----------
    surface : str
        Name of the environment contact surface.
    x, y : float
        Print origin, metres, surface frame.
    theta : float
        Rotation about the surface normal, radians; stored wrapped to [-pi, pi].

    Examples
    --------
    >>> ContactPrint("floor", 0.0, 0.085, 0.0)
    ContactPrint(surface='floor', x=0.0, y=0.085, theta=0.0)
    """

    surface: str
    x: float
    y: float
    theta: float = 0.0

    def __post_init__(self) -> None:
        _name(self.surface, "ContactPrint.surface")
        object.__setattr__(self, "x", _finite_float(self.x, "ContactPrint.x"))
        object.__setattr__(self, "y", _finite_float(self.y, "ContactPrint.y"))
        theta = wrap_angle(_finite_float(self.theta, "ContactPrint.theta"))
        # -pi and pi are the same angle: keep one so equal prints compare equal.
        if theta <= -math.pi:
            theta = math.pi
        object.__setattr__(self, "theta", theta)


@dataclass(frozen=True)
class Contact:
    """A robot surface on a contact print.

    Parameters
    ----------
    robot_surface : str
        Name of the robot contact surface, e.g. ``"left_sole"``.
    contact_print : ContactPrint
        Where it lies.
    """

    robot_surface: str
    contact_print: ContactPrint

    def __post_init__(self) -> None:
        _name(self.robot_surface, "Contact.robot_surface")
        if not isinstance(self.contact_print, ContactPrint):
            raise SceneError(
                f"Contact.contact_print must be a ContactPrint, got {type(self.contact_print).__name__}"
            )


_PRINT_KEYS = ("surface", "x", "y", "theta", "theta_deg")


def contact_print_from_dict(robot_surface: str, data: Mapping) -> ContactPrint:
    """Read one print from ``{"surface", "x", "y", "theta" | "theta_deg"}``.

    ``theta`` is in radians, ``theta_deg`` in degrees; give at most one of them
    (default 0). ``x`` and ``y`` default to 0.

    Raises
    ------
    SceneError
        On a missing surface, an unknown key, both angles, or a non-number.
    """
    if not isinstance(data, Mapping):
        raise SceneError(f"{robot_surface}: a print must be a mapping with keys {_PRINT_KEYS}")
    unknown = sorted(set(data) - set(_PRINT_KEYS))
    if unknown:
        raise SceneError(f"{robot_surface}: unknown key(s) {unknown}; valid keys: {', '.join(_PRINT_KEYS)}")
    if "surface" not in data:
        raise SceneError(f"{robot_surface}: missing key 'surface'")
    if "theta" in data and "theta_deg" in data:
        raise SceneError(f"{robot_surface}: give 'theta' (radians) or 'theta_deg' (degrees), not both")
    theta = _finite_float(data.get("theta", 0.0), f"{robot_surface}.theta")
    if "theta_deg" in data:
        theta = math.radians(_finite_float(data["theta_deg"], f"{robot_surface}.theta_deg"))
    return ContactPrint(
        data["surface"],
        _finite_float(data.get("x", 0.0), f"{robot_surface}.x"),
        _finite_float(data.get("y", 0.0), f"{robot_surface}.y"),
        theta,
    )


@dataclass(frozen=True)
class Stance:
    """A set of contacts, at most one per robot surface, in canonical order.

    Parameters
    ----------
    contacts : iterable of Contact
        Any order; stored sorted by robot surface name.

    Raises
    ------
    SceneError
        If two contacts share a robot surface.

    Examples
    --------
    >>> left = Contact("left_sole", ContactPrint("floor", 0.0, 0.085))
    >>> right = Contact("right_sole", ContactPrint("floor", 0.0, -0.085))
    >>> Stance((right, left)) == Stance((left, right))
    True
    >>> Stance((left, right)).without("right_sole").robot_surfaces
    ('left_sole',)
    """

    contacts: tuple[Contact, ...] = ()

    def __post_init__(self) -> None:
        contacts = tuple(self.contacts)
        for contact in contacts:
            if not isinstance(contact, Contact):
                raise SceneError(f"Stance contacts must be Contact, got {type(contact).__name__}")
        contacts = tuple(sorted(contacts, key=lambda contact: contact.robot_surface))
        names = [contact.robot_surface for contact in contacts]
        repeated = sorted({name for name in names if names.count(name) > 1})
        if repeated:
            raise SceneError(f"a stance has at most one contact per robot surface; repeated: {', '.join(repeated)}")
        object.__setattr__(self, "contacts", contacts)

    @property
    def robot_surfaces(self) -> tuple[str, ...]:
        """Robot surfaces in contact, sorted."""
        return tuple(contact.robot_surface for contact in self.contacts)

    def contact(self, robot_surface: str) -> Contact:
        """The contact of one robot surface.

        Raises
        ------
        SceneError
            If that robot surface is not in contact; lists those that are.
        """
        for contact in self.contacts:
            if contact.robot_surface == robot_surface:
                return contact
        raise SceneError(
            f"no contact on robot surface {robot_surface!r}; "
            f"in contact: {', '.join(self.robot_surfaces) or '(none)'}"
        )

    def has(self, robot_surface: str) -> bool:
        """Whether a robot surface is in contact."""
        return robot_surface in self.robot_surfaces

    def with_contact(self, contact: Contact) -> "Stance":
        """A new stance with this contact added, replacing any on the same robot surface."""
        others = tuple(c for c in self.contacts if c.robot_surface != contact.robot_surface)
        return Stance(others + (contact,))

    def without(self, robot_surface: str) -> "Stance":
        """A new stance without the contact of a robot surface.

        Raises
        ------
        SceneError
            If that robot surface is not in contact.
        """
        self.contact(robot_surface)
        return Stance(tuple(c for c in self.contacts if c.robot_surface != robot_surface))

    def __len__(self) -> int:
        return len(self.contacts)

    def __iter__(self) -> Iterator[Contact]:
        return iter(self.contacts)

    def to_dict(self) -> dict:
        """Plain data for JSON or YAML: ``{robot_surface: {surface, x, y, theta}}``, theta in radians."""
        return {
            c.robot_surface: {
                "surface": c.contact_print.surface,
                "x": c.contact_print.x,
                "y": c.contact_print.y,
                "theta": c.contact_print.theta,
            }
            for c in self.contacts
        }

    @classmethod
    def from_dict(cls, mapping: Mapping) -> "Stance":
        """Read a stance from ``{robot_surface: {surface, x, y, theta | theta_deg}}``.

        ``theta`` is in radians, ``theta_deg`` in degrees (at most one; default 0).

        Raises
        ------
        SceneError
            On a malformed entry.
        """
        if not isinstance(mapping, Mapping):
            raise SceneError(f"a stance must be a mapping robot_surface -> print, got {type(mapping).__name__}")
        return cls(
            tuple(
                Contact(_name(robot_surface, "robot surface"), contact_print_from_dict(robot_surface, data))
                for robot_surface, data in mapping.items()
            )
        )
