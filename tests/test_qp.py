"""The SQP's elastic QP subproblem (stances.qp) on small problems with known answers."""

import numpy as np
import pytest

from stances.blocks import ConstraintBlock, equality
from stances.problem import Linearization
from stances.qp import QPWorkspace, elastic_qp, elastic_start, plain_qp, row_multipliers
from stances.qp_backend import proxsuite


def _linearization(blocks, n=2, bound=10.0):
    return Linearization(
        objective=0.0,
        gradient=np.zeros(n),
        hessian=np.eye(n),
        blocks=blocks,
        step_lower=np.full(n, -bound),
        step_upper=np.full(n, bound),
        forces=np.zeros((0, 3)),
        torques=np.zeros(6),
    )


def test_a_feasible_qp_gives_the_least_norm_step_and_no_elastic():
    """min 1/2 |x|^2 s.t. x0 + x1 = 1: x = (1/2, 1/2)."""
    row = equality("sum", np.array([-1.0]), np.array([[1.0, 1.0]]), 1.0, ["x0 + x1 = 1"])
    x = QPWorkspace().solve(*elastic_qp(_linearization([row]), penalty=100.0), accuracy=1e-9)
    assert np.allclose(x[:2], [0.5, 0.5], atol=1e-6)
    assert abs(x[2]) <= 1e-6


def test_the_plain_qp_of_compatible_rows_is_the_elastic_qps_answer_with_row_multipliers():
    """min 1/2 |x - (2, 1)|^2 s.t. x0 + x1 = 1 (violated at the iterate: value -1) and
    x0 <= 0.5 (scale 0.5), steps within 10: the plain QP (one row each, no elastic
    variable) gives the elastic QP's x = (0.5, 0.5), whose elastic is zero, and its
    multipliers, mapped to the rows, are stationarity's: (x - (2, 1)) + y_sum (1, 1) +
    y_cap (1, 0) = 0, y_sum = 0.5 and y_cap = 1."""
    lin = _linearization([
        equality("sum", np.array([-1.0]), np.array([[1.0, 1.0]]), 1.0, ["x0 + x1 = 1"]),
        ConstraintBlock("cap", np.zeros(1), np.array([[1.0, 0.0]]), -np.inf, 0.5, 0.5, ("x0 <= 0.5",)),
    ])
    lin.gradient[:] = [-2.0, -1.0]
    data = plain_qp(lin)
    assert data[2].shape == (2, 2)  # one QP row a row, no elastic column
    np.testing.assert_array_equal(data[3], [1.0, -1e20])  # the equality's bounds are equal
    np.testing.assert_array_equal(data[4], [1.0, 1.0])  # the cap's gap in its scale
    plain = QPWorkspace()
    x = plain.solve(*data, accuracy=1e-10)
    assert plain.solved
    relaxed = QPWorkspace()
    elastic = relaxed.solve(*elastic_qp(lin, penalty=1e4), accuracy=1e-10)
    np.testing.assert_allclose(x, [0.5, 0.5], atol=1e-6)
    np.testing.assert_allclose(x, elastic[:2], atol=1e-6)
    assert abs(elastic[2]) <= 1e-6
    multipliers = row_multipliers(lin, plain.multipliers, plain=True)
    assert multipliers["x0 + x1 = 1"] == pytest.approx(0.5, abs=1e-6)
    assert multipliers["x0 <= 0.5"] == pytest.approx(1.0, abs=1e-6)
    for label, value in row_multipliers(lin, relaxed.multipliers, penalty=1e4).items():
        assert value == pytest.approx(multipliers[label], abs=1e-5), label  # the elastic QP's, mapped its way


def test_the_plain_qp_of_conflicting_rows_is_not_solved():
    """x0 = 1 and x0 = -1: no step meets both; the plain QP says so (``solved`` False,
    within its iteration limit), where the elastic QP would relax them."""
    rows = [
        equality("a", np.array([-1.0]), np.array([[1.0, 0.0]]), 1.0, ["x0 = 1"]),
        equality("b", np.array([1.0]), np.array([[1.0, 0.0]]), 1.0, ["x0 = -1"]),
    ]
    workspace = QPWorkspace()
    workspace.solve(*plain_qp(_linearization(rows)), accuracy=1e-9, max_iterations=100)
    assert not workspace.solved
    assert workspace.iterations <= 100
    workspace.solve(*elastic_qp(_linearization(rows), penalty=1e4), accuracy=1e-9)
    assert workspace.solved


def test_conflicting_rows_are_met_halfway_and_the_elastic_says_by_how_much():
    """x0 = 1 and x0 = -1 cannot both hold: with a large penalty x0 = 0 and the
    elastic variable, in units of each row's scale, is 1 (scale 1) for both."""
    rows = [
        equality("a", np.array([-1.0]), np.array([[1.0, 0.0]]), 1.0, ["x0 = 1"]),
        equality("b", np.array([1.0]), np.array([[1.0, 0.0]]), 1.0, ["x0 = -1"]),
    ]
    x = QPWorkspace().solve(*elastic_qp(_linearization(rows), penalty=1e4), accuracy=1e-9)
    assert x[0] == pytest.approx(0.0, abs=1e-5)
    assert x[2] == pytest.approx(1.0, abs=1e-5)


def test_an_inequality_binds_only_when_it_must_and_scales_read_in_row_units():
    """min 1/2 |x - (2, 0)|^2 s.t. x0 <= 1 (scale 0.01) and x1 >= 3 (scale 1), steps
    within 2: x1 >= 3 cannot hold, the elastic is 1 (one scale of that row) and the
    same elastic relaxes the cap by one of its own scales, 0.01: x0 = 1.01."""
    lin = _linearization(
        [
            ConstraintBlock("cap", np.zeros(1), np.array([[1.0, 0.0]]), -np.inf, 1.0, 0.01, ("x0 <= 1",)),
            ConstraintBlock("floor", np.zeros(1), np.array([[0.0, 1.0]]), 3.0, np.inf, 1.0, ("x1 >= 3",)),
        ],
        bound=2.0,
    )
    lin.gradient[:] = [-2.0, 0.0]
    x = QPWorkspace().solve(*elastic_qp(lin, penalty=1e4), accuracy=1e-9)
    assert x[0] == pytest.approx(1.01, abs=1e-5)
    assert x[1] == pytest.approx(2.0, abs=1e-6)
    assert x[2] == pytest.approx(1.0, abs=1e-4)


def test_a_row_met_on_both_sides_is_one_held_row_and_a_violated_one_is_relaxed():
    """Two-sided rows -1 <= x0 <= 1 (met at the iterate: one QP row, no elastic term)
    and 2 <= x1 <= 3 (violated: two relaxed rows), with x1 <= 0 (one-sided: one relaxed
    row). x1's rows conflict: the elastic is 1 and x1 = 1. The objective pulls x0 to 5:
    x0 stays held at 1, where relaxed it would take the elastic's slack (x0 = 2). The
    held row's multiplier, mapped back, satisfies stationarity."""
    from stances.qp import row_multipliers

    lin = _linearization([
        ConstraintBlock("held", np.zeros(1), np.array([[1.0, 0.0]]), -1.0, 1.0, 1.0, ("x0 in [-1, 1]",)),
        ConstraintBlock("far", np.zeros(1), np.array([[0.0, 1.0]]), 2.0, 3.0, 1.0, ("x1 in [2, 3]",)),
        ConstraintBlock("cap", np.zeros(1), np.array([[0.0, 1.0]]), -np.inf, 0.0, 1.0, ("x1 <= 0",)),
    ])
    lin.gradient[:] = [-5.0, 0.0]
    _, _, inequality, lower, upper, _, _ = elastic_qp(lin, penalty=1e4)
    assert inequality.shape == (4, 3)  # far's and cap's upper rows, far's lower row, the held row
    np.testing.assert_array_equal(inequality[:, 2], [-1.0, -1.0, 1.0, 0.0])
    assert (lower[3], upper[3]) == (-1.0, 1.0)
    workspace = QPWorkspace()
    x = workspace.solve(*elastic_qp(lin, penalty=1e4), accuracy=1e-10)
    np.testing.assert_allclose(x, [1.0, 1.0, 1.0], atol=1e-6)
    multipliers = row_multipliers(lin, workspace.multipliers, penalty=1e4)
    assert multipliers["x0 in [-1, 1]"] == pytest.approx(4.0, abs=1e-5)  # H x + g + y = 1 - 5 + 4


def test_the_elastic_start_is_the_least_elastic_feasible_point_of_no_step_and_gives_the_same_answer():
    """Rows x1 in [2, 3] (violated by 2 below), x1 <= 0 (met), x0 in [-1, 1] (held) and
    x0 >= 0.5 (scale 0.25: violated by 2 scales) at the iterate: from x = 0 the elastic
    variable must cover 2 scales, no less, every QP row and bound then holds; proxsuite
    started there gives the answer it gives from x = 0."""
    lin = _linearization([
        ConstraintBlock("held", np.zeros(1), np.array([[1.0, 0.0]]), -1.0, 1.0, 1.0, ("x0 in [-1, 1]",)),
        ConstraintBlock("far", np.zeros(1), np.array([[0.0, 1.0]]), 2.0, 3.0, 1.0, ("x1 in [2, 3]",)),
        ConstraintBlock("cap", np.zeros(1), np.array([[0.0, 1.0]]), -np.inf, 0.0, 1.0, ("x1 <= 0",)),
        ConstraintBlock("half", np.zeros(1), np.array([[1.0, 0.0]]), 0.5, np.inf, 0.25, ("x0 >= 0.5",)),
    ])
    lin.gradient[:] = [-5.0, 0.0]
    data = elastic_qp(lin, penalty=1e4)
    _, _, inequality, lower, upper, box_lower, box_upper = data
    start = elastic_start(data)
    np.testing.assert_array_equal(start, [0.0, 0.0, 2.0])
    rows = inequality @ start
    assert np.all(rows >= lower) and np.all(rows <= upper)
    assert np.all(start >= box_lower) and np.all(start <= box_upper)
    less = start - [0.0, 0.0, 1e-9]
    assert np.any(inequality @ less < lower) or np.any(inequality @ less > upper)
    cold, warm = QPWorkspace(), QPWorkspace()
    x = cold.solve(*data, accuracy=1e-10)
    y = warm.solve(*data, accuracy=1e-10, start=start)
    assert cold.solved and warm.solved
    np.testing.assert_allclose(y, x, atol=1e-6)
    np.testing.assert_allclose(x, [1.0, 1.0, 1.0], atol=1e-6)  # x1's rows conflict: x1 = 1, elastic 1


def test_a_conflict_names_a_row_held_at_its_bound_too():
    """x0 <= 1 at its bound (a torque at its limit: a held row in the SQP's QP) against
    x0 >= 2 (equilibrium, violated): the reason's conflict QP relaxes both, and both
    share the elastic variable, 0.5 at x0 = 1.5, so both are named."""
    from stances.sqp import _conflict

    lin = _linearization([
        ConstraintBlock("torque", np.array([1.0]), np.array([[1.0, 0.0]]), -1.0, 1.0, 1.0, ("torque limit",)),
        ConstraintBlock("equilibrium", np.array([1.0]), np.array([[1.0, 0.0]]), 2.0, np.inf, 1.0, ("equilibrium",)),
    ])
    assert elastic_qp(lin, 100.0)[2].shape[0] == 2  # the SQP's QP: torque held, one row
    assert elastic_qp(lin, 100.0, hold=False)[2].shape[0] == 3
    assert _conflict(lin, 1e4) == ("equilibrium", "torque limit")


def test_a_warm_started_workspace_gives_the_cold_answer():
    row = equality("sum", np.array([-1.0]), np.array([[1.0, 2.0]]), 1.0, ["x0 + 2 x1 = 1"])
    workspace = QPWorkspace()
    workspace.warm_start = True  # the option (the library's policy is cold starts)
    workspace.solve(*elastic_qp(_linearization([row]), penalty=100.0), accuracy=1e-9)
    first = workspace.qp
    moved = equality("sum", np.array([-2.0]), np.array([[1.0, 2.0]]), 1.0, ["x0 + 2 x1 = 2"])
    warm = workspace.solve(*elastic_qp(_linearization([moved]), penalty=100.0), accuracy=1e-9)
    assert workspace.qp is first  # the same proxsuite object, started from its last answer
    assert first.settings.initial_guess == proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
    cold = QPWorkspace().solve(*elastic_qp(_linearization([moved]), penalty=100.0), accuracy=1e-9)
    assert np.allclose(warm, cold, atol=1e-6)
    assert np.allclose(warm[:2], [0.4, 0.8], atol=1e-6)


def test_a_large_penalty_divides_the_objective_and_changes_neither_answer_nor_multipliers():
    """At penalty 1e6 the QP's objective is divided by 1e4: the same step, and the
    multipliers, taken back to objective units, are those of the undivided QP."""
    from stances.qp import objective_scale, row_multipliers

    lin = _linearization([
        equality("sum", np.array([-1.0]), np.array([[1.0, 1.0]]), 1.0, ["x0 + x1 = 1"]),
        ConstraintBlock("cap", np.zeros(1), np.array([[1.0, 0.0]]), -np.inf, 0.2, 1.0, ("x0 <= 0.2",)),
    ])
    lin.gradient[:] = [0.3, -0.1]
    assert objective_scale(1e6) == 1e4 and objective_scale(1e5) == 1.0 and objective_scale(50.0) == 1.0
    divided = QPWorkspace()
    x = divided.solve(*elastic_qp(lin, penalty=1e6), accuracy=1e-12)
    hessian, gradient, *rest = elastic_qp(lin, penalty=1e6)
    whole = QPWorkspace()
    y = whole.solve(hessian * 1e4, gradient * 1e4, *rest, accuracy=1e-9)
    np.testing.assert_allclose(x, y, atol=1e-7)
    np.testing.assert_allclose(x[:2], [0.2, 0.8], atol=1e-7)  # feasible: no elastic
    scaled = row_multipliers(lin, divided.multipliers, penalty=1e6)
    unscaled = row_multipliers(lin, whole.multipliers, penalty=1e2)
    assert scaled.keys() == unscaled.keys()
    for label in scaled:
        assert scaled[label] == pytest.approx(unscaled[label], rel=1e-5, abs=1e-7)
    # Stationarity in objective units: H x + g + J^T y = 0 on the two rows.
    jacobian = np.array([[1.0, 1.0], [1.0, 0.0]])
    multipliers = np.array([scaled["x0 + x1 = 1"], scaled["x0 <= 0.2"]])
    np.testing.assert_allclose(x[:2] + lin.gradient + jacobian.T @ multipliers, 0.0, atol=1e-6)


def test_the_library_solves_every_qp_from_a_cold_start_with_a_small_first_proximal_weight():
    """A reused workspace answers a QP exactly as a fresh one does (nothing carried
    over), with proxsuite's first inequality weight at 1e-3."""
    rows = [
        equality("sum", np.array([-1.0]), np.array([[1.0, 2.0]]), 1.0, ["x0 + 2 x1 = 1"]),
        ConstraintBlock("cap", np.zeros(1), np.array([[1.0, 0.0]]), -np.inf, 0.2, 1.0, ("x0 <= 0.2",)),
    ]
    assert QPWorkspace.warm_start is False
    reused = QPWorkspace()
    other = [equality("sum", np.array([-3.0]), np.array([[1.0, 2.0]]), 1.0, ["x0 + 2 x1 = 3"]), rows[1]]
    reused.solve(*elastic_qp(_linearization(other), penalty=100.0), accuracy=1e-9)  # same shape
    again = reused.solve(*elastic_qp(_linearization(rows), penalty=100.0), accuracy=1e-9)
    fresh = QPWorkspace()
    once = fresh.solve(*elastic_qp(_linearization(rows), penalty=100.0), accuracy=1e-9)
    np.testing.assert_array_equal(again, once)
    np.testing.assert_array_equal(reused.multipliers, fresh.multipliers)
    assert reused.iterations == fresh.iterations
    assert reused.qp.settings.default_mu_in == 1e-3
    assert reused.qp.settings.initial_guess == proxsuite.proxqp.InitialGuess.NO_INITIAL_GUESS
