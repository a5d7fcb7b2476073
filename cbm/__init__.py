"""Contact-before-motion planning for a legged robot over rigid and deformable supports.

Examples
--------
>>> import cbm
>>> plan = cbm.plan("cross-soft-block", max_expansions=40)  # doctest: +SKIP
>>> plan.success, len(plan.stances)  # doctest: +SKIP
(True, 10)
"""

from .batch import BatchFileError, Check, CheckOutcome, read_checks, run_check
from .distributed import solve_many, write_dataset
from .errors import CbmError, MotionError, PlanFileError, UnknownScenario
from .output import OutputFiles, write_outputs
from .plan import Plan, PlanCheck, PlannedStance, PlanStatistics
from .planner import (
    LookaheadHeuristic,
    PostureOracle,
    StanceCheck,
    initial_configuration,
    load_robot,
    load_scenario,
    plan,
)
from .reach import ReachLimits, ReachModel
from .replan import AvoidedStep, MovingPlan, plan_with_motions
from .sampling import PrintSet, SamplingOptions, sample_prints
from .search import SearchLimits, SearchResult, SearchStatistics, best_first_search
from .stance_graph import Move, StanceNeighbours, differ_by_one_contact

__all__ = [
    "AvoidedStep",
    "BatchFileError",
    "Check",
    "CheckOutcome",
    "CbmError",
    "LookaheadHeuristic",
    "Move",
    "MotionError",
    "MovingPlan",
    "OutputFiles",
    "Plan",
    "PlanCheck",
    "PlanFileError",
    "PlanStatistics",
    "PlannedStance",
    "PostureOracle",
    "PrintSet",
    "ReachLimits",
    "ReachModel",
    "SamplingOptions",
    "SearchLimits",
    "SearchResult",
    "SearchStatistics",
    "StanceCheck",
    "StanceNeighbours",
    "UnknownScenario",
    "best_first_search",
    "differ_by_one_contact",
    "initial_configuration",
    "load_robot",
    "load_scenario",
    "plan",
    "plan_with_motions",
    "read_checks",
    "run_check",
    "solve_many",
    "write_dataset",
    "sample_prints",
    "write_outputs",
]
