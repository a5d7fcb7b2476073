"""Isotropic linear elastic material (paper eqs. 3, 25-26)."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .errors import FemWarning, MaterialError

__all__ = ["LinearElasticMaterial", "MAX_YOUNG_MODULUS", "LOCKING_POISSON_RATIO"]

#: Poisson's ratio above which linear tetrahedra lock (volumetric locking: a nearly
#: incompressible body answers too stiff, and refining converges slowly). Measured on
#: step-on-cube's default mesh, its soft sole's force changed on a mesh twice as fine by
#: 1.6 % at 0.3, 3.4 % at 0.4 (the built-in scenes), 4.7 % at 0.43, 6.3 % at 0.45, 16 % at
#: 0.49 and 23 % at 0.499, where the force on the default mesh was 2.4 times the one at 0.3.
LOCKING_POISSON_RATIO = 0.45

#: Largest Young's modulus accepted, pascals: about diamond's (1.05e12 Pa). A stiffer
#: support is rigid for any robot and belongs in the scene as a rigid object. Every
#: built-in soft stance solves up to it within 0.0-2.9 % of its rigid twin's forces
#: (``bench/bench_any_stiffness.py``); beyond it the contact solves near their round-off
#: (at 1e13 Pa iCub's palm lay 46 % off, through W, the stiff limit refused), and far
#: beyond the stiffness entries (E times an element size) overflow to inf.
MAX_YOUNG_MODULUS = 1e12


@dataclass(frozen=True, eq=False)
class LinearElasticMaterial:
    """Homogeneous isotropic linear elastic material.

    Parameters
    ----------
    young_modulus : float
        Young's modulus E, pascals, in (0, :data:`MAX_YOUNG_MODULUS`].
    poisson_ratio : float
        Poisson's ratio nu, dimensionless, in (-1, 0.5).
    density : float
        Mass density rho, kg/m^3, >= 0: the body's own weight
        (:meth:`fem.DeformableBody.self_weight_displacement`), which strains it at rest
        but, the body being meshed as it rests, moves no print force (eq. 31).

    Raises
    ------
    MaterialError
        If a constant is NaN, infinite or outside its range.

    Examples
    --------
    >>> m = LinearElasticMaterial(young_modulus=1e6, poisson_ratio=0.4, density=1e3)
    >>> round(m.lame_mu)
    357143
    """

    young_modulus: float
    poisson_ratio: float
    density: float = 0.0

    def __post_init__(self) -> None:
        for name in ("young_modulus", "poisson_ratio", "density"):
            value = getattr(self, name)
            try:
                value = float(value)
            except (TypeError, ValueError) as exc:
                raise MaterialError(f"{name} must be a real number, got {value!r}", field=name) from exc
            if not math.isfinite(value):
                raise MaterialError(f"{name} must be finite, got {value}", field=name)
            object.__setattr__(self, name, value)
        if self.young_modulus <= 0.0:
            raise MaterialError(
                f"young_modulus must be > 0 Pa, got {self.young_modulus:g}; "
                "soft foams are around 1e4-1e6 Pa",
                field="young_modulus",
            )
        if self.young_modulus > MAX_YOUNG_MODULUS:
            raise MaterialError(
                f"young_modulus must be <= {MAX_YOUNG_MODULUS:g} Pa (about diamond's), got "
                f"{self.young_modulus:g}; model a support this stiff as a rigid object",
                field="young_modulus",
            )
        if not -1.0 < self.poisson_ratio < 0.5:
            raise MaterialError(
                f"poisson_ratio must lie in (-1, 0.5), got {self.poisson_ratio:g}; "
                "0.5 is incompressible (the stiffness is singular there), and linear tetrahedra lock as it nears "
                f"0.5: use at most {LOCKING_POISSON_RATIO:g}",
                field="poisson_ratio",
            )
        if self.density < 0.0:
            raise MaterialError(f"density must be >= 0 kg/m^3, got {self.density:g}", field="density")
        if self.poisson_ratio > LOCKING_POISSON_RATIO:
            warnings.warn(
                f"poisson_ratio {self.poisson_ratio:g} is above {LOCKING_POISSON_RATIO:g}: linear tetrahedra lock "
                "as it nears 0.5 and answer too stiff (a sole's force on a default mesh changed by 16 % at 0.49 "
                "on a mesh twice as fine, 3 % at 0.4); check a stance on finer meshes (cbm check --refine 2, "
                "stances.check_refined) or use a smaller ratio",
                FemWarning,
                stacklevel=3,
            )

    @property
    def lame_lambda(self) -> float:
        """First Lame parameter lambda = E nu / ((1 + nu)(1 - 2 nu)), pascals."""
        e, nu = self.young_modulus, self.poisson_ratio
        return e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))

    @property
    def lame_mu(self) -> float:
        """Shear modulus mu = E / (2 (1 + nu)), pascals."""
        return self.young_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @cached_property
    def voigt_matrix(self) -> np.ndarray:
        """Elasticity matrix A of eq. (26), (6, 6) float, pascals, read-only.

        Voigt order of eqs. (22)-(23): 11, 22, 33, 12, 13, 23, engineering shear
        strains (2 eps_12, ...), so that ``{sigma} = A {eps}`` (eq. 25).
        """
        lam, mu = self.lame_lambda, self.lame_mu
        a = np.zeros((6, 6))
        a[:3, :3] = lam
        a[[0, 1, 2], [0, 1, 2]] += 2.0 * mu
        a[[3, 4, 5], [3, 4, 5]] = mu
        a.setflags(write=False)
        return a
