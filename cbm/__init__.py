"""Contact-before-motion planning for a humanoid over rigid and deformable supports."""

from .errors import CbmError, PlanFileError, UnknownScenario
from .search import SearchLimits, SearchResult, SearchStatistics, best_first_search

__all__ = [
    "CbmError",
    "PlanFileError",
    "UnknownScenario",
    "SearchLimits",
    "SearchResult",
    "SearchStatistics",
    "best_first_search",
]
