"""Small dense algebra of print-sized matrices: one BLAS thread, SPD inverses by Cholesky.

Print compliances and contact systems have a few hundred rows: too small for
threads to pay, and on a shared or loaded machine OpenBLAS's threads spin waiting
for cores (measured: a soft-contact solve's CPU time multiplied by up to 9,
cross-two-mats 4.8 s against 0.5 s; the inverse of a 600 x 600 print compliance
57 ms of CPU with the default threads, 11 ms with one). A large body's sparse
factorisation keeps every thread: only the blocks below are limited.
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np
import scipy.linalg
from threadpoolctl import ThreadpoolController

from .errors import FemError

__all__ = ["block_diagonal_product", "single_threaded_blas", "spd_inverse"]

_controller: ThreadpoolController | None = None


@contextmanager
def single_threaded_blas():
    """Limit every loaded BLAS to one thread inside the ``with`` block."""
    global _controller
    if _controller is None:
        # Created on first use, once the BLAS libraries of numpy, scipy and cvxopt are loaded.
        _controller = ThreadpoolController()
    with _controller.limit(limits=1, user_api="blas"):
        yield


def spd_inverse(matrix: np.ndarray, what: str) -> np.ndarray:
    """Inverse of a symmetric positive definite matrix, through its Cholesky factor.

    LAPACK ``potrf`` then ``potri`` on one thread: a third of the work of a
    Cholesky check followed by a general (LU) inverse.

    Parameters
    ----------
    matrix : (n, n) float
        Symmetric positive definite (its upper triangle is read).
    what : str
        What the matrix is, for the error message.

    Returns
    -------
    (n, n) float
        The inverse, exactly symmetric.

    Raises
    ------
    FemError
        If ``matrix`` is not positive definite.
    """
    with single_threaded_blas():
        upper, info = scipy.linalg.lapack.dpotrf(matrix, lower=0)
        if info == 0:
            upper, info = scipy.linalg.lapack.dpotri(upper, lower=0)
    if info != 0:
        raise FemError(f"{what} is not positive definite (LAPACK info {info})")
    return np.triu(upper) + np.triu(upper, 1).T


def block_diagonal_product(blocks: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """A block-diagonal matrix, given by its (p, 3, 3) ``blocks``, times stacked (3p,)
    or (3p, k) vectors: 9 p numbers read instead of the 9 p^2 of the whole matrix.

    Returns
    -------
    ndarray of the shape of ``vectors``.
    """
    p = blocks.shape[0]
    return np.einsum("pij,pj...->pi...", blocks, vectors.reshape(p, 3, *vectors.shape[1:])).reshape(vectors.shape)
