"""Sparse Cholesky / LU factorisations of the free-dof stiffness K_NN behind one interface."""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .errors import SolverError

__all__ = [
    "Factorization",
    "CholmodFactorization",
    "ScipyFactorization",
    "factorize",
    "available_solvers",
    "resolve_solver",
]

logger = logging.getLogger(__name__)

SOLVERS = ("auto", "cholmod", "scipy")


def _cholmod():
    try:
        from cvxopt import cholmod
    except ImportError:
        return None
    return cholmod


def available_solvers() -> tuple[str, ...]:
    """Names of the factorisations usable here, fastest first (``"cholmod"``, ``"scipy"``)."""
    return ("cholmod", "scipy") if _cholmod() is not None else ("scipy",)


class Factorization(ABC):
    """A factorised symmetric positive definite matrix; ``solve`` many right-hand sides."""

    name: str = ""
    size: int = 0

    @abstractmethod
    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve ``K x = rhs``.

        Parameters
        ----------
        rhs : (n,) or (n, k) float

        Returns
        -------
        (n,) or (n, k) float
        """


class CholmodFactorization(Factorization):
    """Supernodal sparse Cholesky of CHOLMOD through ``cvxopt.cholmod``.

    Only the lower triangle of the matrix is passed; CHOLMOD picks its fill-reducing
    ordering (AMD, or METIS when built with it).
    """

    name = "cholmod"

    def __init__(self, matrix: sp.spmatrix, ordering: np.ndarray | None = None) -> None:
        import cvxopt

        cholmod = _cholmod()
        lower = sp.tril(matrix, format="coo")
        self.size = matrix.shape[0]
        a = cvxopt.spmatrix(
            lower.data.astype(float), lower.row.astype(np.int64).tolist(), lower.col.astype(np.int64).tolist(),
            (self.size, self.size),
        )
        # Force the supernodal factorisation: CHOLMOD's automatic choice sometimes
        # picks the simplicial one on graded meshes, 10-30x slower on 3-D stiffness.
        saved = dict(cholmod.options)
        cholmod.options["supernodal"] = 2
        cholmod.options["postorder"] = True
        try:
            if ordering is None:
                self._factor = cholmod.symbolic(a, uplo="L")
            else:
                p = cvxopt.matrix(np.asarray(ordering, dtype=np.int32))
                self._factor = cholmod.symbolic(a, p=p, uplo="L")
            cholmod.numeric(a, self._factor)
        except ArithmeticError as exc:
            raise SolverError(
                "CHOLMOD: the free-dof stiffness is not positive definite; is the body "
                "fixed enough to stop every rigid motion?"
            ) from exc
        finally:
            cholmod.options.clear()
            cholmod.options.update(saved)
        self._cholmod = cholmod
        self._matrix = cvxopt.matrix

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        rhs = np.asarray(rhs, dtype=float)
        x = self._matrix(np.asfortranarray(rhs.reshape(self.size, -1)))
        self._cholmod.solve(self._factor, x)
        return np.array(x).reshape(rhs.shape)


class ScipyFactorization(Factorization):
    """SuperLU of scipy in symmetric mode (diagonal pivots, ordering on A^T + A)."""

    name = "scipy"

    def __init__(self, matrix: sp.spmatrix, ordering: np.ndarray | None = None) -> None:
        self.size = matrix.shape[0]
        self._perm = None if ordering is None else np.asarray(ordering, dtype=np.int64)
        if self._perm is not None:
            matrix = sp.csr_matrix(matrix)[self._perm][:, self._perm]
        try:
            self._lu = spla.splu(
                sp.csc_matrix(matrix),
                permc_spec="MMD_AT_PLUS_A" if self._perm is None else "NATURAL",
                diag_pivot_thresh=0.0,
                options={"SymmetricMode": True},
            )
        except RuntimeError as exc:
            raise SolverError(f"SuperLU failed on the free-dof stiffness: {exc}") from exc

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        rhs = np.asarray(rhs, dtype=float)
        columns = rhs.reshape(self.size, -1)
        if self._perm is None:
            return self._lu.solve(columns).reshape(rhs.shape)
        x = np.empty_like(columns)
        x[self._perm] = self._lu.solve(np.ascontiguousarray(columns[self._perm]))
        return x.reshape(rhs.shape)


def resolve_solver(solver: str) -> str:
    """The factorisation a solver name stands for here (``"auto"``: the fastest available).

    Raises
    ------
    SolverError
        If the name is unknown.
    """
    if solver not in SOLVERS:
        raise SolverError(f"unknown solver {solver!r}; choose one of {SOLVERS}")
    return available_solvers()[0] if solver == "auto" else solver


def factorize(matrix: sp.spmatrix, solver: str = "auto", ordering: np.ndarray | None = None) -> Factorization:
    """Factorise a sparse symmetric positive definite matrix.

    Parameters
    ----------
    matrix : (n, n) scipy.sparse matrix
        Symmetric positive definite, e.g. K_NN in N/m.
    solver : {"auto", "cholmod", "scipy"}
        ``"auto"`` takes CHOLMOD when cvxopt is importable, else scipy's SuperLU.
    ordering : (n,) int, optional
        Fill-reducing permutation (e.g. :func:`fem.ordering.nested_dissection` of the
        nodes, expanded to dofs); default the solver's own (AMD / MMD).

    Returns
    -------
    Factorization

    Raises
    ------
    SolverError
        If the solver name is unknown, CHOLMOD is requested but missing, or the
        matrix is not positive definite.
    """
    solver = resolve_solver(solver)
    if solver == "cholmod":
        if _cholmod() is None:
            raise SolverError("solver='cholmod' needs cvxopt (pip install cvxopt); or use solver='scipy'")
        return CholmodFactorization(matrix, ordering)
    return ScipyFactorization(matrix, ordering)
