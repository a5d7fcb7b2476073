"""Best-first search over a lazily checked graph (generic: no robot inside).

The nodes are any hashable values (the planner uses stances). A node is
*reached* only if a feasibility oracle accepts it. The oracle is called lazily,
when a node is popped from the open list rather than when it is generated, so a
search that goes straight to the goal pays one solve per stance of the path,
not one per neighbour. Every answer is cached: no node is ever given to the
oracle twice.

A node may also carry a cost known only from its answer (``node_cost``: the
planner's terrain cost, from the stance's deformation). The search stays exact
by lazy re-evaluation, as lazy weighted A* does for edge costs: a node is queued
with 0 for its own cost (a lower bound), and when it is popped and answered, if
its true cost is higher, it is queued again with its true priority instead of
being goal-tested or expanded.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import math
import random
import time
import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable, Hashable, Iterable

import networkx as nx

from .errors import CbmError

__all__ = [
    "SearchLimits",
    "SearchStatistics",
    "SearchProgress",
    "SearchResult",
    "best_first_search",
    "SearchInterrupted",
    "NO_FEASIBLE_NEIGHBOUR",
    "INTERRUPTED",
    "budget_exhausted",
    "DEFAULT_MAX_EXPANSIONS",
    "DEFAULT_TIME_LIMIT",
]

logger = logging.getLogger(__name__)

#: Reason given when the open list empties before a goal is reached.
NO_FEASIBLE_NEIGHBOUR = "no feasible neighbour"

#: Reason of the partial result carried by :class:`SearchInterrupted`.
INTERRUPTED = "interrupted (Ctrl-C)"


def budget_exhausted(limit: str) -> str:
    """The reason of a search stopped by one of its :class:`SearchLimits` (its field name)."""
    return f"budget exhausted: {limit}"


class SearchInterrupted(KeyboardInterrupt):
    """Ctrl-C during a search, carrying the best partial result found so far.

    A ``KeyboardInterrupt``, so a program that does not look for it stops as
    on any Ctrl-C; one that does can keep the work done (``cbm plan`` writes it).

    Parameters
    ----------
    result : SearchResult
        ``success`` False, reason :data:`INTERRUPTED`, ``path`` the best
        partial path (possibly empty if the start was not yet checked).
    """

    def __init__(self, result):
        super().__init__(INTERRUPTED)
        self.result = result


#: Stances expanded at most, for :class:`SearchLimits`, :func:`cbm.plan` and ``cbm plan`` alike.
DEFAULT_MAX_EXPANSIONS = 200

#: Seconds of search at most, for :class:`SearchLimits`, :func:`cbm.plan` and
#: ``cbm plan`` alike: enough for the default expansions on the built-in scenarios
#: (cross-two-mats spends its 200 expansions in about 140 s on 2 cores).
DEFAULT_TIME_LIMIT = 300.0


@dataclass(frozen=True)
class SearchLimits:
    """Budgets of one search; ``None`` means unlimited.

    Parameters
    ----------
    max_expansions : int or None
        Nodes whose neighbours may be generated.
    max_solver_calls : int or None
        Calls to the feasibility oracle (the start node included).
    time_limit : float or None
        Wall time, seconds. Checked between oracle calls; an oracle that can
        stop in time is told the deadline by its owner (``cbm.plan`` gives
        each posture solve the time left).
    """

    max_expansions: int | None = DEFAULT_MAX_EXPANSIONS
    max_solver_calls: int | None = None
    time_limit: float | None = DEFAULT_TIME_LIMIT

    def __post_init__(self):
        for name in ("max_expansions", "max_solver_calls"):
            value = getattr(self, name)
            if value is not None and (int(value) != value or value < 0):
                raise CbmError(f"{name} must be a non-negative integer or None, got {value!r}")
        if self.time_limit is not None and not self.time_limit > 0:
            raise CbmError(f"time_limit must be positive seconds or None, got {self.time_limit!r}")


@dataclass(frozen=True)
class SearchStatistics:
    """Counters of one search.

    Parameters
    ----------
    expanded : int
        Nodes whose neighbours were generated.
    generated : int
        Neighbours generated (before any oracle call).
    solver_calls : int
        Calls to the feasibility oracle.
    cache_hits : int
        Oracle requests answered from the cache instead.
    requeued : int
        Nodes queued again with their true priority once their answer gave
        them a positive ``node_cost`` (lazy re-evaluation; no oracle call).
    time : float
        Wall time of the search, seconds.
    cpu_time : float
        CPU time of this process during the search, seconds (on a loaded
        machine it stays close to the work done while ``time`` grows).
    """

    expanded: int = 0
    generated: int = 0
    solver_calls: int = 0
    cache_hits: int = 0
    requeued: int = 0
    time: float = 0.0
    cpu_time: float = 0.0

    def to_dict(self):
        """Return the counters as a plain dict (subclasses' fields included)."""
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class SearchProgress:
    """Where a search stands, after an expansion (what a progress display shows).

    Parameters
    ----------
    statistics : SearchStatistics
        The counters so far.
    best_heuristic : float
        Heuristic value of the feasible node closest to the goal found so far (in
        the heuristic's units; the planner's: metres to the goal regions).
    queued : int
        Entries waiting in the open list.
    """

    statistics: SearchStatistics
    best_heuristic: float
    queued: int


@dataclass(frozen=True)
class SearchResult:
    """Outcome of :func:`best_first_search`.

    Parameters
    ----------
    success : bool
        True if ``path`` ends on a goal node.
    reason : str
        ``"goal reached"``, ``"no feasible neighbour"`` (search space
        exhausted), ``"budget exhausted: <limit>"`` or ``"start infeasible: ..."``.
    path : tuple
        Nodes from the start to the goal; on failure, the best partial path
        (to the feasible node of smallest heuristic), possibly empty if the
        start itself is infeasible.
    results : tuple
        Oracle answers of the nodes of ``path``, same length.
    statistics : SearchStatistics
        Counters.
    graph : networkx.DiGraph
        Explored graph. Node attributes: ``status`` (``"open"``,
        ``"feasible"``, ``"infeasible"``), ``result`` (oracle answer or
        None), ``h`` (heuristic); edge attribute ``move``.
    """

    success: bool
    reason: str
    path: tuple
    results: tuple
    statistics: SearchStatistics
    graph: nx.DiGraph = field(compare=False, repr=False)


def best_first_search(
    start: Hashable,
    *,
    neighbours: Callable[[Any], Iterable[tuple[Any, Any]]],
    oracle: Callable[[Any, Any, Any], Any],
    heuristic: Callable[[Any], float],
    is_goal: Callable[[Any], bool],
    step_cost: Callable[[Any, Any, Any], float] | None = None,
    path_cost_weight: float = 0.0,
    node_cost: Callable[[Any, Any], float] | None = None,
    limits: SearchLimits = SearchLimits(),
    eager: bool = False,
    shuffle_neighbours: bool = False,
    seed: int = 0,
    on_expand: Callable[[SearchProgress], None] | None = None,
    submit: Callable[[Any, Any, Any], Any] | None = None,
    lookahead: int = 0,
) -> SearchResult:
    """Search from ``start`` to a goal node through feasible nodes only.

    Nodes are popped in increasing order of
    ``heuristic(node) + path_cost_weight * cost_from_start + node_costs``
    (``node_costs``: the sum of ``node_cost`` over the path's nodes, the node
    included), ties broken by insertion order. A popped node is given to the
    oracle (warm start: its parent and the parent's answer) unless the cache
    already knows it; infeasible nodes are dropped, feasible ones are
    goal-tested then expanded.

    With ``node_cost``, a node whose answer is not yet known is queued with 0
    for its own node cost. Invariant: every queued entry's priority is at most
    the true priority of the path it stands for, and a node is goal-tested or
    expanded only from an entry holding its true priority: an entry popped
    before its node's cost was counted, if that cost is positive, is queued
    again with it (counted as ``requeued``). So the node expanded is always
    one of least true priority among the queued paths, as if every cost had
    been known from the start (up to the order of ties), while the oracle is
    still called only on popped nodes.

    Parameters
    ----------
    start : hashable
        First node; it is checked by the oracle too.
    neighbours : callable
        ``neighbours(node)`` yields ``(child, move)`` pairs; ``move`` is any
        label stored on the graph edge.
    oracle : callable
        ``oracle(node, parent, parent_result)`` returns an answer with a bool
        attribute ``feasible``; ``parent`` is None for the start.
    heuristic : callable
        ``heuristic(node)``, non-negative estimate of the distance to a goal.
    is_goal : callable
        ``is_goal(node)`` for a feasible node.
    step_cost : callable, optional
        ``step_cost(parent, child, move)``; 1 per move by default.
    path_cost_weight : float
        Weight of the cost from the start in the priority; 0 is greedy.
    node_cost : callable, optional
        ``node_cost(node, answer)`` for a feasible node: a cost known only from
        its oracle answer (the planner's terrain cost), >= 0 and finite, in the
        priority's units (not weighted by ``path_cost_weight``), added to every
        path through the node; called once per node. None: 0 everywhere.
    limits : SearchLimits
        Budgets.
    eager : bool
        Baseline mode: call the oracle on every neighbour when generated
        (still cached). The default lazy mode calls it when popped.
    shuffle_neighbours : bool
        Shuffle each node's neighbours with a generator seeded by ``seed``
        before queuing them, so equal priorities are not always resolved in
        generation order. Off: the order is generation order.
    seed : int
        Seed of the shuffling generator.
    on_expand : callable, optional
        Called with a :class:`SearchProgress` after each expansion (a progress display).
    submit : callable, optional
        Starts oracle calls ahead: ``submit(node, parent, parent_result)``
        returns a future (``result()``, ``done()``) of ``oracle``'s answer
        for the same arguments, run elsewhere (a process pool). With it the
        search still consumes answers in its own order, each one computed
        from the node and parent it would have used alone, so the result is
        the same whatever ``lookahead`` is; ``oracle`` is then not called.
    lookahead : int
        With ``submit``: oracle calls kept running at once. Whenever the
        search waits for an answer it starts the next calls it would make if
        no expansion intervened (the open list's best entries; in eager mode
        every new neighbour of an expansion), up to ``lookahead``. Answers
        never consumed are wasted work, counted as ``speculative`` only in the
        log.

    Returns
    -------
    SearchResult

    Raises
    ------
    CbmError
        If ``path_cost_weight`` is negative, or ``node_cost`` returns a negative
        or non-finite value (a lower bound of 0 would then be wrong).
    SearchInterrupted
        On Ctrl-C (``KeyboardInterrupt``) during the search, with the best
        partial result so far.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> edges = {0: [1, 2], 1: [3], 2: [3], 3: []}
    >>> result = best_first_search(
    ...     0,
    ...     neighbours=lambda n: [(m, (n, m)) for m in edges[n]],
    ...     oracle=lambda n, p, r: SimpleNamespace(feasible=n != 1),
    ...     heuristic=lambda n: 3 - n,
    ...     is_goal=lambda n: n == 3,
    ... )
    >>> result.success, result.path
    (True, (0, 2, 3))
    """
    if path_cost_weight < 0:
        raise CbmError(f"path_cost_weight must be >= 0, got {path_cost_weight!r}")
    if submit is not None and not (int(lookahead) == lookahead and lookahead >= 1):
        raise CbmError(f"lookahead must be a positive integer with submit, got {lookahead!r}")
    if step_cost is None:
        step_cost = _unit_step_cost
    started, cpu_started = time.perf_counter(), time.process_time()
    rng = random.Random(seed)
    # The counter makes every heap entry unique before its node, so the heap
    # never compares two nodes (stances need not be orderable) and equal
    # priorities pop in insertion order: a deterministic tie-break.
    counter = itertools.count()
    heap: list = []
    cache: dict = {}
    came_from: dict = {}
    closed: set = set()
    h_of: dict = {}
    own_cost_of: dict = {}
    graph = nx.DiGraph()
    counts = {"expanded": 0, "generated": 0, "solver_calls": 0, "cache_hits": 0, "requeued": 0}
    best = None  # (h, order, node) of the feasible node closest to the goal

    def statistics():
        return SearchStatistics(
            time=time.perf_counter() - started, cpu_time=time.process_time() - cpu_started, **counts
        )

    def heuristic_of(node):
        if node not in h_of:
            h_of[node] = float(heuristic(node))
        return h_of[node]

    def own_cost(node, answer):
        """``node_cost`` of a feasible node, checked and computed once."""
        if node not in own_cost_of:
            value = float(node_cost(node, answer))
            if not (math.isfinite(value) and value >= 0.0):
                raise CbmError(f"node_cost must return a finite value >= 0, got {value!r} for node {node!r}")
            own_cost_of[node] = value
        return own_cost_of[node]

    def push(node, parent, cost, path_node_costs):
        """Queue ``node`` reached from ``parent``; ``path_node_costs`` sums the node costs up to ``parent``.

        The entry is settled (its priority true) if the node's own cost is
        known; otherwise it counts 0 for it, a lower bound (see the invariant).
        """
        settled, total = node_cost is None, path_node_costs
        if not settled and node in cache:
            settled, total = True, path_node_costs + own_cost(node, cache[node])
        priority = heuristic_of(node) + path_cost_weight * cost + total
        heapq.heappush(heap, (priority, next(counter), node, parent, cost, total, settled))

    def budget_exceeded(before_solve):
        if limits.time_limit is not None and time.perf_counter() - started > limits.time_limit:
            return "time_limit"
        if (
            before_solve
            and limits.max_solver_calls is not None
            and counts["solver_calls"] >= limits.max_solver_calls
        ):
            return "max_solver_calls"
        return None

    def evaluate(node, parent):
        """Oracle answer of ``node``, from the cache if known; None if out of budget."""
        if node in cache:
            counts["cache_hits"] += 1
            return cache[node]
        exceeded = budget_exceeded(before_solve=True)
        if exceeded is not None:
            raise _BudgetExhausted(exceeded)
        if submit is None:
            answer = oracle(node, parent, cache.get(parent) if parent is not None else None)
        else:
            ahead.request(node, parent)
            ahead.fill(heap)
            answer = ahead.take(node, parent)
        counts["solver_calls"] += 1
        cache[node] = answer
        feasible = bool(answer.feasible)
        graph.add_node(node, status="feasible" if feasible else "infeasible", result=answer)
        logger.debug("oracle: %s -> %s", node, "feasible" if feasible else "infeasible")
        return answer

    def finish(success, reason, last):
        path = _path_to(last, came_from) if last is not None else ()
        stats = statistics()
        logger.info(
            "search %s (%s): %d expanded, %d solver calls, %d cache hits, %.2f s",
            "succeeded" if success else "failed",
            reason,
            stats.expanded,
            stats.solver_calls,
            stats.cache_hits,
            stats.time,
        )
        return SearchResult(
            success=success,
            reason=reason,
            path=path,
            results=tuple(cache[n] for n in path),
            statistics=stats,
            graph=graph,
        )

    ahead = _Lookahead(submit, lookahead, cache, closed) if submit is not None else None
    graph.add_node(start, status="open", result=None, h=heuristic_of(start))
    push(start, None, 0.0, 0.0)
    try:
        while heap:
            exceeded = budget_exceeded(before_solve=False)
            if exceeded is not None:
                raise _BudgetExhausted(exceeded)
            _, order, node, parent, cost, node_costs, settled = heapq.heappop(heap)
            if node in closed:
                continue
            if eager and node in cache:
                answer = cache[node]  # checked when generated; not a cache hit
            else:
                answer = evaluate(node, parent)
            if not answer.feasible:
                if parent is None:
                    reason = getattr(answer, "reason", "") or "rejected by the oracle"
                    return finish(False, f"start infeasible: {reason}", None)
                continue
            if not settled and own_cost(node, answer) > 0.0:
                # Its true priority is higher than the one it was popped with:
                # queue it again with that priority before any goal test or expansion.
                counts["requeued"] += 1
                push(node, parent, cost, node_costs)
                continue
            came_from.setdefault(node, parent)
            h = heuristic_of(node)
            if best is None or (h, order) < best[:2]:
                best = (h, order, node)
            if is_goal(node):
                return finish(True, "goal reached", node)
            if limits.max_expansions is not None and counts["expanded"] >= limits.max_expansions:
                raise _BudgetExhausted("max_expansions")
            closed.add(node)
            counts["expanded"] += 1
            children = list(neighbours(node))
            counts["generated"] += len(children)
            if shuffle_neighbours:
                rng.shuffle(children)
            if eager and ahead is not None:
                for child, _ in children:
                    if child not in closed and child not in cache:
                        ahead.request(child, node)
            for child, move in children:
                if child in closed:
                    continue
                if child in cache and not cache[child].feasible:
                    counts["cache_hits"] += 1
                    continue
                if child not in graph:
                    graph.add_node(child, status="open", result=None)
                graph.nodes[child]["h"] = heuristic_of(child)
                graph.add_edge(node, child, move=move)
                if eager and child not in cache:
                    if not evaluate(child, node).feasible:
                        continue
                push(child, node, cost + float(step_cost(node, child, move)), node_costs)
            if on_expand is not None:
                on_expand(SearchProgress(statistics(), best[0], len(heap)))
    except _BudgetExhausted as exhausted:
        return finish(False, budget_exhausted(exhausted.limit), best[2] if best else None)
    except KeyboardInterrupt:
        # Every node on the way to ``best`` has its answer in the cache and its
        # parent in came_from before ``best`` names it, wherever the interrupt falls.
        raise SearchInterrupted(finish(False, INTERRUPTED, best[2] if best else None)) from None
    finally:
        if ahead is not None and ahead.pending:
            logger.info("%d oracle calls started ahead were not used", len(ahead.pending))
    return finish(False, NO_FEASIBLE_NEIGHBOUR, best[2] if best else None)


class _Lookahead:
    """Oracle calls started ahead of the search, keyed by (node, parent).

    The key holds the parent because the answer depends on it (the warm
    start): a node reached later through another parent is a new call, so
    every answer the search consumes is the one it would have computed alone.
    """

    def __init__(self, submit, size, cache, closed):
        self.submit = submit
        self.size = int(size)
        self.cache = cache
        self.closed = closed
        self.pending = {}

    def request(self, node, parent):
        """Start the oracle call of ``node`` warm-started from ``parent``, unless started."""
        if (node, parent) not in self.pending:
            parent_result = self.cache.get(parent) if parent is not None else None
            self.pending[node, parent] = self.submit(node, parent, parent_result)

    def fill(self, heap):
        """Start the calls of the open list's best entries while fewer than ``size`` run."""
        running = sum(not future.done() for future in self.pending.values())
        if running >= self.size:
            return
        seen = set()
        # The heap's entries in pop order; only a node's first entry is the one
        # the search would pop, its later ones are skipped as closed or cached.
        for entry in heapq.nsmallest(4 * self.size + len(self.pending), heap):
            node, parent = entry[2], entry[3]
            if running >= self.size:
                break
            if node in seen or node in self.closed or node in self.cache:
                continue
            seen.add(node)
            if (node, parent) not in self.pending:
                self.request(node, parent)
                running += 1

    def take(self, node, parent):
        """Wait for the answer of a started call and forget the call."""
        return self.pending.pop((node, parent)).result()


class _BudgetExhausted(Exception):
    """Internal: unwinds the search loop when a limit is hit."""

    def __init__(self, limit):
        super().__init__(limit)
        self.limit = limit


def _unit_step_cost(parent, child, move):
    return 1.0


def _path_to(node, came_from):
    path = [node]
    while came_from.get(path[-1]) is not None:
        path.append(came_from[path[-1]])
    return tuple(reversed(path))
