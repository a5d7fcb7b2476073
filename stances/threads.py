"""One BLAS thread for the small dense algebra of a posture solve.

A solve's linear algebra works on matrices of a few hundred rows (QPs, print
contact systems, Jacobian products): too small for threads to pay
(:mod:`fem.dense` has the measurements). The limit holds inside the SQP loop;
factorising a large body keeps every thread.
"""

from __future__ import annotations

from fem.dense import single_threaded_blas

__all__ = ["single_threaded_blas"]
