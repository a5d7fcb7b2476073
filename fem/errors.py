"""Exceptions and warnings of the :mod:`fem` package.

Every error a caller can provoke with a bad argument is a :class:`FemError`, a
subclass of :class:`ValueError`, so ``except ValueError`` keeps working for code that
does not know this package. Subclasses name the family of the problem; messages say
what is wrong and what would be valid.
"""

from __future__ import annotations

__all__ = [
    "FemError",
    "MeshError",
    "MaterialError",
    "BoundaryError",
    "PrintError",
    "SolverError",
    "FemWarning",
]


class FemError(ValueError):
    """Base class of every error raised by :mod:`fem`."""


class MeshError(FemError):
    """A mesh is invalid: inverted or flat tets, duplicate nodes, bad indices, NaN."""


class MaterialError(FemError):
    """Material constants are outside the range where linear elasticity is defined.

    Parameters
    ----------
    message : str
    field : str, optional
        The :class:`fem.LinearElasticMaterial` field at fault (``"young_modulus"``,
        ``"poisson_ratio"`` or ``"density"``), which the message then starts with, so
        that a reader of another format can name its own key.
    """

    def __init__(self, message: str, field: str | None = None) -> None:
        super().__init__(message)
        self.field = field


class BoundaryError(FemError):
    """Boundary conditions are invalid, e.g. no fixed node (singular stiffness)."""


class PrintError(FemError):
    """A contact print or its displacements are invalid."""


class SolverError(FemError):
    """A sparse solver is unavailable or failed (e.g. matrix not positive definite)."""


class ContactStateError(FemError):
    """A print's Signorini-Coulomb contact has no state the active set finds at this motion.

    With very high friction (or infinite) a node can need a tangential force with almost no
    normal force: the discrete Coulomb problem then has no solution, or none the active set
    reaches. A posture solver meets it at a trial motion and steps elsewhere.
    """


class FemWarning(UserWarning):
    """Doubtful physics, e.g. strains beyond the small-deformation hypothesis."""
