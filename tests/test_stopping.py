"""The SQP's stopping test on its own: each rule fed a sequence that must fire it, and
one just short of it that must not (the toy SQPs of test_sqp_toy.py run them inside
the loop)."""

import numpy as np
import pytest

from stances import stopping
from stances.stopping import StoppingTest, at_rounding_floor, better

TOLERANCE = 1e-7


class _Iterate:
    """The two things the rules read of a linearisation: its objective and its violation."""

    def __init__(self, objective, violation=0.0):
        self.objective, self.violation = objective, violation

    def met(self, tolerance):
        return self.violation <= tolerance

    def max_violation(self):
        return self.violation, "row"


def _point(objective, violation=0.0):
    return (np.zeros(1), np.zeros(0), _Iterate(objective, violation))


@pytest.fixture
def stops():
    return StoppingTest(TOLERANCE, 1e-6, limit=100)


def test_a_negligible_step_at_a_feasible_iterate_is_the_answer(stops):
    assert stops.converged_before_search(_Iterate(1.0), 5e-8, 1.0)
    assert stops.converged_before_search(_Iterate(1.0), 1.0, 1e-9)
    assert not stops.converged_before_search(_Iterate(1.0), 1e-6, 1e-6)
    assert not stops.converged_before_search(_Iterate(1.0, violation=1e-3), 0.0, 0.0)


def test_a_restoration_finishes_only_an_infeasible_iterate_within_the_band_whose_step_gains_nothing(stops):
    """The optimality tolerance is 1e-6 here: the gain bound is FINISHING_GAIN of it, times
    (1 + |objective|); each condition failed alone keeps the line search."""
    bound = stopping.FINISHING_GAIN * 1e-6 * 2.0  # objective 1
    inside = stopping.FINISHING_VIOLATION
    assert stops.finishing(False, inside, 0.99 * bound, 1.0)
    assert stops.finishing(False, inside, 0.99 * bound, -1.0)
    assert not stops.finishing(True, inside, 0.0, 1.0)  # feasible: the usual stops decide
    assert not stops.finishing(False, 1.01 * inside, 0.0, 1.0)  # too far for one restoration
    assert not stops.finishing(False, inside, 1.01 * bound, 1.0)  # optimality still gains


def test_a_gauss_newton_tail_is_finished_once_what_it_would_still_gain_is_negligible():
    """Gains of three iterations in a row falling at r = 0.8 (left-on-platform's Coulomb
    stage) finish once gain / (1 - r) is under FINISHING_TAIL tolerances; a slow tail
    (r = 0.9, a point far off a sphere), one sudden drop, gains from iterations not in a row,
    a rising gain or forgotten objectives do not use the rule."""
    unit = 1e-6 * 2.0  # optimality tolerance 1e-6, objective 1
    tail = stopping.FINISHING_TAIL * unit
    inside = stopping.FINISHING_VIOLATION

    def finishes(gains, iterations=None, forget=False):
        stops = StoppingTest(TOLERANCE, 1e-6, limit=100)
        answers = []
        for index, gain in enumerate(gains):
            if forget and index == len(gains) - 1:
                stops.forget_objectives()
            iteration = (iterations or range(1, len(gains) + 1))[index]
            answers.append(stops.finishing(False, inside, gain, 1.0, iteration))
        return answers

    def falling(last, *ratios):
        """Gains ending at ``last``, each the one before times its ratio."""
        gains = [last]
        for ratio in reversed(ratios):
            gains.insert(0, gains[0] / ratio)
        return gains

    assert stopping.FINISHING_GAIN * unit < 0.19 * tail  # the gain alone never decides here
    assert finishes(falling(0.19 * tail, 0.8, 0.8)) == [False, False, True]  # 0.95 of the bound left
    assert finishes(falling(0.21 * tail, 0.8, 0.8))[-1] is False  # 1.05 of it
    assert finishes(falling(0.19 * tail, 0.9, 0.9))[-1] is False  # slow: 1.9 times the bound
    assert finishes(falling(0.19 * tail, 0.8))[-1] is False  # one ratio is no rate
    assert finishes(falling(0.19 * tail, 0.95, 0.001))[-1] is False  # a sudden drop: r is 0.95
    assert finishes(falling(0.19 * tail, 0.001, 0.8))[-1] is True  # a drop, then a steady 0.8
    assert finishes(falling(0.19 * tail, 0.8, 0.8), iterations=[1, 2, 4])[-1] is False
    assert finishes(falling(0.19 * tail, 0.8, 0.8), iterations=[1, 3, 4])[-1] is False
    assert finishes(falling(0.19 * tail, 0.8, 1.25))[-1] is False  # rising
    assert finishes(falling(0.19 * tail, 0.8, 0.8), forget=True)[-1] is False
    stops = StoppingTest(TOLERANCE, 1e-6, limit=100)
    for iteration, gain in enumerate(falling(0.19 * tail, 0.8, 0.8)[:-1], start=1):
        stops.finishing(False, inside, gain, 1.0, iteration)
    assert not stops.finishing(True, inside, 0.19 * tail, 1.0, 3)  # feasible: the usual stops decide


def test_stagnation_needs_a_full_window_a_large_penalty_and_no_1_percent_fall(stops):
    window = stopping._STAGNATION_WINDOW
    for iteration in range(1, window + 1):
        assert stops.diverging(iteration, 1.0, 0.0, 1e4) is None
    assert stops.diverging(window + 1, 0.995, 0.0, 1e3) is None  # the penalty still low
    assert stops.diverging(window + 2, 0.995, 0.0, 1e4) == "stagnated"


def test_a_violation_falling_too_slowly_ends_once_its_qp_cannot_meet_its_rows(stops):
    window = stopping._STAGNATION_WINDOW
    violations = 0.9 ** np.arange(window + 1)  # 10 % an iteration: 1e-7 is 150 away
    for iteration, violation in enumerate(violations[:-1], start=1):
        assert stops.diverging(iteration, violation, 0.0, 1e6) is None
    assert stops.diverging(90, violations[-1], 0.0, 1e6) is None  # elastic 0: a grace
    assert stops.diverging(91, violations[-1] * 0.9, 1.0, 1e6) == "converging too slowly: 10.0% an iteration"


def test_cut_steps_far_from_feasible_end_the_solve_unless_the_violation_halves(stops):
    violation = 1.0
    for _ in range(stopping.CRAWL_STEPS - 1):
        assert not stops.hopeless(violation, None, 0.0)
    assert stops.hopeless(violation, _point(1.0, violation=0.6), 1.0 / 32)
    fresh = StoppingTest(TOLERANCE, 1e-6, limit=100)
    for _ in range(stopping.CRAWL_STEPS - 1):
        fresh.hopeless(violation, None, 0.0)
    assert not fresh.hopeless(violation, _point(1.0, violation=0.4), 1.0 / 32)
    near = StoppingTest(TOLERANCE, 1e-6, limit=100)
    assert not any(near.hopeless(1e-3, None, 0.0) for _ in range(10))  # not far from feasible


def _creep(stops, steps):
    """Feed ``(violation before, violation after, alpha)`` steps to creeping; its answers."""
    return [stops.creeping(before, after, alpha) for before, after, alpha in steps]


def _creeper():
    return StoppingTest(TOLERANCE, 1e-6, limit=25, creep=True)


def test_cut_steps_creeping_far_from_feasible_end_a_stage_that_has_a_fallback():
    count = stopping.CREEP_STEPS
    # The quadruped-foam planner stance's free Coulomb stage: cut to 1/8-1/2, 4 % an iteration.
    violations = 0.28 * 0.96 ** np.arange(count + 3)
    steps = [(violations[i], violations[i + 1], 0.25) for i in range(count + 2)]
    assert _creep(_creeper(), steps) == [False] * (count - 1) + [True] * 3
    # Any cut counts (3/4 too); a whole step restarts the count; without a fallback the
    # rule is off.
    assert _creep(_creeper(), [(v, w, 0.75) for v, w, _ in steps])[count - 1]
    whole = [(v, w, 1.0 if i == 1 else 0.25) for i, (v, w, _) in enumerate(steps)]
    assert _creep(_creeper(), whole) == [False] * (count + 1) + [True]
    assert not any(_creep(StoppingTest(TOLERANCE, 1e-6, limit=25), steps))
    # Half of the violation where the cuts began is the line: 0.55 of it after the sixth
    # step ends the stage, 0.45 does not; nor does a creep near feasibility.
    for ratio, ends in ((0.55, True), (0.45, False)):
        falling = 0.28 * ratio ** (np.arange(count + 1) / count)
        cut = [(falling[i], falling[i + 1], 0.25) for i in range(count)]
        assert _creep(_creeper(), cut) == [False] * (count - 1) + [ends]
    near = [(v, 0.99 * v, 0.25) for v in 5e-3 * 0.99 ** np.arange(count + 2)]
    assert not any(_creep(_creeper(), near))


def test_nearly_feasible_steps_cut_without_the_violation_halving_linger(stops):
    window = stopping.LINGER_ITERATIONS
    # A palm stance of rail-over-gap: a whole step and one cut to 1/128 in turn, the
    # violation at 1.35-1.45e-7; only the cut ones count.
    hovering = [(1.35e-7, False), (1.42e-7, True)] * window
    fired = [stops.lingering(violation, False, troubled) for violation, troubled in hovering]
    assert fired == [False] * (2 * window - 1) + [True]


def test_whole_steps_halving_or_doubling_and_feasibility_restart_the_count(stops):
    window = stopping.LINGER_ITERATIONS
    # Whole steps creeping 10 % an iteration: progress, never counted.
    assert not any(stops.lingering(5e-6 * 0.9**k, False, False) for k in range(20))
    # Cut steps whose violation halves each time: counted from anew each time.
    assert not any(stops.lingering(8e-6 * 0.45**k, False, True) for k in range(8))
    # A rise beyond twice the reference starts the count again (then halving: never fires).
    stops = StoppingTest(TOLERANCE, 1e-6, limit=100)
    assert not any(stops.lingering(v, False, True) for v in [2e-7, 8e-6, 3.5e-6, 1.6e-6, 7e-7])
    # A feasible iterate, or one outside the band, resets it.
    stops = StoppingTest(TOLERANCE, 1e-6, limit=100)
    for _ in range(window - 1):
        assert not stops.lingering(5e-7, False, True)
    assert not stops.lingering(5e-7, True, True)  # met (a block's own accuracy)
    assert not any(stops.lingering(5e-7, False, True) for _ in range(window - 1))
    assert not stops.lingering(2e-5, False, True)  # above LINGER_VIOLATION
    assert not any(stops.lingering(5e-7, False, True) for _ in range(window - 1))
    assert stops.lingering(5e-7, False, True)


def test_the_lingering_band_is_within_the_verified_band_and_empty_for_warm_starts():
    # A tighter tolerance: only iterates an answer would go to verify from (100 tolerances).
    tight = StoppingTest(1e-9, 1e-6, limit=100)
    assert not any(tight.lingering(5e-7, False, True) for _ in range(10))  # 500 tolerances: not near
    assert any(tight.lingering(5e-8, False, True) for _ in range(10))
    # A warm start's loose tolerance (1e-2): the band (1e-2, 1e-5] is empty.
    loose = StoppingTest(1e-2, 1e-2, limit=100)
    assert not any(loose.lingering(v, False, True) for v in (5e-6, 0.06) for _ in range(10))


def test_failed_searches_stall_after_four_or_at_once_where_nothing_changes(stops):
    assert [stops.stalled(1.0, 1.0, True, False) for _ in range(4)] == [False, False, False, True]
    assert StoppingTest(TOLERANCE, 1e-6, 100).stalled(1e-3, 0.0, False, False)  # the same QP again
    assert not StoppingTest(TOLERANCE, 1e-6, 100).stalled(1e-3, 0.0, False, True)  # the curvature may enter
    assert StoppingTest(TOLERANCE, 1e-6, 100).stalled(2e-7, 0.0, False, False)  # the rows' rounding


def test_the_rounding_floor_is_absolute_and_needs_met_linearised_rows():
    assert at_rounding_floor(2e-7, 0.0, 1e-7)
    assert not at_rounding_floor(2e-7, 1e-6, 1e-7)  # the QP could not meet its rows
    assert not at_rounding_floor(5e-3, 0.0, 1e-3)  # a warm start's loose tolerance
    assert not at_rounding_floor(5e-8, 0.0, 1e-7)  # feasible


def test_a_feasible_step_that_barely_moves_the_objective_is_final(stops):
    first = _point(1.0)
    assert stops.converged(1, first, _Iterate(2.0), 0.0, 1.0, 1.0, 1.0) is None
    assert stops.best is first
    # 1e-6 of 1 + |f|, under the optimality tolerance of 1e-6 relative to 2: final.
    last = _point(1.0 - 1e-6)
    assert stops.converged(2, last, first[2], 0.0, 1.0, 1.0, 1.0) is last
    # 1e-3: not final.
    assert StoppingTest(TOLERANCE, 1e-6, 100).converged(2, _point(0.999), first[2], 0.0, 1.0, 1.0, 1.0) is None


def test_a_restoration_in_place_of_a_failed_search_that_gains_nothing_is_not_final(stops):
    """A restoration step ignores the objective: that it moved it by nothing says nothing
    of optimality, whether the line search found no optimality step (searched = 0) or cut
    it and the restoration took its place (alpha = 1 > searched)."""
    def steps(searched):
        test = StoppingTest(TOLERANCE, 1e-6, limit=100)
        test.converged(1, _point(1.0), _Iterate(2.0), 0.0, 1.0, 1.0, 1.0)  # the best feasible iterate
        near = _point(0.99, violation=1e-6)  # an optimality step 1 % down, just off the rows
        assert test.converged(2, near, _Iterate(1.0), 0.0, 1.0, 1.0, 0.02) is None
        restored = _point(0.99 - 1e-9)  # back onto them, the objective unmoved
        return test.converged(3, restored, near[2], 1e-6, 1.0, searched, 0.01), restored

    assert steps(searched=0.0)[0] is None
    assert steps(searched=1.0 / 32.0)[0] is None
    # The same gain from an optimality step taken whole is final.
    answer, restored = steps(searched=1.0)
    assert answer is restored


def test_a_cycle_that_beats_the_best_by_less_than_no_gain_ends_at_the_best(stops):
    best = _point(1.0)
    stops.converged(1, best, _Iterate(2.0), 0.0, 1.0, 1.0, 1.0)
    answer = None
    for iteration in range(2, 2 + stopping.NO_GAIN_ITERATIONS):
        # infeasible neighbours with large objective moves: no convergence by gain
        answer = stops.converged(iteration, _point(0.5, violation=1e-3), _Iterate(3.0), 1e-3, 1.0, 1.0, 1.0)
    assert answer is best


def test_after_the_objective_changes_old_iterates_are_forgotten(stops):
    stops.converged(1, _point(1.0), _Iterate(2.0), 0.0, 1.0, 1.0, 1.0)
    stops.forget_objectives()
    assert stops.best is None
    infeasible = _point(5.0, violation=1.0)
    assert stops.final(infeasible) is infeasible


def test_an_infeasible_last_iterate_gives_way_to_the_best_feasible_one(stops):
    best = _point(1.0)
    stops.converged(1, best, _Iterate(2.0), 0.0, 1.0, 1.0, 1.0)
    assert stops.final(_point(0.5, violation=1.0)) is best
    feasible = _point(0.9)
    assert stops.final(feasible) is feasible
    assert better(best, feasible) is feasible and better(best, _point(1.5)) is best and better(None, best) is best
