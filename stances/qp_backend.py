"""proxsuite, in its generic build, so that every QP answer is reproducible bit for bit.

proxsuite ships three compiled builds and loads the AVX-512 or AVX2 one when the
processor has those instructions. Measured on this project's QPs (the same dense
problem solved in fresh solver objects within one process), the answers of those two
builds change in their last bits with the heap addresses of the solver's buffers: an
SQP then takes different paths from run to run, and an infeasible stance comes back
with different reasons. The generic build gives the same bits every time, for about
15 % more time per QP. It is selected by answering "no" to proxsuite's
instruction-set probe while it is first imported; if proxsuite was imported before
this module, the build already loaded is used and reproducibility is not promised.
"""

from __future__ import annotations

import logging
import sys
import types

logger = logging.getLogger(__name__)


def _import_generic_proxsuite():
    if "proxsuite" in sys.modules:
        logger.warning(
            "proxsuite was imported before stances: its vectorised build may be in use, and "
            "posture solves may differ in their last bits from run to run"
        )
        import proxsuite

        return proxsuite
    probe = types.ModuleType("proxsuite.instructionset")
    probe.has_AVX512F = lambda: False
    probe.has_AVX2 = lambda: False
    sys.modules["proxsuite.instructionset"] = probe
    try:
        import proxsuite
    finally:
        del sys.modules["proxsuite.instructionset"]
    return proxsuite


proxsuite = _import_generic_proxsuite()

__all__ = ["proxsuite"]
