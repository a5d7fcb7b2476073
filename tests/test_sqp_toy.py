"""The SQP iterations (:func:`stances.sqp.run_sqp`) on toy problems whose optimum is known.

A toy problem is a point in space (a pinocchio model with one translation
joint, so ``pin.integrate`` is plain addition) plus optional force variables,
with an objective and constraint rows written out by hand. The loop sees the
same interface as on a robot (``options``, ``variable_lower``, ``robot.model``,
``linearize``, ``evaluate``); the answers are checked against the closed-form optimum and its
Lagrange multipliers, recovered from the stationarity of the final
linearisation (the loop itself does not return multipliers) and read from the
QP's answer.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin
import pytest

from stances.blocks import ConstraintBlock, equality
from stances.problem import Linearization, PostureOptions
from stances.qp import QPWorkspace, elastic_qp, row_multipliers
from stances import sqp, stages, stopping
from stances.sqp import run_sqp


@dataclass(frozen=True)
class PointRobot:
    """What the SQP reads of a robot: its pinocchio model (one translation joint, nq = nv = 3)."""

    model: pin.Model


def point_model() -> pin.Model:
    model = pin.Model()
    model.addJoint(0, pin.JointModelTranslation(), pin.SE3.Identity(), "point")
    return model


class ToyProblem:
    """A point ``q`` (3,) and force variables ``lam`` (m,) >= 0 under hand-written rows.

    Parameters
    ----------
    objective : callable
        ``(q, lam) -> (value, gradient (3 + m,), Hessian (3 + m, 3 + m))``.
    rows : callable
        ``(q, lam) -> list of ConstraintBlock``, Jacobians in ``(dq, dlam)``.
    n_variables : int
        m, the number of force variables.
    constraint_curvature : bool
        The SQP option (off: the QP's Hessian is the objective's alone).
    """

    def __init__(self, objective, rows, n_variables=0, constraint_curvature=False):
        self.robot = PointRobot(point_model())
        # No torque-usage phase: the toy has no torques.
        self.options = PostureOptions(torque_weight=0.0, constraint_curvature=constraint_curvature)
        self.variable_lower = np.zeros(n_variables)
        self._objective, self._rows = objective, rows

    def linearize(self, q, lam, torque_weight=None) -> Linearization:
        value, gradient, hessian = self._objective(q, lam)
        bound = self.options.trust_region
        step_lower = np.full(len(gradient), -bound)
        step_upper = np.full(len(gradient), bound)
        step_lower[3:] = np.maximum(self.variable_lower - lam, -bound)
        return Linearization(
            value, gradient, hessian, self._rows(q, lam), step_lower, step_upper, np.zeros((0, 3)), np.zeros(0)
        )

    def evaluate(self, q, lam, torque_weight=None) -> Linearization:
        # The line search reads only the objective and the rows' values.
        return self.linearize(q, lam, torque_weight)


def squared_distance_to(target):
    """Half the squared distance of ``(q, lam)`` to ``target`` (3 + m,), Hessian the identity."""

    def objective(q, lam):
        error = np.concatenate([q, lam]) - target
        return 0.5 * float(error @ error), error, np.eye(len(error))

    return objective


RADIUS = 1.0


def on_the_sphere(q, lam):
    """``|q|^2 - RADIUS^2 = 0``, with its curvature: ``sum_i y_i grad c_i`` at any point is ``2 y q``."""
    return [
        equality(
            "sphere", np.array([q @ q - RADIUS**2]), 2.0 * q[None, :], 1.0, ["on the sphere"],
            second_order=lambda model, data, weights: 2.0 * weights[0] * data.oMi[1].translation,
        )
    ]


START = np.array([0.3, -0.5, 0.9])


@pytest.mark.parametrize("distance", [1.1, 0.9, 1.3], ids=["outside-rate-0.1", "inside-rate-0.1", "outside-rate-0.3"])
def test_closest_point_on_a_sphere_at_the_rate_its_hessian_predicts(distance, monkeypatch):
    """min 1/2 |q - a|^2 on the sphere |q| = r: q* = r a / |a|, multiplier y = (|a| - r) / (2 r).

    The SQP's Hessian is the objective's alone (the identity); the Lagrangian's
    is (1 + 2y) I on the tangent plane, so the tangential error contracts by
    |1 - (1 + 2y)| = |2y| per full step: linear convergence at that rate, no
    slower (a wrong Hessian or a line search that shortens steps near the
    solution would be slower; a wrong gradient would converge elsewhere). The
    optimality iterations alone: no finishing restoration step (tested below).
    """
    monkeypatch.setattr(stopping, "FINISHING_VIOLATION", 0.0)
    target = distance * np.array([1.0, 2.0, 2.0]) / 3.0
    problem = ToyProblem(squared_distance_to(target), on_the_sphere)
    optimum = RADIUS * target / np.linalg.norm(target)
    multiplier = (np.linalg.norm(target) - RADIUS) / (2.0 * RADIUS)
    rate = abs(2.0 * multiplier)

    outcome = run_sqp(problem, START, np.zeros(0), limit=100)
    assert outcome.feasible and outcome.status == "converged" and outcome.reason == ""
    # From |q0 - q*| ~ 1 to 1e-6 at rate <= 0.3 takes 12 full steps; a few more
    # for the globalised start.
    assert outcome.iterations <= 20
    # Once feasible, the loop stops when a step moves the objective by < 1e-7
    # relative: the objective is then that close to its optimum, while q, along
    # the flat bottom of the objective on the constraint, may still be off by
    # the last steps' size (1.4e-6 to 3.3e-5 measured).
    assert abs(outcome.linearization.objective - 0.5 * (np.linalg.norm(target) - RADIUS) ** 2) < 1e-7 * (
        1.0 + 0.5 * (np.linalg.norm(target) - RADIUS) ** 2
    )
    assert np.linalg.norm(outcome.q - optimum) < 1e-4
    # Stationarity of the final linearisation gives the multiplier of the sphere
    # the iterate lies on (its radius off by the final violation, within the
    # tolerance: 0.3 of it in the multiplier, up to 1.2e-8 measured) to second order
    # in the (tangential) error of q: to 1e-9.
    linearization = outcome.linearization
    jacobian = linearization.blocks[0].jacobian
    estimate = np.linalg.lstsq(jacobian.T, -linearization.gradient, rcond=None)[0][0]
    on_its_sphere = (np.linalg.norm(target) - np.linalg.norm(outcome.q)) / (2.0 * np.linalg.norm(outcome.q))
    assert estimate == pytest.approx(on_its_sphere, abs=1e-9)
    assert on_its_sphere == pytest.approx(multiplier, abs=1e-7)

    # The same loop stopped after k iterations gives the k-th iterate.
    errors = np.array(
        [np.linalg.norm(run_sqp(problem, START, np.zeros(0), limit=k).q - optimum) for k in range(1, outcome.iterations)]
    )
    # Asymptotic regime: close enough for the linear model (1e-2), far from the
    # QP's accuracy floor (1e-5).
    close = (errors[:-1] < 1e-2) & (errors[:-1] > 1e-5)
    assert np.count_nonzero(close) >= 2
    ratios = errors[1:][close] / errors[:-1][close]
    assert np.all(ratios <= rate + 5e-3), (ratios, rate)


@pytest.mark.parametrize("distance, iterations", [(1.3, 10), (1.6, 13), (1.95, 53)])
def test_a_nearly_feasible_iterate_that_optimality_no_longer_moves_is_finished_by_a_restoration(distance, iterations,
                                                                                            monkeypatch):
    """Near the sphere's closest point each optimality step leaves a violation of its
    length squared, and the steps shrink at the linear rate |2y| (0.3, 0.6, 0.95): the
    last iterations only chase that violation. Once a QP step would gain less than
    FINISHING_GAIN optimality tolerances of the objective by optimality (``1/2 s^T H s``),
    or the gains falling at their rate would gain less than FINISHING_TAIL in all, from
    within FINISHING_VIOLATION, the shortest step onto the sphere ends the solve: fewer
    iterations (measured 10, 13, 53 against 12, 18, 86; 11, 15, 53 with the gain's bound
    alone), on the sphere, the objective within FINISHING_TAIL of its optimum (measured 9.2,
    19.3 and 5.1 units of tolerance times 1 + objective: the slow tail, its gains falling by
    0.90, waits for the gain's own bound)."""
    target = distance * np.array([1.0, 2.0, 2.0]) / 3.0
    optimum = 0.5 * (np.linalg.norm(target) - RADIUS) ** 2
    problem = ToyProblem(squared_distance_to(target), on_the_sphere)
    finished = run_sqp(problem, START, np.zeros(0), limit=200)
    monkeypatch.setattr(stopping, "FINISHING_VIOLATION", 0.0)
    plain = run_sqp(problem, START, np.zeros(0), limit=200)
    for outcome in (finished, plain):
        assert outcome.feasible and outcome.status == "converged"
    assert finished.iterations < plain.iterations
    assert finished.iterations == iterations  # the tail's rule at work: 11 and 15 without it
    unit = problem.options.optimality_tolerance * (1.0 + optimum)
    assert -1e-9 <= finished.linearization.objective - optimum <= stopping.FINISHING_TAIL * unit
    # the finishing's price, no more
    assert abs(plain.linearization.objective - optimum) < 0.1 * stopping.FINISHING_GAIN * unit


def test_a_step_held_by_a_bound_is_not_finished_however_little_curvature_it_reads(monkeypatch):
    """min 1/2 q_y^2 + 1/2 1e-5 (q_z - 300)^2 on the plane q_x = 0, from 5e-5 off it (found by
    review). The QP's step runs 0.3 along z, held by the trust region: 1/2 s^T H s reads
    4.5e-7, under the finishing bound, but the step gains 9e-4 (the bound's multiplier takes
    the rest). It is not finished: the solve goes on along z like the one without the rule
    (finished, it stopped 'converged' at its first iteration, objective 0.45)."""
    curvature = np.diag([0.0, 1.0, 1e-5]) + 1e-12 * np.eye(3)
    far = np.array([0.0, 0.0, 300.0])

    def objective(q, lam):
        error = q - far
        return 0.5 * float(error @ curvature @ error), curvature @ error, curvature.copy()

    def on_the_plane(q, lam):
        return [equality("plane", np.array([q[0]]), np.array([[1.0, 0.0, 0.0]]), 1.0, ["on the plane"])]

    problem = ToyProblem(objective, on_the_plane)
    start = np.array([5e-5, 0.0, 0.0])
    outcome = run_sqp(problem, start, np.zeros(0), limit=20)
    monkeypatch.setattr(stopping, "FINISHING_VIOLATION", 0.0)
    plain = run_sqp(problem, start, np.zeros(0), limit=20)
    assert outcome.iterations == plain.iterations == 20 and outcome.q[2] > 5.0
    np.testing.assert_array_equal(outcome.q, plain.q)


def test_a_slow_but_steady_creep_near_feasibility_is_not_cut_short():
    """Far out (|a| = 1.95, rate 0.95 with the objective's Hessian alone) the violation
    creeps down 5-10 % an iteration near feasibility, every step taken whole: that is
    progress, not hovering (stopping.LINGER_ITERATIONS counts only cut, failed or
    elastic steps), and the solve converges to the optimum."""
    target = 1.95 * np.array([1.0, 2.0, 2.0]) / 3.0
    outcome = run_sqp(ToyProblem(squared_distance_to(target), on_the_sphere), START, np.zeros(0), limit=200)
    assert outcome.feasible and outcome.status == "converged"
    assert outcome.iterations > 40  # slow indeed: dozens of iterations in the lingering band
    np.testing.assert_allclose(outcome.q, RADIUS * target / np.linalg.norm(target), atol=1e-3)


@pytest.mark.parametrize("distance", [1.6, 0.5], ids=["outside-rate-0.6", "inside-rate-0.5"])
def test_constraint_curvature_reaches_the_sphere_optimum_in_fewer_iterations(distance):
    """With the constraint's curvature (2 y I, y of either sign) the QP's Hessian is the
    Lagrangian's, (1 + 2y) I: Newton's method, converging faster than the objective's
    Hessian alone (linear rate |2y|: 0.6 outside, 0.5 inside) and to a tighter answer."""
    target = distance * np.array([1.0, 2.0, 2.0]) / 3.0
    optimum = RADIUS * target / np.linalg.norm(target)
    outcomes = {}
    for curvature in (False, True):
        problem = ToyProblem(squared_distance_to(target), on_the_sphere, constraint_curvature=curvature)
        outcomes[curvature] = run_sqp(problem, START, np.zeros(0), limit=100)
        assert outcomes[curvature].feasible and outcomes[curvature].status == "converged"
    plain, curved = outcomes[False], outcomes[True]
    assert curved.iterations < plain.iterations
    assert curved.iterations <= 10  # 14 and 18 without (measured)
    assert np.linalg.norm(curved.q - optimum) < 1e-6 < np.linalg.norm(plain.q - optimum)


# Force variables and an inequality: min 1/2 |q - a|^2 + 1/2 |lam - c|^2
# s.t. sum(q) + sum(lam) = S, q_z <= CAP, lam >= 0.
TARGET = np.array([0.2, -0.1, 0.8, 0.4, -0.2])  # (a, c)
SUM, CAP = 0.1, 0.3


def sum_and_cap(q, lam):
    value = q.sum() + lam.sum() - SUM
    cap_row = np.array([[0.0, 0.0, 1.0, 0.0, 0.0]])
    return [
        equality("sum", np.array([value]), np.ones((1, 5)), 1.0, ["sum of q and lam"]),
        ConstraintBlock("cap", np.array([q[2]]), cap_row, -np.inf, CAP, 1.0, ("q_z cap",)),
    ]


@pytest.mark.parametrize(
    "q_start, lam_start",
    [(np.zeros(3), np.array([0.1, 0.1])), (np.array([0.0, -0.1, 0.1]), np.array([0.1, 0.1]))],
    ids=["beyond-the-trust-region", "within-the-trust-region"],
)
def test_quadratic_problem_with_active_bounds_is_solved_exactly(q_start, lam_start):
    """With the cap and lam_1 >= 0 active (c_1 < 0), the KKT conditions give
    y = (a_x + a_y + CAP + c_0 - S) / 3 for the sum row, q = (a_x - y, a_y - y, CAP),
    lam = (c_0 - y, 0), cap multiplier a_z - y - CAP and bound multiplier y - c_1,
    both > 0 here (so the active set is the right one)."""
    a, c = TARGET[:3], TARGET[3:]
    y = (a[0] + a[1] + CAP + c[0] - SUM) / 3.0
    q_optimum = np.array([a[0] - y, a[1] - y, CAP])
    lam_optimum = np.array([c[0] - y, 0.0])
    multipliers = np.array([y, a[2] - y - CAP, y - c[1]])
    assert np.all(multipliers[1:] > 0)

    outcome = run_sqp(ToyProblem(squared_distance_to(TARGET), sum_and_cap, 2), q_start, lam_start, limit=100)
    assert outcome.feasible and outcome.status == "converged"
    # The QP is the problem itself: one step to the optimum (a second when the
    # trust region of 0.3 cuts the first, |q_y*| = 0.33), then one to the QP's
    # full accuracy (it is solved to 1e-6 while the violation is large), then
    # the stopping test.
    assert outcome.iterations <= 4
    np.testing.assert_allclose(outcome.q, q_optimum, atol=1e-8)
    np.testing.assert_allclose(outcome.lam, lam_optimum, atol=1e-8)
    assert outcome.lam[1] == 0.0  # on its bound, not near it
    # Multipliers of the active rows (sum, cap, lam_1 >= 0 as -lam_1 <= 0) from stationarity.
    active = np.array([np.ones(5), [0.0, 0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, -1.0]])
    gradient = outcome.linearization.gradient
    estimate, *_ = np.linalg.lstsq(active.T, -gradient, rcond=None)
    np.testing.assert_allclose(estimate, multipliers, atol=1e-8)
    assert np.linalg.norm(active.T @ estimate + gradient) < 1e-8
    # The QP's own multipliers at the optimum, per row label, in the same convention.
    workspace = QPWorkspace()
    workspace.solve(*elastic_qp(outcome.linearization, 100.0), accuracy=1e-10)
    rows = row_multipliers(outcome.linearization, workspace.multipliers)
    assert rows["sum of q and lam"] == pytest.approx(multipliers[0], abs=1e-7)
    assert rows["q_z cap"] == pytest.approx(multipliers[1], abs=1e-7)


def contradicting_rows(q, lam):
    """``q_x = 0`` and ``q_x = 1``: no point meets both."""
    row = np.array([[1.0, 0.0, 0.0]])
    return [
        equality("a", np.array([q[0]]), row, 1.0, ["q_x at 0"]),
        equality("b", np.array([q[0] - 1.0]), row, 1.0, ["q_x at 1"]),
    ]


INFEASIBLE_TARGET = np.array([0.2, 0.3, 0.4])


def test_contradicting_rows_end_at_the_least_violation_with_a_reason():
    """The elastic QP minimises the largest violation: q_x = 1/2, both rows off
    by 1/2; the directions the rows leave free go to the objective's optimum."""
    problem = ToyProblem(squared_distance_to(INFEASIBLE_TARGET), contradicting_rows)
    outcome = run_sqp(problem, np.zeros(3), np.zeros(0), limit=100)
    assert not outcome.feasible
    # Any of the infeasible stops (the violation falls towards its floor of 1/2).
    assert outcome.status in ("stalled", "stagnated") or outcome.status.startswith(
        ("converging too slowly: ", "no progress toward feasibility: ")
    )
    np.testing.assert_allclose(outcome.q, [0.5, 0.3, 0.4], atol=1e-8)
    assert outcome.iterations < 100
    head, tail = outcome.reason.split(" violated by ")
    assert head in ("q_x at 0", "q_x at 1")
    assert tail.startswith(f"0.5 N ({outcome.status} after {outcome.iterations} iterations)")


def test_contradicting_rows_are_named_together():
    problem = ToyProblem(squared_distance_to(INFEASIBLE_TARGET), contradicting_rows)
    outcome = run_sqp(problem, np.zeros(3), np.zeros(0), limit=100)
    clause = outcome.reason.split("; no step meets together: ")[1]
    assert sorted(clause.split(", ")) == ["q_x at 0", "q_x at 1"]


@pytest.mark.parametrize("placement, other, prefix", [
    ("placement of a on mat_top (z, elastic)", "strain bound (compression) of tet 7 of mat", sqp.SOFT_SUPPORT_GIVES),
    ("placement of a on mat_top (z, elastic)", "mesh overlap bound (0.002 m, max_mesh_overlap) at node 3 of mat",
     sqp.SOFT_SUPPORT_GIVES),
    ("placement of a on floor (z)", "strain bound (compression) of tet 7 of mat", "print unreachable: "),
    ("placement of a on mat_top (z, elastic)", "collision between a and b", "print unreachable: "),
], ids=["soft print held back by its strain", "by its mesh overlap", "rigid print", "soft print held by a collision"])
def test_a_soft_print_held_back_by_its_body_is_not_called_unreachable(placement, other, prefix):
    """A soft print's elastic placement at the worst, with its body's strain or mesh
    overlap among the rows no step meets together: the body cannot carry the print there
    (an audit's fuzz: a sole on a 1.2e4 Pa mat read "print unreachable"). A rigid print,
    or one held back by a collision, is unreached."""
    row = np.array([[1.0, 0.0, 0.0]])
    blocks = [equality("placement", np.array([0.3]), row, 1.0, [placement]),
              equality("other", np.array([0.1]), row, 1.0, [other])]
    linearization = Linearization(0.0, np.zeros(3), np.eye(3), blocks, -np.ones(3), np.ones(3), np.zeros((0, 3)),
                                  np.zeros(0))
    reason = sqp._reason(linearization, 7, "stalled", (placement, other))
    assert reason == f"{prefix}{placement} violated by 0.3 m or rad (stalled after 7 iterations)"


def test_a_soft_print_held_back_with_a_collision_in_the_way_is_unreached():
    """A collision among the rows no step meets together stands in the way first: the print
    is unreached (cbm.rejections then files it as a collision and suggests a finer grid)."""
    placement, strain = "placement of a on mat_b_top (z, elastic)", "strain bound (compression) of tet 7 of mat_b"
    row = np.array([[1.0, 0.0, 0.0]])
    blocks = [equality("placement", np.array([0.3]), row, 1.0, [placement]),
              equality("other", np.array([0.1]), row, 1.0, [strain])]
    linearization = Linearization(0.0, np.zeros(3), np.eye(3), blocks, -np.ones(3), np.ones(3), np.zeros((0, 3)),
                                  np.zeros(0))
    reason = sqp._reason(linearization, 7, "stalled", (placement, "collision between leg and mat_a", strain))
    assert reason.startswith("print unreachable: " + placement)


def below_a_kink(q, lam):
    """``|q_x| + 1/2 <= 0``: no point meets it, and its linearisation, exact on either
    side of ``q_x = 0``, is wrong across it, so every full step overshoots the kink."""
    return [
        ConstraintBlock(
            "kink", np.array([abs(q[0]) + 0.5]), np.array([[np.sign(q[0]), 0.0, 0.0]]), -np.inf, 0.0, 1.0,
            ("kink at q_x = 0",),
        )
    ]


def test_a_line_search_crawling_far_from_feasible_stops_with_its_reason():
    """From q_x = 0.005 each QP step (-0.3, the trust region) overshoots the kink: the
    line search cuts it to 1/32, then to 1/256 (the violation falls from 0.505 by
    less than 0.005), and the loop ends after stopping.CRAWL_STEPS such iterations with the
    violation still 0.5. Without the test it stalled after 7 iterations (four
    line searches finding no step, ten trial linearisations each)."""
    problem = ToyProblem(squared_distance_to(np.array([0.0, 0.3, 0.4])), below_a_kink)
    outcome = run_sqp(problem, np.array([0.005, 0.0, 0.0]), np.zeros(0), limit=100)
    assert not outcome.feasible
    assert outcome.status == stopping.NO_PROGRESS
    assert outcome.iterations == stopping.CRAWL_STEPS < 7
    assert abs(outcome.q[0]) < 0.005
    assert outcome.reason.startswith(
        "kink at q_x = 0 violated by 0.5 N (no progress toward feasibility: the line search cut 3 steps "
        f"in a row below 1/16 after {outcome.iterations} iterations)"
    )
    # The stop keeps no state between solves: the same input gives the same answer, bit for bit.
    again = run_sqp(problem, np.array([0.005, 0.0, 0.0]), np.zeros(0), limit=100)
    assert again.q.tobytes() == outcome.q.tobytes() and again.reason == outcome.reason


def test_a_creep_ends_the_loop_only_where_the_caller_has_a_fallback(monkeypatch):
    """run_sqp hands ``creep`` to its stopping test, reads it after every step taken, and
    ends with stopping.CREEPING when it fires (here at once, wherever it is on)."""
    problem = ToyProblem(squared_distance_to(np.array([0.0, 0.3, 0.4])), below_a_kink)
    monkeypatch.setattr(stopping.StoppingTest, "creeping", lambda self, violation, reached, alpha: self.creep)
    outcome = run_sqp(problem, np.array([0.005, 0.0, 0.0]), np.zeros(0), limit=100, creep=True)
    assert outcome.status == stopping.CREEPING and outcome.iterations == 1
    assert run_sqp(problem, np.array([0.005, 0.0, 0.0]), np.zeros(0), limit=100).status == stopping.NO_PROGRESS


def test_full_steps_that_leave_a_curved_row_are_corrected_back_onto_it(monkeypatch):
    """The Maratos effect: min 1/2 |q - (0, 3, 0)|^2 on the unit sphere from (1, 0, 0).
    Each QP step runs along the tangent (0.3, the trust region) and leaves the sphere by
    about |d|^2 = 0.09, which the merit (penalty 100) refuses although the objective
    falls: cut to 1/16 and restored, the SQP crept and stopped at its 60-iteration
    limit with the objective at 3.3 (optimum 2 at (0, 1, 0)). The second-order
    correction (the restoration step from the trial point) takes the steps whole. Near
    the optimum (Gauss-Newton contracts slowly here, its rate 2y > 1) a step is cut below
    1/16; the next ones are bounded by a tenth of its length, and the solve ends at the
    optimum (measured: 12 iterations, 2.000028; with the whole trust region the crawl rule
    stopped it after 9 at 2.0044)."""
    problem = ToyProblem(squared_distance_to(np.array([0.0, 3.0, 0.0])), on_the_sphere)
    start = np.array([1.0, 0.0, 0.0])
    outcome = run_sqp(problem, start, np.zeros(0), limit=60)
    assert outcome.feasible and outcome.iterations <= 12 and outcome.corrections >= 3
    assert outcome.linearization.objective < 2.0001
    monkeypatch.setattr(sqp, "_CORRECTION_PHASE", -1.0)  # no correction
    monkeypatch.setattr(sqp, "_CORRECTION_GROWTH", np.inf)
    crept = run_sqp(problem, start, np.zeros(0), limit=60)
    assert crept.iterations == 60 and crept.status == "iteration limit" and crept.corrections == 0
    assert crept.linearization.objective > 3.0


def test_a_full_step_that_doubles_a_small_violation_is_corrected(monkeypatch):
    """The same sphere from (1.02, 0, 0), 0.04 off it: above the correction phase (1e-2),
    below the torque-usage one (0.1). The first full step runs 0.3 along the tangent and
    leaves the sphere by 0.09, more than twice the violation it started from: corrected,
    it lands 0.002 off the sphere, taken whole. Without the correction the merit cut it
    to half (0.043 off), and the solve took 23 iterations instead of 9."""
    problem = ToyProblem(squared_distance_to(np.array([0.0, 3.0, 0.0])), on_the_sphere)
    start = np.array([1.02, 0.0, 0.0])
    first = run_sqp(problem, start, np.zeros(0), limit=1)
    assert first.corrections == 1 and first.linearization.max_violation()[0] < 0.01
    assert first.q[1] > 0.28  # about the whole 0.3 along the tangent
    outcome = run_sqp(problem, start, np.zeros(0), limit=60)
    assert outcome.feasible and outcome.iterations <= 12 and outcome.linearization.objective < 2.0001
    monkeypatch.setattr(sqp, "_CORRECTION_GROWTH", np.inf)  # the correction phase alone
    cut = run_sqp(problem, start, np.zeros(0), limit=1)
    assert cut.corrections == 0 and cut.linearization.max_violation()[0] > 0.04
    assert cut.q[1] == pytest.approx(0.15)  # the step halved
    assert run_sqp(problem, start, np.zeros(0), limit=60).iterations > 15


# A small sphere (radius 0.3) and a far target: near its closest point each QP step runs
# along the tangent and leaves the sphere at second order (found by random search).
SMALL_RADIUS = 0.3
SMALL_TARGET = np.array([-0.5839, 0.2164, -0.3533])
SMALL_START = np.array([0.29409485308260214, -0.027094620993184458, -0.052686800173842044])


def on_the_small_sphere(q, lam):
    return [equality("sphere", np.array([q @ q - SMALL_RADIUS**2]), 2.0 * q[None, :], 1.0, ["on the sphere"])]


def test_cut_steps_that_still_gain_are_not_a_crawl():
    """Near the closest point of the small sphere, each step is cut below 1/16 (its
    curvature takes it off the sphere) and a restoration step brings it back, yet the
    objective still falls, 0.1-0.3 % an iteration: the solve goes on. Counting such cuts
    as a crawl without their gain (as between c63f641 and this test) stopped it after 3
    iterations, 'converged' at 0.459 (optimum 0.087)."""
    problem = ToyProblem(squared_distance_to(SMALL_TARGET), on_the_small_sphere)
    outcome = run_sqp(problem, SMALL_START, np.zeros(0), limit=12)
    assert outcome.feasible
    assert outcome.iterations == 12 and outcome.status == "iteration limit"
    assert outcome.linearization.objective < 0.455


def test_after_a_crawl_the_steps_are_bounded_and_the_solve_reaches_the_optimum(monkeypatch):
    """The small sphere of the test above, solved to the end. Its QP steps run along the
    tangent, off the sphere at second order, and are cut below 1/16. With the whole trust
    region every QP went back to the same far point: the line search crawled and the solve
    stopped, 'converged', 17 % above the optimum (29 iterations, 0.1009 against 0.0865).
    Bounded by a tenth of the cut step's length after each crawl, the steps stay where the
    model holds: within 0.5 % of the optimum (24 iterations, measured 0.0868)."""
    optimum = 0.5 * (np.linalg.norm(SMALL_TARGET) - SMALL_RADIUS) ** 2
    problem = ToyProblem(squared_distance_to(SMALL_TARGET), on_the_small_sphere)
    bounded = run_sqp(problem, SMALL_START, np.zeros(0), limit=100)
    assert bounded.feasible and bounded.status == "converged"
    assert bounded.linearization.objective < 1.005 * optimum
    monkeypatch.setattr(sqp, "_CRAWL_REGION", np.inf)  # the whole trust region at every step
    whole = run_sqp(problem, SMALL_START, np.zeros(0), limit=100)
    assert whole.feasible and whole.status == "converged"
    assert whole.linearization.objective > 1.1 * optimum


def test_a_qp_without_a_finite_answer_ends_the_solve_as_infeasible(monkeypatch):
    """A QP answer with NaN (proxsuite diverging at a huge penalty) is no step: the
    iterate is returned as an infeasible answer, not passed to the next linearisation."""
    problem = ToyProblem(squared_distance_to(INFEASIBLE_TARGET), contradicting_rows)
    solve = QPWorkspace.solve
    calls = []

    def diverging(self, *matrices, **settings):
        calls.append(1)
        x = solve(self, *matrices, **settings)
        return x if len(calls) < 3 else np.full_like(x, np.nan)

    monkeypatch.setattr(QPWorkspace, "solve", diverging)
    start = np.zeros(3)
    outcome = run_sqp(problem, start, np.zeros(0), limit=100)
    assert not outcome.feasible and outcome.status == sqp.QP_FAILED
    assert np.all(np.isfinite(outcome.q))
    assert "(the QP solver returned no finite step after 3 iterations)" in outcome.reason


def _cycling_problem(feasible_until=np.inf):
    """A flat objective, 1 +- 2e-6 as q_x steps by 0.01 (each value within 1e-5 of the
    others), whose reported gradient always asks for a step; the row ``q_x <=
    feasible_until`` turns infeasible past it. The line search is replaced by steps
    of +0.01 in q_x: what a solve cycling across a print node's mode switch sees."""

    def objective(q, lam):
        value = 1.0 + 2e-6 * np.cos(np.pi * round(q[0] / 0.01))
        return value, np.array([-1.0, 0.0, 0.0]), np.eye(3)

    def rows(q, lam):
        return [ConstraintBlock("bound", np.array([q[0]]), np.array([[1.0, 0.0, 0.0]]), -np.inf, feasible_until, 1.0,
                                ("q_x bound",))]

    return ToyProblem(objective, rows)


def _steps_of_one_hundredth(problem, q, lam, *args, **kwargs):
    q_next = q + np.array([0.01, 0.0, 0.0])
    return (q_next, lam, problem.linearize(q_next, lam)), 1.0, False


def test_feasible_iterates_that_no_step_improves_end_the_solve_at_the_best(monkeypatch):
    """Feasible iterates whose objective moves by 2e-6 without falling by 1e-5: after
    _NO_GAIN_ITERATIONS iterations without a better one the SQP stops, converged, at
    the first (the best) of them, instead of running to its iteration limit."""
    monkeypatch.setattr(sqp, "_line_search", _steps_of_one_hundredth)
    outcome = run_sqp(_cycling_problem(), np.zeros(3), np.zeros(0), limit=100)
    assert outcome.feasible and outcome.status == "converged"
    assert outcome.iterations == 1 + stopping.NO_GAIN_ITERATIONS
    assert outcome.q[0] == pytest.approx(0.01, abs=1e-12)  # the first accepted iterate, objective 1 - 2e-6
    assert outcome.linearization.objective == pytest.approx(1.0 - 2e-6, abs=1e-12)


@pytest.mark.parametrize("gain, stops", [(1e-4, True), (1e-3, False)])
def test_feasible_iterates_that_gain_too_slowly_end_the_solve(monkeypatch, gain, stops):
    """Feasible steps each better by ``gain`` (so never 'no gain'): gaining under 0.1 % of
    the objective over _SLOW_GAIN_ITERATIONS iterations (1e-4 a step: 4e-4 over four,
    against 2e-3) ends the solve at the best iterate; 1e-3 a step goes on to the limit."""

    def objective(q, lam):
        return 1.0 - gain * round(q[0] / 0.01), np.array([-1.0, 0.0, 0.0]), np.eye(3)

    monkeypatch.setattr(sqp, "_line_search", _steps_of_one_hundredth)
    outcome = run_sqp(ToyProblem(objective, lambda q, lam: []), np.zeros(3), np.zeros(0), limit=20)
    assert outcome.feasible
    if stops:
        assert outcome.status == "converged" and outcome.iterations == stopping.SLOW_GAIN_ITERATIONS + 1
        assert outcome.q[0] == pytest.approx(0.01 * (stopping.SLOW_GAIN_ITERATIONS + 1), abs=1e-12)  # the last is the best
    else:
        assert outcome.status == "iteration limit" and outcome.iterations == 20


def test_an_infeasible_last_iterate_gives_way_to_the_best_feasible_one(monkeypatch):
    """At the iteration limit on an infeasible iterate, the best feasible one seen is the answer."""
    monkeypatch.setattr(sqp, "_line_search", _steps_of_one_hundredth)
    outcome = run_sqp(_cycling_problem(feasible_until=0.025), np.zeros(3), np.zeros(0), limit=3)
    assert outcome.iterations == 3 and outcome.feasible and outcome.reason == ""
    assert outcome.q[0] == pytest.approx(0.01, abs=1e-12)


def test_a_step_held_by_the_trust_region_does_not_raise_the_penalty(monkeypatch):
    """The row q_x = 2 lies seven trust regions (0.3) from the start: each QP meets what
    it can and leaves the rest to the elastic variable, which no penalty can remove.
    The penalty stays at its first value (raising it made the palm stances' QPs take
    60-165 proxsuite iterations instead of 7-80) and the solve still walks there."""
    penalties = []
    qp = sqp.elastic_qp

    def recording(linearization, penalty, **options):
        penalties.append(penalty)
        return qp(linearization, penalty, **options)

    monkeypatch.setattr(sqp, "elastic_qp", recording)

    def at_two(q, lam):
        return [equality("x", np.array([q[0] - 2.0]), np.array([[1.0, 0.0, 0.0]]), 1.0, ["q_x at 2"])]

    problem = ToyProblem(squared_distance_to(np.zeros(3)), at_two)
    outcome = run_sqp(problem, np.zeros(3), np.zeros(0), limit=30)
    assert outcome.feasible and outcome.status == "converged"
    np.testing.assert_allclose(outcome.q, [2.0, 0.0, 0.0], atol=1e-8)
    assert set(penalties) == {problem.options.elastic_penalty}
    assert len(penalties) <= 10  # ceil(2 / 0.3) = 7 steps to get there


class _CountingTrials(ToyProblem):
    """A toy problem that counts the linearisations and evaluations the SQP asks for."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.trials = 0

    def evaluate(self, q, lam, torque_weight=None):
        self.trials += 1
        return ToyProblem.linearize(self, q, lam, torque_weight)  # (ToyProblem.evaluate would count twice)

    def linearize(self, q, lam, torque_weight=None):
        self.trials += 1
        return super().linearize(q, lam, torque_weight)


def test_a_marginal_step_the_objective_refuses_ends_the_solve_without_backtracking():
    """At a feasible point the reported gradient (3e-3) asks for a step predicted to gain
    4.5e-6 of an objective that does not move: the full step is tried once, refused,
    and the solve ends there, converged (the line search used to cut it ten times,
    a contact solve each on a soft stance)."""

    def flat(q, lam):
        return 1.0, np.array([-3e-3, 0.0, 0.0]), np.eye(3)

    problem = _CountingTrials(flat, lambda q, lam: [])
    outcome = run_sqp(problem, np.zeros(3), np.zeros(0), limit=30)
    assert outcome.feasible and outcome.status == "converged"
    assert outcome.iterations == 1
    assert problem.trials == 2  # the start's linearisation and the refused full step
    assert np.all(outcome.q == 0.0)


@pytest.mark.parametrize("slope, lengths", [(0.1, 10), (0.05, 5)], ids=["full-depth", "minor-gain"])
def test_a_feasible_iterate_whose_line_search_finds_no_step_ends_at_once(slope, lengths):
    """At a feasible point the gradient asks for a step predicted to gain 5e-3, which the
    flat objective never gives: the line search tries ten lengths and finds none. Nothing
    the next iteration reads changes (the penalty stays, no curvature), so the solve ends
    there, converged, rather than repeating that search three more times (41 trials).
    At a slope of 0.05 the step is predicted to gain 1.25e-3, 6e-4 of the objective
    (under stopping.MINOR_GAIN, above stopping.PREDICTED_GAIN): the line search tries lengths down to 1/16
    only, five trials instead of ten (each a contact solve per soft print; hand-on-cube's
    Coulomb stage cut such steps to 1/128 and 1/512, 30 of its 200 ms)."""

    def flat(q, lam):
        return 1.0, np.array([-slope, 0.0, 0.0]), np.eye(3)

    problem = _CountingTrials(flat, lambda q, lam: [])
    outcome = run_sqp(problem, np.zeros(3), np.zeros(0), limit=30)
    assert outcome.feasible and outcome.status == "converged"
    assert outcome.iterations == 1 and np.all(outcome.q == 0.0)
    assert problem.trials == 1 + lengths  # the start, then lengths 1, 1/2, ..., down to 1/512 or 1/16


def _a_row_with_a_rounding_floor(q, lam):
    """``q_x = 2`` read with a jump of 3e-7 across it (scale 1): no point meets it within
    1.5e-7, though its Jacobian (1) says a step does, as a stiff print's rows read through
    rounding."""
    value = q[0] - 2.0 + (1.5e-7 if q[0] >= 2.0 else -1.5e-7)
    return [equality("x", np.array([value]), np.array([[1.0, 0.0, 0.0]]), 1.0, ["q_x at 2"])]


def test_a_failed_line_search_at_a_rounding_floor_ends_the_solve(monkeypatch):
    """1.5 tolerances from feasible, the QP meets its linearised row, no step length nor
    the restoration gets below the floor: the solve ends at the first failed search (its
    iterate goes to verify), instead of raising the penalty search after search (to its
    1e8 cap, ten trials a search)."""

    def flat(q, lam):
        return 0.0, np.zeros(3), np.eye(3)

    start = np.array([2.01, 0.0, 0.0])
    problem = _CountingTrials(flat, _a_row_with_a_rounding_floor)
    outcome = run_sqp(problem, start, np.zeros(0), limit=30)
    assert outcome.status == "stalled" and not outcome.feasible
    assert 1.5e-7 <= outcome.linearization.max_violation()[0] < 3e-7
    assert outcome.penalty == problem.options.elastic_penalty
    monkeypatch.setattr(stopping, "ROUNDING_FLOOR", -1.0)
    # Without the floor, failed searches that do not halve the violation end it
    # (stopping.LINGER_ITERATIONS)...
    lingering = run_sqp(_CountingTrials(flat, _a_row_with_a_rounding_floor), start, np.zeros(0), limit=30)
    # (two steps to 1.5e-7, then four cut or failed)
    assert lingering.status == stopping.LINGERING and lingering.iterations == 2 + stopping.LINGER_ITERATIONS
    assert lingering.penalty < 1e8 and not lingering.feasible
    # ... and without that either, the penalty climbs to its cap.
    monkeypatch.setattr(stopping, "LINGER_ITERATIONS", 1000)
    longer = _CountingTrials(flat, _a_row_with_a_rounding_floor)
    raised = run_sqp(longer, start, np.zeros(0), limit=30)
    assert raised.status == "stalled" and raised.penalty == 1e8
    assert raised.iterations > outcome.iterations and longer.trials > problem.trials + 25


def test_a_rounding_floor_is_absolute_not_relative_to_a_loose_tolerance():
    """The same row with a floor of 5e-3 at a warm start's tolerance of 1e-3: violations
    that far up are not rounding, and a warm start is not verified: the penalty is
    raised as before, the stop does not fire."""

    def far_floor(q, lam):
        value = q[0] - 2.0 + (5e-3 if q[0] >= 2.0 else -5e-3)
        return [equality("x", np.array([value]), np.array([[1.0, 0.0, 0.0]]), 1.0, ["q_x at 2"])]

    problem = ToyProblem(lambda q, lam: (0.0, np.zeros(3), np.eye(3)), far_floor)
    problem.options = replace(problem.options, feasibility_tolerance=1e-3)
    outcome = run_sqp(problem, np.array([2.01, 0.0, 0.0]), np.zeros(0), limit=30)
    assert outcome.penalty > problem.options.elastic_penalty


def test_failed_line_searches_far_from_feasible_are_left_to_the_crawl_stop(monkeypatch):
    """Far from feasible (contradicting rows: a restoration step takes the violation from 1
    to its floor of 1/2) at the largest penalty, a failed line search changes nothing
    either, but the solve goes on to the crawl stop, which ends it with its own reason
    after stopping.CRAWL_STEPS failures in a row (what _solve_coulomb reads as a stance that
    cannot be held), not as "stalled" at the first."""
    monkeypatch.setattr(sqp, "_line_search", lambda *args, **kwargs: (None, 2.0**-10, False))
    problem = ToyProblem(squared_distance_to(INFEASIBLE_TARGET), contradicting_rows)
    problem.options = replace(problem.options, elastic_penalty=sqp._MAX_PENALTY)
    outcome = run_sqp(problem, np.zeros(3), np.zeros(0), limit=100)
    assert not outcome.feasible
    assert outcome.status == stopping.NO_PROGRESS and outcome.iterations > stopping.CRAWL_STEPS


def test_a_feasible_step_cut_short_for_nothing_ends_the_solve(monkeypatch):
    """From a feasible point a step cut to 1/256 that gains 1.2e-6 of the objective (more
    than the optimality tolerance, 1e-7, less than a crawl's 1.25e-4):
    the QP's model is wrong there, and the solve ends at once (it used to repeat the
    same cut step until three of them in a row)."""

    def slope(q, lam):
        return 1.0 - 1e-3 * q[0], np.array([-1.0, 0.0, 0.0]), np.eye(3)

    def cut(problem, q, lam, step, *args, **kwargs):
        q_next = q + step[:3] / 256.0
        return (q_next, lam, problem.linearize(q_next, lam)), 1.0 / 256.0, False

    monkeypatch.setattr(sqp, "_line_search", cut)
    outcome = run_sqp(ToyProblem(slope, lambda q, lam: []), np.zeros(3), np.zeros(0), limit=30)
    assert outcome.feasible and outcome.status == "converged"
    assert outcome.iterations == 1
    assert outcome.q[0] == pytest.approx(0.3 / 256.0, rel=1e-6)


def test_a_cut_step_back_to_feasibility_that_beats_the_best_by_nothing_ends_the_solve(monkeypatch):
    """A feasible iterate (the best), then a step cut to 1/512 that leaves q_y <= 0 by
    1e-6, then another cut step back onto it, 2e-6 better than the best: the solve ends
    there (a two-sole turn stance on a mat cycled so: a lean cut to 1/512, restored,
    three times, ten contact solves a line search). Counting them as a crawl needed
    three such iterations in a row, each ending feasible."""
    script = [((0.001, 0.0, 0.0), 1.0), ((0.002, 1e-6, 0.0), 1.0 / 512.0), ((0.003, 0.0, 0.0), 1.0 / 512.0),
              ((0.004, 0.0, 0.0), 1.0 / 512.0), ((0.005, 0.0, 0.0), 1.0 / 512.0)]

    outcome = _run_scripted(monkeypatch, script)
    assert outcome.feasible and outcome.status == "converged"
    assert outcome.iterations == 3
    np.testing.assert_array_equal(outcome.q, [0.003, 0.0, 0.0])


def test_a_cut_step_at_the_trust_region_restored_still_raises_the_penalty(monkeypatch):
    """The step toward q_x = 2 is at the trust region but the line search cuts it to
    1/32 and a restoration step replaces it: that says the QP's model is off, not that
    the step was too short, so the penalty rises as it always did (an infeasible
    quadruped stance stops early through it)."""
    penalties = []
    qp = sqp.elastic_qp

    def recording(linearization, penalty, **options):
        penalties.append(penalty)
        return qp(linearization, penalty, **options)

    def cut(problem, q, lam, step, *args, **kwargs):
        q_next = q + step[:3] / 32.0
        return (q_next, lam, problem.linearize(q_next, lam)), 1.0 / 32.0, False

    def restored(problem, linearization, q, lam, workspace, torque_weight):
        q_next = q + np.array([0.1, 0.0, 0.0])
        return q_next, lam, problem.linearize(q_next, lam)

    def at_two(q, lam):
        return [equality("x", np.array([q[0] - 2.0]), np.array([[1.0, 0.0, 0.0]]), 1.0, ["q_x at 2"])]

    monkeypatch.setattr(sqp, "elastic_qp", recording)
    monkeypatch.setattr(sqp, "_line_search", cut)
    monkeypatch.setattr(sqp, "_restoration", restored)
    run_sqp(ToyProblem(squared_distance_to(np.zeros(3)), at_two), np.zeros(3), np.zeros(0), limit=2)
    assert penalties[:2] == [100.0, 1000.0]  # (then the reason's conflict QP)


def test_a_crawl_stop_after_a_worse_restoration_returns_the_best_feasible_iterate(monkeypatch):
    """As the cycle above, but the step back onto q_y <= 0 lands 8e-6 above the best
    feasible objective (restoration ignores the objective): the solve ends there, at
    the best feasible iterate, not at the worse one it stopped on."""
    script = [((0.01, 0.0, 0.0), 1.0), ((0.02, 1e-6, 0.0), 1.0 / 512.0), ((0.002, 0.0, 0.0), 1.0 / 512.0)]

    outcome = _run_scripted(monkeypatch, script)
    assert outcome.feasible and outcome.status == "converged" and outcome.iterations == 3
    np.testing.assert_array_equal(outcome.q, [0.01, 0.0, 0.0])
    assert outcome.linearization.objective == pytest.approx(1.0 - 1e-5, abs=1e-15)


class _UsageToy(ToyProblem):
    """A toy whose objective has a 'torque usage' term, 0.1 (q_y - 1)^2, that joins once the
    iterate is within _USAGE_PHASE of feasible, as the posture problem's does."""

    def __init__(self, rows):
        super().__init__(squared_distance_to(np.zeros(3)), rows)
        self.options = PostureOptions(torque_weight=0.1, constraint_curvature=False)

    def linearize(self, q, lam, torque_weight=None):
        base = super().linearize(q, lam)
        weight = torque_weight or 0.0
        gradient = base.gradient + np.array([0.0, 2.0 * weight * (q[1] - 1.0), 0.0])
        hessian = base.hessian + np.diag([0.0, 2.0 * weight, 0.0])
        return replace(base, objective=base.objective + weight * (q[1] - 1.0) ** 2, gradient=gradient, hessian=hessian)


def test_the_best_feasible_iterate_is_forgotten_when_the_usage_term_joins(monkeypatch):
    """A feasible iterate reached in one step from a violation of 0.2 is the best one so
    far, its objective without the usage term; once the term joins, every objective is
    larger, and measured against that best a cut step that still gains 6 % would end the
    solve. The best is forgotten at the switch: the cut step is just a step."""
    script = [((0.8, 0.0, 0.0), 1.0), ((0.8, 0.2, 0.0), 1.0 / 32.0), ((0.8, 0.4, 0.0), 1.0), ((0.8, 0.6, 0.0), 1.0)]

    def scripted(problem, q, lam, step, linearization, violation, penalty, predicted, torque_weight, **kwargs):
        point, alpha = script.pop(0)
        q_next = np.array(point)
        return (q_next, lam, problem.linearize(q_next, lam, torque_weight)), alpha, False

    def at_most(q, lam):
        return [ConstraintBlock("x", np.array([q[0]]), np.array([[1.0, 0.0, 0.0]]), 0.8, np.inf, 1.0, ("q_x >= 0.8",))]

    monkeypatch.setattr(sqp, "_line_search", scripted)
    outcome = run_sqp(_UsageToy(at_most), np.array([0.6, 0.0, 0.0]), np.zeros(0), limit=4)
    assert outcome.iterations == 4 and outcome.q[1] == pytest.approx(0.6)


def _run_scripted(monkeypatch, script):
    """run_sqp on ``min 1 - 1e-3 q_x`` with ``q_y <= 0``, its line search replaced by the
    ``(point, alpha)`` steps of ``script`` in turn and no restoration."""

    def scripted(problem, q, lam, *args, **kwargs):
        point, alpha = script.pop(0)
        q_next = np.array(point)
        return (q_next, lam, problem.linearize(q_next, lam)), alpha, False

    def slope(q, lam):
        return 1.0 - 1e-3 * q[0], np.array([-1.0, 0.0, 0.0]), np.eye(3)

    def below(q, lam):
        return [ConstraintBlock("y", np.array([q[1]]), np.array([[0.0, 1.0, 0.0]]), -np.inf, 0.0, 1.0, ("q_y <= 0",))]

    monkeypatch.setattr(sqp, "_line_search", scripted)
    monkeypatch.setattr(sqp, "_restoration", lambda *args: None)
    return run_sqp(ToyProblem(slope, below), np.zeros(3), np.zeros(0), limit=30)


def test_a_restoration_step_is_the_shortest_step_onto_compatible_rows_and_relaxes_contradicting_ones():
    """sqp.restoration_step from (0.4, 0, 0): onto q_x + q_y = 0.5, the shortest step
    (solved without the elastic variable: the rows are compatible within the trust
    region), to (0.45, 0.05, 0); onto q_x = 0 and q_x = 1, which no step meets, the
    elastic QP's least violation, q_x = 1/2."""

    def one_row(q, lam):
        return [equality("sum", np.array([q[0] + q[1] - 0.5]), np.array([[1.0, 1.0, 0.0]]), 1.0, ["q_x + q_y = 0.5"])]

    start = np.array([0.4, 0.0, 0.0])
    for rows, expected in ((one_row, [0.45, 0.05, 0.0]), (contradicting_rows, [0.5, 0.0, 0.0])):
        problem = ToyProblem(squared_distance_to(INFEASIBLE_TARGET), rows)
        workspace = QPWorkspace()
        q, _ = sqp.restoration_step(problem, problem.linearize(start, np.zeros(0)), start, np.zeros(0), workspace)
        np.testing.assert_allclose(q, expected, atol=1e-6)
        assert workspace.solved


class _HeldModesContact:
    """A soft contact whose nodes read the same modes wherever the solve stops."""

    kind = "deformable"

    def __init__(self):
        self.frozen = 0
        self.released = 0

    def freeze_modes(self, model, data, w):
        self.frozen += 1
        return np.array([0, 1, 2])

    def release_modes(self):
        self.released += 1


def _held_modes_problem():
    """A stand-in problem with one soft contact of :class:`_HeldModesContact`."""
    model = point_model()
    problem = type("Problem", (), {})()
    problem.robot = PointRobot(model)
    problem.contacts = [_HeldModesContact()]
    problem.variable_slices = [slice(0, 2)]
    problem.data = pin.Data(model)
    problem.initial_variables = lambda q: np.zeros(2)
    problem.check_configuration = lambda q: np.asarray(q, dtype=float)
    return problem


def _scripted_stages(monkeypatch, attempt_status):
    """Replace stages.solve_problem by stages that stall near feasibility (a held-mode attempt
    ending with ``attempt_status``), each moving q by 0.01; returns the list of the stages'
    iteration caps it fills."""
    from stances.results import PostureResult

    calls = []

    def stage(problem, q, lam_init=None, max_iterations=None, deadline=None, check=True, creep=False):
        # Only the first stage, which the held-mode attempts can replace, may end creeping.
        assert creep == (max_iterations == stages._FREE_ITERATIONS)
        calls.append(max_iterations)
        status = attempt_status if max_iterations == stages._FROZEN_ITERATIONS else "stalled"
        return PostureResult(
            feasible=False, q=np.asarray(q, dtype=float) + 0.01, point_forces=(), torques=np.zeros(0), iterations=5,
            solve_time=0.0, stance=None, statistics={"status": status, "violation": 2.8e-7}, reason=status,
        )

    monkeypatch.setattr(stages, "solve_problem", stage)
    return calls


def test_held_mode_attempts_stop_when_the_modes_to_hold_are_those_just_held(monkeypatch):
    """A Coulomb solve whose first stage stalls near feasibility, and whose held-mode
    attempt stalls too where the nodes read the modes it held: a second attempt would hold
    them again from there (measured: three identical attempts of 27 iterations on a palm
    stance of rail-over-gap, and the final free stage after them the same 27). One attempt
    is made, and it is the answer: the contact set has settled."""
    problem = _held_modes_problem()
    contact = problem.contacts[0]
    calls = _scripted_stages(monkeypatch, "stalled")
    result = stages._solve_coulomb(problem, np.zeros(3))
    assert calls == [stages._FREE_ITERATIONS, stages._FROZEN_ITERATIONS]
    assert contact.frozen == 2  # the second freeze finds the same modes: no second attempt
    assert contact.released == 2  # every freeze released, the early return's too
    # The attempt's answer: from the first stage's q (0.01), one stage further.
    np.testing.assert_allclose(result.q, 0.02)
    assert result.iterations == 10 and not result.feasible and result.reason == "stalled"


def test_a_first_stage_creeping_far_from_feasible_gives_way_to_held_modes_from_the_start(monkeypatch):
    """The first (free-mode) Coulomb stage ends creeping far from feasible (a quadruped
    planner stance on foam: 25 iterations cut to 1/8-1/2 from 0.28 to 0.10, 0.7 s): the
    held-mode attempts follow, from where the solve started, not from the creep's end."""
    from stances.results import PostureResult

    problem = _held_modes_problem()
    starts = []

    def stage(problem, q, lam_init=None, max_iterations=None, deadline=None, check=True, creep=False):
        starts.append((max_iterations, creep, float(np.asarray(q)[0])))
        first = max_iterations == stages._FREE_ITERATIONS
        return PostureResult(
            feasible=not first, q=np.asarray(q, dtype=float) + 0.01, point_forces=(), torques=np.zeros(0),
            iterations=7, solve_time=0.0, stance=None,
            statistics={"status": stopping.CREEPING if first else "converged", "violation": 0.1 if first else 0.0},
            reason=stopping.CREEPING if first else "",
        )

    monkeypatch.setattr(stages, "solve_problem", stage)
    result = stages._solve_coulomb(problem, np.zeros(3))
    assert starts == [(stages._FREE_ITERATIONS, True, 0.0), (stages._FROZEN_ITERATIONS, False, 0.0)]
    assert result.feasible and result.iterations == 14
    np.testing.assert_allclose(result.q, 0.01)


def test_a_held_mode_attempt_its_cap_ended_goes_on_free(monkeypatch):
    """The same, but the held-mode attempt ran to its iteration cap, still moving: not a
    stall, so the uncapped free stage runs from where the attempts began."""
    problem = _held_modes_problem()
    calls = _scripted_stages(monkeypatch, "iteration limit")
    result = stages._solve_coulomb(problem, np.zeros(3))
    assert calls == [stages._FREE_ITERATIONS, stages._FROZEN_ITERATIONS, None]
    np.testing.assert_allclose(result.q, 0.02)  # the free stage from the first stage's q
    assert result.iterations == 15 and result.reason == "stalled"


def test_attempts_from_the_start_that_never_settle_give_way_to_the_first_stage_with_its_own_loads(monkeypatch):
    """The first Coulomb stage ends early far from feasible (the held-mode attempts begin
    from the start, with the start's loads), and every attempt stalls near feasibility in
    modes other than those it held: the last, uncapped free stage goes on from where the
    first stage stopped, with its contact variables (W read off that posture would leave
    every print lifting off with no force: a palm leaning on its centre-of-pressure rows
    stalled 100 N short of a normal-load bound, a new user's audit)."""
    from stances.results import PostureResult

    problem = _held_modes_problem()
    contact = problem.contacts[0]
    modes = iter(range(100))
    contact.freeze_modes = lambda model, data, w: np.array([next(modes)])  # never the same twice
    starts, loads = [], np.array([3.0, 4.0])

    def stage(problem, q, lam_init=None, max_iterations=None, deadline=None, check=True, creep=False):
        starts.append((max_iterations, float(np.asarray(q)[0]), None if lam_init is None else tuple(lam_init)))
        first, last = max_iterations == stages._FREE_ITERATIONS, max_iterations is None
        return PostureResult(
            feasible=last, q=np.asarray(q, dtype=float) + 0.01, point_forces=(), torques=np.zeros(0), iterations=5,
            solve_time=0.0, stance=None,
            statistics={"status": "converged" if last else stopping.NO_PROGRESS,
                        "violation": 0.0 if last else (0.5 if first else 1e-4), "lambda": loads if first else np.zeros(2)},
            reason="" if last else stopping.NO_PROGRESS,
        )

    monkeypatch.setattr(stages, "solve_problem", stage)
    start_loads = np.array([1.0, 2.0])
    result = stages._solve_coulomb(problem, np.zeros(3), lam_init=start_loads)
    frozen = stages._FROZEN_ITERATIONS
    # The attempts: from the start with the start's loads, then each from the last one's end.
    assert starts == [(stages._FREE_ITERATIONS, 0.0, (1.0, 2.0)), (frozen, 0.0, (1.0, 2.0)), (frozen, 0.01, None),
                      (frozen, 0.02, None), (None, 0.01, (3.0, 4.0))]
    assert result.feasible and result.iterations == 25
    np.testing.assert_allclose(result.q, 0.02)
