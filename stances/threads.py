"""One BLAS thread for the small dense algebra of a posture solve.

A solve's linear algebra works on matrices of a few hundred rows (QPs, print
contact systems, Jacobian products): too small for threads to pay, and on a shared
or loaded machine OpenBLAS's threads spin waiting for cores, which was measured to
multiply a soft-contact solve's CPU time by up to 9 (cross-two-mats: 4.8 s against
0.5 s). The limit holds only inside the SQP loop; factorising a large body keeps
every thread.
"""

from __future__ import annotations

from contextlib import contextmanager

from threadpoolctl import ThreadpoolController

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


__all__ = ["single_threaded_blas"]
