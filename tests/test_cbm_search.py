"""Best-first search on tiny hand-made graphs with synthetic feasibility oracles."""

import collections
import random
import re
import time
from dataclasses import dataclass

import networkx as nx
import pytest

from cbm.errors import CbmError
from cbm.search import INTERRUPTED, NO_FEASIBLE_NEIGHBOUR, SearchInterrupted, SearchLimits, best_first_search


@dataclass(frozen=True)
class Answer:
    feasible: bool
    reason: str = ""
    warm_start: object = None


class CountingOracle:
    """Feasible unless listed; records every call and the warm start it got."""

    def __init__(self, infeasible=(), delay=0.0):
        self.infeasible = set(infeasible)
        self.calls = collections.Counter()
        self.parents = {}
        self.delay = delay

    def __call__(self, node, parent, parent_result):
        self.calls[node] += 1
        self.parents[node] = (parent, parent_result)
        if self.delay:
            time.sleep(self.delay)
        feasible = node not in self.infeasible
        return Answer(feasible, "" if feasible else f"{node} rejected", warm_start=node)


def search_graph(graph, start, goal, oracle, heuristic=None, **kwargs):
    if heuristic is None:
        heuristic = lambda n: float(graph.nodes[n].get("h", 0.0))  # noqa: E731
    return best_first_search(
        start,
        neighbours=lambda n: [(m, (n, m)) for m in graph.successors(n)],
        oracle=oracle,
        heuristic=heuristic,
        is_goal=lambda n: n == goal,
        **kwargs,
    )


def diamond():
    #      a(h=1) -> goal
    # s -<
    #      b(h=2) -> c(h=1) -> goal
    g = nx.DiGraph()
    g.add_nodes_from([("s", {"h": 3}), ("a", {"h": 1}), ("b", {"h": 2}), ("c", {"h": 1}), ("goal", {"h": 0})])
    g.add_edges_from([("s", "a"), ("s", "b"), ("a", "goal"), ("b", "c"), ("c", "goal")])
    return g


def test_search_follows_the_heuristic_to_the_exact_path():
    result = search_graph(diamond(), "s", "goal", CountingOracle())
    assert result.success and result.reason == "goal reached"
    assert result.path == ("s", "a", "goal")
    assert [r.warm_start for r in result.results] == ["s", "a", "goal"]


def test_search_detours_around_an_infeasible_node():
    oracle = CountingOracle(infeasible={"a"})
    result = search_graph(diamond(), "s", "goal", oracle)
    assert result.path == ("s", "b", "c", "goal")
    assert result.graph.nodes["a"]["status"] == "infeasible"
    assert result.graph.has_edge("s", "a")


def test_oracle_is_warm_started_from_the_parent_answer():
    oracle = CountingOracle()
    search_graph(diamond(), "s", "goal", oracle)
    assert oracle.parents["s"] == (None, None)
    parent, parent_result = oracle.parents["a"]
    assert parent == "s" and parent_result.warm_start == "s"


def test_oracle_is_called_lazily_only_on_popped_nodes():
    # A star: the start has 50 neighbours, one of them the goal.
    g = nx.DiGraph()
    g.add_node(0, h=1.0)
    for i in range(1, 51):
        g.add_node(i, h=0.0 if i == 37 else 1.0)
        g.add_edge(0, i)
    lazy = CountingOracle()
    result = search_graph(g, 0, 37, lazy)
    assert result.path == (0, 37)
    assert sum(lazy.calls.values()) == 2
    eager = CountingOracle()
    result = search_graph(g, 0, 37, eager, eager=True)
    assert result.path == (0, 37)
    assert sum(eager.calls.values()) == 51


def test_ties_break_in_generation_order_and_repeat_exactly():
    # Two symmetric branches with equal priorities: the first generated wins.
    g = nx.DiGraph()
    g.add_edges_from([("s", "x"), ("s", "y"), ("x", "goal"), ("y", "goal")])
    runs = [search_graph(g, "s", "goal", CountingOracle()) for _ in range(3)]
    assert all(r.path == ("s", "x", "goal") for r in runs)
    assert len({r.statistics.solver_calls for r in runs}) == 1
    g2 = nx.DiGraph()
    g2.add_edges_from([("s", "y"), ("s", "x"), ("x", "goal"), ("y", "goal")])
    assert search_graph(g2, "s", "goal", CountingOracle()).path == ("s", "y", "goal")


def test_unorderable_nodes_with_equal_priority_do_not_break_the_heap():
    class Opaque:
        def __init__(self, name):
            self.name = name

    s, a, b, goal = (Opaque(n) for n in "s a b goal".split())
    edges = {s: [a, b], a: [goal], b: [goal], goal: []}
    result = best_first_search(
        s,
        neighbours=lambda n: [(m, None) for m in edges[n]],
        oracle=lambda n, p, r: Answer(True),
        heuristic=lambda n: 1.0,
        is_goal=lambda n: n is goal,
    )
    assert [n.name for n in result.path] == ["s", "a", "goal"]


def wide_graph(width=8, depth=4):
    # Layers fully connected to the next one: many equal-priority choices.
    g = nx.DiGraph()
    layers = [["s"]] + [[(d, i) for i in range(width)] for d in range(1, depth)] + [["goal"]]
    for upper, lower in zip(layers, layers[1:]):
        g.add_edges_from((u, v) for u in upper for v in lower)
    return g


def test_same_seed_gives_the_same_path_and_seeds_change_the_tie_break():
    g = wide_graph()
    paths = {}
    for seed in range(6):
        first = search_graph(g, "s", "goal", CountingOracle(), shuffle_neighbours=True, seed=seed)
        again = search_graph(g, "s", "goal", CountingOracle(), shuffle_neighbours=True, seed=seed)
        assert first.path == again.path
        assert first.statistics.solver_calls == again.statistics.solver_calls
        paths[seed] = first.path
    assert len(set(paths.values())) > 1


def test_unreachable_goal_ends_with_no_feasible_neighbour_and_the_best_partial_path():
    g = diamond()
    g.add_edge("a", "d")
    g.nodes["d"]["h"] = 0.5
    oracle = CountingOracle(infeasible={"goal"})
    result = search_graph(g, "s", "goal", oracle, limits=SearchLimits(max_expansions=100))
    assert not result.success
    assert result.reason == NO_FEASIBLE_NEIGHBOUR
    assert result.path == ("s", "a", "d")
    assert result.statistics.expanded <= 100


class InterruptingOracle(CountingOracle):
    """Feasible answers until ``node`` is given, where Ctrl-C arrives."""

    def __init__(self, node, **kwargs):
        super().__init__(**kwargs)
        self.node = node

    def __call__(self, node, parent, parent_result):
        if node == self.node:
            raise KeyboardInterrupt
        return super().__call__(node, parent, parent_result)


def test_ctrl_c_during_a_solve_carries_the_best_partial_path_so_far():
    # s and a (h=1) are solved and expanded; Ctrl-C falls in the goal's solve.
    with pytest.raises(SearchInterrupted) as stopped:
        search_graph(diamond(), "s", "goal", InterruptingOracle("goal"))
    result = stopped.value.result
    assert isinstance(stopped.value, KeyboardInterrupt)
    assert not result.success and result.reason == INTERRUPTED
    assert result.path == ("s", "a")
    assert [r.warm_start for r in result.results] == ["s", "a"]
    assert result.statistics.solver_calls == 2 and result.statistics.expanded == 2


def test_ctrl_c_before_the_start_is_solved_carries_an_empty_path():
    with pytest.raises(SearchInterrupted) as stopped:
        search_graph(diamond(), "s", "goal", InterruptingOracle("s"))
    assert stopped.value.result.path == () and stopped.value.result.results == ()


def test_infeasible_start_is_reported():
    result = search_graph(diamond(), "s", "goal", CountingOracle(infeasible={"s"}))
    assert not result.success
    assert result.reason == "start infeasible: s rejected"
    assert result.path == ()


def counters(result):
    """The search's counters, without its times."""
    counts = result.statistics.to_dict()
    return {k: counts[k] for k in ("expanded", "generated", "solver_calls", "cache_hits")}


def test_statistics_count_every_expansion_child_solve_and_cache_hit_exactly():
    # s -> a (infeasible), s -> b -> c -> goal, and b, c both lead back to a:
    # pops s, a, b, c, goal (5 solves); s, b, c expanded with 2 children each;
    # a is met again as a known infeasible child of b and of c (2 cache hits).
    g = diamond()
    g.remove_edge("a", "goal")
    g.add_edges_from([("b", "a"), ("c", "a")])
    oracle = CountingOracle(infeasible={"a"})
    result = search_graph(g, "s", "goal", oracle)
    assert result.path == ("s", "b", "c", "goal")
    assert counters(result) == {"expanded": 3, "generated": 6, "solver_calls": 5, "cache_hits": 2}
    assert sum(oracle.calls.values()) == 5


def test_a_node_queued_twice_before_its_solve_is_solved_once_then_a_cache_hit():
    # x and y both queue z (infeasible) before it pops: z pops twice, solved the first time.
    g = nx.DiGraph()
    g.add_nodes_from([("s", {"h": 3.0}), ("x", {"h": 1.0}), ("y", {"h": 1.5}), ("z", {"h": 2.0})])
    g.add_edges_from([("s", "x"), ("s", "y"), ("x", "z"), ("y", "z")])
    oracle = CountingOracle(infeasible={"z"})
    result = search_graph(g, "s", "goal", oracle)
    assert result.reason == NO_FEASIBLE_NEIGHBOUR and oracle.calls["z"] == 1
    assert counters(result) == {"expanded": 3, "generated": 4, "solver_calls": 4, "cache_hits": 1}


@pytest.mark.parametrize("weight, path", [(1.0, ("s", "a1", "a2")), (2.0, ("s", "b"))], ids=["w1", "w2"])
def test_priority_adds_the_path_cost_weight_per_move(weight, path):
    # Two goals: a2 two moves away (h=1.0), b one move away (h=2.5). With a unit step,
    # a2's priority is 1.0 + 2w and b's 2.5 + w: a2 pops first iff w < 1.5.
    g = nx.DiGraph()
    g.add_nodes_from([("s", {"h": 3.0}), ("a1", {"h": 1.5}), ("a2", {"h": 1.0}), ("b", {"h": 2.5})])
    g.add_edges_from([("s", "a1"), ("a1", "a2"), ("s", "b")])
    def search(**costs):
        return best_first_search(
            "s",
            neighbours=lambda n: [(m, (n, m)) for m in g.successors(n)],
            oracle=CountingOracle(),
            heuristic=lambda n: g.nodes[n]["h"],
            is_goal=lambda n: n in ("a2", "b"),
            **costs,
        )

    assert search(path_cost_weight=weight).path == path
    # Each move costing `weight` with a weight of 1 pops alike.
    assert search(step_cost=lambda parent, child, move: weight, path_cost_weight=1.0).path == path


def test_statistics_times_lie_within_the_call():
    before = time.perf_counter()
    result = search_graph(diamond(), "s", "goal", CountingOracle(delay=0.01))
    elapsed = time.perf_counter() - before
    assert 0.03 <= result.statistics.time <= elapsed  # 3 oracle calls (s, a, goal) of 10 ms each
    assert 0.0 <= result.statistics.cpu_time <= time.process_time()


def test_no_node_is_given_to_the_oracle_twice():
    # Converging paths in a grid: every node is reachable many ways.
    grid = nx.grid_2d_graph(5, 5).to_directed()
    goal = (4, 4)
    oracle = CountingOracle(infeasible={(1, 1), (2, 3), (3, 2), (4, 3)})
    result = search_graph(
        grid,
        (0, 0),
        goal,
        oracle,
        heuristic=lambda n: 0.0,  # uniform cost: explores widely
        path_cost_weight=1.0,
    )
    assert result.success
    assert max(oracle.calls.values()) == 1
    assert result.statistics.solver_calls == sum(oracle.calls.values())
    assert result.statistics.cache_hits > 0
    assert len(result.path) == 9  # a shortest path in a 5 x 5 grid


@pytest.mark.parametrize(
    "limits, reason",
    [
        (SearchLimits(max_expansions=3, max_solver_calls=None), "budget exhausted: max_expansions"),
        (SearchLimits(max_expansions=None, max_solver_calls=5), "budget exhausted: max_solver_calls"),
    ],
    ids=["expansions", "solver-calls"],
)
def test_counting_limits_are_respected(limits, reason):
    g = nx.grid_2d_graph(6, 6).to_directed()
    oracle = CountingOracle()
    result = search_graph(g, (0, 0), "nowhere", oracle, heuristic=lambda n: 0.0, limits=limits)
    assert result.reason == reason
    if limits.max_expansions is not None:
        assert result.statistics.expanded == limits.max_expansions
    if limits.max_solver_calls is not None:
        assert sum(oracle.calls.values()) == limits.max_solver_calls
    assert result.path and result.path[0] == (0, 0)


def test_time_limit_is_respected():
    g = nx.grid_2d_graph(6, 6).to_directed()
    oracle = CountingOracle(delay=0.02)
    result = search_graph(
        g, (0, 0), "nowhere", oracle, heuristic=lambda n: 0.0, limits=SearchLimits(time_limit=0.15)
    )
    assert result.reason == "budget exhausted: time_limit"
    # One oracle call may overrun the limit, not more.
    assert result.statistics.time < 0.15 + 0.1
    assert sum(oracle.calls.values()) < 36


def test_expand_callback_sees_growing_counts_and_the_best_distance_so_far():
    seen = []
    search_graph(diamond(), "s", "goal", CountingOracle(infeasible={"a"}), on_expand=seen.append)
    assert [p.statistics.expanded for p in seen] == [1, 2, 3]
    # s (h 3) expanded, then b (h 2: a is infeasible), then c (h 1).
    assert [p.best_heuristic for p in seen] == [3.0, 2.0, 1.0]


# ------------------------------------------- node costs known only from the answer
class RecordingNeighbours:
    """Successors in a graph, recording the order in which nodes are expanded."""

    def __init__(self, graph):
        self.graph = graph
        self.expanded = []

    def __call__(self, node):
        self.expanded.append(node)
        return [(m, (node, m)) for m in self.graph.successors(node)]


def search_with_node_costs(graph, start, goal, costs, oracle=None, **kwargs):
    neighbours = RecordingNeighbours(graph)
    oracle = oracle if oracle is not None else CountingOracle()
    result = best_first_search(
        start,
        neighbours=neighbours,
        oracle=oracle,
        heuristic=lambda n: float(graph.nodes[n].get("h", 0.0)),
        is_goal=lambda n: n == goal,
        node_cost=lambda node, answer: costs.get(answer.warm_start, 0.0),
        **kwargs,
    )
    return result, neighbours.expanded, oracle


def soft_shortcut_graph():
    #      soft(h=1, node cost 2) -> goal
    # s -<
    #      firm1(h=2) -> firm2(h=1) -> goal
    g = nx.DiGraph()
    g.add_nodes_from([("s", {"h": 3}), ("soft", {"h": 1}), ("firm1", {"h": 2}), ("firm2", {"h": 1}), ("goal", {"h": 0})])
    g.add_edges_from([("s", "soft"), ("s", "firm1"), ("soft", "goal"), ("firm1", "firm2"), ("firm2", "goal")])
    return g


@pytest.mark.parametrize("soft_cost, path", [(0.0, ("s", "soft", "goal")), (2.0, ("s", "firm1", "firm2", "goal"))],
                         ids=["free", "costly"])
@pytest.mark.parametrize("eager", [False, True], ids=["lazy", "eager"])
def test_a_node_cost_known_from_the_answer_changes_the_path_exactly(soft_cost, path, eager):
    # With a unit step and weight 1: via soft 1 + 1 + cost (popped at h + g = 2 + cost),
    # via firm1 and firm2 3 + 0: soft is taken iff its cost is below 1.
    result, expanded, oracle = search_with_node_costs(
        soft_shortcut_graph(), "s", "goal", {"soft": soft_cost}, path_cost_weight=1.0, eager=eager
    )
    assert result.success and result.path == path
    if soft_cost > 0:
        # Lazy: solved first (its estimate 1 + 1 beats firm1's 2 + 1), found costly,
        # queued again and never expanded. Eager: its cost is known when it is queued.
        assert oracle.calls["soft"] == 1 and "soft" not in expanded
        assert result.graph.nodes["soft"]["status"] == "feasible"
        assert result.statistics.requeued == (0 if eager else 1)


def test_a_node_whose_true_cost_is_higher_is_not_expanded_before_cheaper_ones():
    # s's children by heuristic: x (1), y (2), z (3); x's own cost 5 makes its true
    # priority 1 + 1 + 5 = 7, above y's 3 and z's 4: x is solved first (on its
    # estimate 2), but y and z are expanded before it. Only x leads to the goal.
    g = nx.DiGraph()
    g.add_nodes_from([("s", {"h": 4}), ("x", {"h": 1}), ("y", {"h": 2}), ("z", {"h": 3}), ("goal", {"h": 0})])
    g.add_edges_from([("s", "x"), ("s", "y"), ("s", "z"), ("x", "goal")])
    solved = []
    oracle = CountingOracle()

    def recording_oracle(node, parent, parent_result):
        solved.append(node)
        return oracle(node, parent, parent_result)

    result, expanded, _ = search_with_node_costs(g, "s", "goal", {"x": 5.0}, oracle=recording_oracle,
                                                 path_cost_weight=1.0)
    assert result.path == ("s", "x", "goal")
    assert solved == ["s", "x", "y", "z", "goal"]
    assert expanded == ["s", "y", "z", "x"]
    assert result.statistics.requeued == 1 and max(oracle.calls.values()) == 1


def test_a_costly_goal_is_not_returned_before_a_cheaper_goal():
    # Two goals one move away: g1 (h 0, cost 3) and g2 (h 0.5, cost 0).
    g = nx.DiGraph()
    g.add_nodes_from([("s", {"h": 1}), ("g1", {"h": 0}), ("g2", {"h": 0.5})])
    g.add_edges_from([("s", "g1"), ("s", "g2")])
    result = best_first_search(
        "s",
        neighbours=lambda n: [(m, (n, m)) for m in g.successors(n)],
        oracle=CountingOracle(),
        heuristic=lambda n: g.nodes[n]["h"],
        is_goal=lambda n: n in ("g1", "g2"),
        node_cost=lambda node, answer: 3.0 if node == "g1" else 0.0,
    )
    assert result.path == ("s", "g2")


def test_node_costs_are_computed_once_per_node_and_added_along_the_path():
    # A grid where every node costs its answer's x coordinate: "s" reaches (2, 2)
    # through many parents; each cost is asked for once.
    grid = nx.grid_2d_graph(3, 3).to_directed()
    asked = collections.Counter()

    def cost(node, answer):
        asked[node] += 1
        return 0.25 * node[0]

    result = best_first_search(
        (0, 0),
        neighbours=lambda n: [(m, (n, m)) for m in grid.successors(n)],
        oracle=CountingOracle(),
        heuristic=lambda n: 0.0,
        is_goal=lambda n: n == (2, 2),
        node_cost=cost,
        path_cost_weight=1.0,
    )
    assert max(asked.values()) == 1
    # Uniform cost: 4 moves and the x costs 0.25 * (0 + 0 + 0 + 1 + 2) at least, reached
    # by moving along y first (costs 0, 0, 0, then 0.25, 0.5).
    assert result.path == ((0, 0), (0, 1), (0, 2), (1, 2), (2, 2))


@pytest.mark.parametrize("seed", range(6))
def test_lazy_node_costs_expand_as_a_search_that_knew_them_from_the_start(seed):
    # Random graphs, heuristics, infeasible nodes and node costs: folding each
    # node's cost into the step reaching it (known in advance) must expand the
    # same nodes in the same order and return the same path.
    rng = random.Random(seed)
    g = nx.gnp_random_graph(40, 0.12, seed=seed, directed=True)
    for n in g:
        g.nodes[n]["h"] = rng.uniform(0.0, 3.0)
    costs = {n: (rng.uniform(0.0, 2.0) if rng.random() < 0.5 else 0.0) for n in g if n != 0}
    infeasible = {n for n in g if n != 0 and rng.random() < 0.15}
    goal = max(g, key=lambda n: nx.shortest_path_length(g, 0, n) if nx.has_path(g, 0, n) else -1)
    lazy, lazy_expanded, _ = search_with_node_costs(
        g, 0, goal, costs, oracle=CountingOracle(infeasible), path_cost_weight=1.0
    )
    neighbours = RecordingNeighbours(g)
    known = best_first_search(
        0,
        neighbours=neighbours,
        oracle=CountingOracle(infeasible),
        heuristic=lambda n: g.nodes[n]["h"],
        is_goal=lambda n: n == goal,
        step_cost=lambda parent, child, move: 1.0 + costs.get(child, 0.0),
        path_cost_weight=1.0,
    )
    assert lazy.reason == known.reason
    assert lazy.path == known.path
    assert lazy_expanded == neighbours.expanded


@pytest.mark.parametrize("value", [-0.5, float("nan"), float("inf")], ids=["negative", "nan", "inf"])
def test_a_node_cost_that_is_not_a_finite_non_negative_number_is_refused(value):
    with pytest.raises(CbmError, match=re.escape(f"node_cost must return a finite value >= 0, got {value!r} for node 'a'")):
        search_with_node_costs(diamond(), "s", "goal", {"a": value}, path_cost_weight=1.0)


def test_the_search_has_the_planners_defaults():
    """One set of defaults: the search's own budgets and seed are those `cbm.plan` and
    `cbm plan` use, the values the README quotes (200 expansions, 300 s, seed 0)."""
    import inspect

    from cbm.planner import plan

    limits = SearchLimits()
    assert (limits.max_expansions, limits.max_solver_calls, limits.time_limit) == (200, None, 300.0)
    planner = inspect.signature(plan).parameters
    assert (planner["max_expansions"].default, planner["max_solver_calls"].default, planner["time_limit"].default) == (
        limits.max_expansions,
        limits.max_solver_calls,
        limits.time_limit,
    )
    assert inspect.signature(best_first_search).parameters["seed"].default == planner["seed"].default == 0


def test_solving_ahead_is_asked_for_not_implied_by_submit():
    """lookahead defaults to 0: a search given ``submit`` without a lookahead is refused
    rather than solving ahead by a default nobody chose."""
    import inspect

    assert inspect.signature(best_first_search).parameters["lookahead"].default == 0
    with pytest.raises(CbmError, match="^lookahead must be a positive integer with submit, got 0$"):
        best_first_search(
            "a", neighbours=lambda n: [], oracle=lambda *a: None, heuristic=lambda n: 0.0,
            is_goal=lambda n: True, submit=lambda *args: None,
        )


def test_solving_ahead_starts_the_best_open_entries_while_done_answers_wait():
    """Answers started earlier and not yet taken (done, so not running) do not use up the
    window of open entries looked at: the two best open nodes are started."""
    import heapq
    from concurrent.futures import Future

    from cbm.search import _Lookahead

    def done(value):
        future = Future()
        future.set_result(value)
        return future

    started = []

    def submit(node, parent, parent_result):
        started.append((node, parent))
        return Future()  # still running

    ahead = _Lookahead(submit, 2, cache={}, closed=set())
    ahead.pending = {(f"old{i}", None): done(i) for i in range(8)}
    # The search's heap entries: (priority, order, node, parent, cost, total, settled).
    heap = [(float(i), i, f"n{i}", f"p{i}", 10.0 + i, 20.0 + i, False) for i in range(5)]
    heapq.heapify(heap)
    ahead.fill(heap)
    assert started == [("n0", "p0"), ("n1", "p1")]
    assert set(ahead.pending) >= {("n0", "p0"), ("n1", "p1")}
    # Closed nodes at the top of the heap (entries the search will skip) are looked
    # past: up to 4 entries per call it may run, so the two open ones after 6 closed start.
    started.clear()
    closed = {f"c{i}" for i in range(6)}
    ahead = _Lookahead(submit, 2, cache={}, closed=closed)
    heap = [(float(i), i, f"c{i}", "p", 0.0, 0.0, False) for i in range(6)]
    heap += [(10.0 + i, 10 + i, f"n{i}", "p", 0.0, 0.0, False) for i in range(3)]
    heapq.heapify(heap)
    ahead.fill(heap)
    assert started == [("n0", "p"), ("n1", "p")]
