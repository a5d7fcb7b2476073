"""A posture solve's stages around the SQP (:mod:`stances.sqp`): :func:`solve`.

A stance on rigid supports is one SQP. On soft supports the FEM forces are meaningful
only near their prints, so a solve goes by stages:

1. the rigid warm start: the stance held rigid, to loose tolerances (and the cheap
   rejection of a stance that cannot be held even so);
2. the stiff limit (:func:`_solve_stiff_limit`): the bodies that give under 10 um held
   rigid where their nodes are, then the links' motion whose Coulomb forces carry that
   answer, or else the least-energy pressure under each face, verified; where it does not
   hold, nothing of it is kept (and where every soft
   body is that stiff and the stance is not held even rigid where their nodes reach, it is
   refused there);
3. the Coulomb stages (:func:`_solve_coulomb`): the nodes' modes read at every
   linearisation, then held while the SQP converges, then read again; a bonded warm
   start where that stalls near feasibility.

A time budget bounds them all; the answer says which stage it came from.
"""

from __future__ import annotations

import logging
import time
from dataclasses import fields, replace

import numpy as np
import pinocchio as pin

from fem.deadline import SetupTimeout, deadline as setup_deadline
from fem.errors import ContactStateError

from .cold_start import initial_configuration, starting_configuration
from .deformable import STIFF_GIVE
from .errors import ConfigurationError, StanceError
from .problem import PostureOptions, build_problem
from .qp import QPWorkspace
from .results import PointForce, PostureResult
from .sqp import (OUT_OF_TIME, QP_FAILED, SqpOutcome, deformation_fields, posture_result, problem_held_slips,
                  restoration_step, solve_problem, verify_shown)
from .statics import points_in_world
from .stopping import NEARLY_FEASIBLE, NO_PROGRESS, ROUNDING_FLOOR, STALLED
from .verify import VerificationTolerances

logger = logging.getLogger(__name__)

_FROZEN_ITERATIONS = 30  # per attempt with the prints' contact sets held (it converges in a few)
_FREE_ITERATIONS = 25  # first Coulomb stage, modes read at every linearisation (isotropic slip: hand-on-soft-cube needs 18; at 15 it fell to held-mode attempts, 69 iterations)
_CONTACT_SET_VIOLATION = 1e-2  # scaled violation beyond which a Coulomb solve is not retried
# ... unless its first stage stopped within this many iterations: its start failed it, not
# the stance (hand-on-coarse-cube's palm at mu = 3-7, modes read at every step from the
# rigid answer's loads: no progress after 4-5 iterations at a violation of 1; with the
# modes held from the same start, solved in 16-23).
_EARLY_STOP = 8
# Warm starts give starting postures only: feasible within 1e-2 (scaled: 0.1 mm and 0.1 mrad
# of placement, 0.1 N of equilibrium, where a soft print then sinks millimetres), and done
# once an iteration gains under 1 % of the objective. At 1e-5 the rigid warm start spent
# its last 1-2 iterations confirming an objective the Coulomb stage then changes anyway
# (plans on five soft suite scenes x 3 seeds, the same solver calls and stances, 5-6 % less
# CPU at 1e-3); from 1e-3 to 1e-2 the 15 built-in soft stances took 14 warm-start
# iterations fewer and 2 Coulomb iterations more (206 -> 194), all verified, -2.0 % of
# their instructions. The early rejection of a stance that cannot be held rigid reads the
# same tolerance: a rigid warm start stopping between 1e-3 and 1e-2 now goes on to the soft
# solve (the suite's 200 plans as at b71a919 but one, whose path had moved by 85fe6b3).
_WARM_START_TOLERANCES = {"feasibility_tolerance": 1e-2, "optimality_tolerance": 1e-2}
# A warm start's iteration cap (the options' max_iterations where lower). Of 906 rigid warm
# starts in the plans of 16 soft scenes x 10 seeds (2026-12-04), every one that reached its
# loose tolerance did so within 39 iterations; the two that ran to the options' cap of 100
# crept there at 1 % an iteration at the 0.3 trust region (quadruped-foam seeds 6 and 10,
# 1.0 and 1.3 s), each then rejected as a stance that cannot be held rigid. The bonded warm
# start (after a Coulomb solve that failed near feasibility) has the same cap: none ran in
# those plans, so it is not measured.
_WARM_START_ITERATIONS = 60
# A soft body that gives less than STIFF_GIVE under a stance's loads is solved in its stiff
# limit (_solve_stiff_limit; stances.deformable says why that give).
_STIFF_SHARE = 0.5  # of a solve's time left (its time budget's), at most
# The held prints tried in turn, loosest first (DeformableContact.held_prints): the reach of
# all of a print's nodes and which share of their friction its resultant keeps to (None:
# options.friction_margin), until the nodes carry one's answer and a restoration step meets
# the rows and stances.verify takes the answer (among its checks, a stiff print's node forces
# a pressure under its face: DeformableContact.pressure_fits). A palm on a 1e10 Pa cube
# beside a 1e6 Pa mat, which the rigid support tips onto its edge with its resultant near
# the pyramid's face: 0.19 % from the rigid support's force at the first, 2.74 % at the
# second (2026-12-06). climb-with-soft-support's palm at 1e12 Pa: from the first no
# restoration step met the rows (its nodes all but sliding); the second and third pivot onto
# nodes past its edge, which verify refuses, and it goes on through W. hand-on-cube's palm
# at 1e9 Pa: on its edge its nodes carry either only by a 52 um pivot; within the rows its
# polygon covers a hundredth or more, 2.6 um (1.1 %).
_HELD_LEVELS = ((0.0, 1.0), (0.0, None), (0.01, None))
# Tried only with this many rigid warm starts' time left: hand-on-cube at 1e10 Pa, its warm
# start 0.03-0.06 s, took 0.13 s in the stiff limit and 0.13-0.17 s through W (2026-12-05).
_STIFF_TIME = 8.0
_LIFT_STEPS = 4
# Then at most this many with the stiff bodies' W free as well: with W held the forces
# are the carried ones, and a row at its bound that they do not quite balance stays off.
# Both soles on a 1e10 Pa slab, the centre of mass held at 0.101 m ahead by a user's row,
# on a mesh whose lines lay 17 mm further forward under the soles: held, that row stayed
# 4.4 nm off its bound and the equilibrium 1e-6 N, through 4 steps and more; one step
# with W free met both (W moved by picometres), where the solve through W then failed
# after 8.6 s.
_FREE_STEPS = 2
# The status of a solve refused before its SQP (_balls_refused_anyway).
BALLS_REFUSED = "ball refused before solving"
# The status (and the reason's start) of a solve that met a posture where a soft print's
# contact has no state (fem.ContactStateError) other than as a line search's trial.
NO_CONTACT_STATE = "contact of a soft print with no Coulomb state at a posture the solve had to start from"
# What a stance's reason starts with when it cannot be held even with its soft supports
# held rigid (the rigid warm start's cheap rejection; cbm.rejections reads past it).
HELD_RIGID = "even with its soft supports held rigid: "
# ... and when it cannot be held with its soft bodies, all too stiff to give, held rigid
# where their prints' nodes reach (_solve_stiff_limit).
HELD_AT_NODES = "even with its stiff soft supports held rigid where their prints' nodes reach: "


def solve(robot, scene, stance, q_init=None, time_budget=None, constraints=(), lam_init=None, reference=None,
          history=None, **options) -> PostureResult:
    """Find a statically feasible posture holding a stance.

    Parameters
    ----------
    robot : stances.Robot
    scene : environments.Scene
    stance : environments.Stance
    q_init : (nq,) float, optional
        Warm start (e.g. the parent stance's posture in a search); by default the
        reference posture moved over the prints (:func:`stances.initial_configuration`).
    lam_init : (m,) float, optional
        Contact variables to start from with ``q_init``: ``statistics["lambda"]``
        of an earlier answer for the same stance and options (a motion's
        previous sample). With them a soft stance starts its solve at once,
        without the rigid warm start, whose posture the prints barely touch
        and whose forces are the rigid contacts', not the earlier answer's
        sinking into the soft supports; the cheap early rejection of a stance that
        cannot be held even rigid is skipped too, so a hopeless stance costs
        a full soft solve.
    reference : (nq,) float, optional
        The posture the joint-distance cost pulls toward (``posture_weight``);
        the robot's reference posture by default. A motion's samples use a
        blend of the two stances they join.
    history : PostureResult, optional
        The answer before this one in a sequence (a plan's previous stance). Each soft
        print this stance keeps from it (the same robot surface on the same print)
        starts where that answer left its link points over its nodes
        (``history.slips``): under Coulomb friction a node that sticks keeps its slip,
        one that slips moves on from it, so a print held down between two stances does
        not slide back. By default every print starts from rest. The slips started
        from are the answer's ``held_slips``, which :func:`stances.verify` reads.
    time_budget : float, optional
        Wall-clock seconds this call may take. No SQP iteration starts after
        it is spent, nor a soft print's compliance column (the long part of a
        new print's setup on a large body, :mod:`fem.deadline`); the stance is
        then infeasible with a reason that says so (unless the iterate reached
        is already feasible and verified). A body's factorisation and the final
        verification's other steps are not interrupted.
    constraints : sequence, optional
        Extra constraints, each an object with ``blocks(problem, iterate)``
        returning :class:`~stances.blocks.ConstraintBlock` rows (as the pieces
        of :mod:`stances.terms`; with ``iterate.derivatives`` False only the
        rows' values are read), added to every problem this call solves
        (e.g. a free link held on a path while the robot moves between
        stances). :func:`stances.verify` knows nothing of them: check them
        yourself.
    **options
        Fields of :class:`~stances.problem.PostureOptions`.

    Returns
    -------
    PostureResult
        ``feasible`` is True only when the SQP converged and the independent
        :func:`stances.verify` passed; otherwise ``reason`` says why.

    Raises
    ------
    StanceError
        For bad input (unknown surfaces, a print off its surface, a malformed
        q); an infeasible stance is an answer, not an exception.
    environments.SceneError
        Before any solve, for a soft body pressed by the stance whose own weight
        strains it beyond its strain bound: linear elasticity cannot describe it.
    """
    start = time.perf_counter()
    deadline = None if time_budget is None else start + _time_budget(time_budget)
    held = kept_slips(history, stance)
    try:
        with setup_deadline(deadline):
            return _solve(robot, scene, stance, q_init, time_budget, constraints, lam_init, reference, options,
                          start, deadline, held)
    except SetupTimeout as stop:
        # Out of time while a soft print was set up: an answer, as a spent budget
        # is anywhere else, from the posture the solve would have started at.
        return _unsolved(robot, scene, stance, q_init, start, OUT_OF_TIME, _budget_spent(time_budget, str(stop)))
    except ContactStateError as error:
        # A soft print's contact with no state at a posture a stage had to start from (the
        # SQP's trials step around such postures; the stiff limit and held-mode attempts
        # give way to what follows them): an answer too, at the solve's starting posture.
        return _unsolved(robot, scene, stance, q_init, start, NO_CONTACT_STATE, f"{NO_CONTACT_STATE}: {error}")


def kept_slips(history, stance) -> dict:
    """Robot surface -> :class:`~stances.results.NodeSlips` of each soft print ``stance``
    keeps from the answer ``history`` (the same robot surface on the same print), where
    ``history`` left its link points; empty for None.

    Raises
    ------
    StanceError
        If ``history`` is no posture answer.
    """
    if history is None:
        return {}
    if not isinstance(history, PostureResult):
        hint = " (a check's answer is its .result)" if hasattr(history, "result") else ""
        raise StanceError(f"history must be a PostureResult (the answer of the stance before), "
                          f"got {type(history).__name__}{hint}")
    before, left = set(getattr(history.stance, "contacts", ()) or ()), history.slips or {}
    return {contact.robot_surface: left[contact.robot_surface] for contact in stance
            if contact in before and contact.robot_surface in left}


def _unsolved(robot, scene, stance, q_init, start, status, reason) -> PostureResult:
    """An infeasible answer at the posture the solve started from (its SQP iterations, if any,
    not counted: a time-out in a print's setup, a contact with no state where a stage had to
    start), its ``statistics`` the ``status`` alone."""
    q = initial_configuration(robot, scene, stance) if q_init is None else np.asarray(q_init, dtype=float)
    return PostureResult(
        feasible=False, q=q, point_forces=(), torques=np.zeros(robot.model.nv - 6), iterations=0,
        solve_time=time.perf_counter() - start, stance=stance, statistics={"status": status}, reason=reason,
    )


def _solve(robot, scene, stance, q_init, time_budget, constraints, lam_init, reference, options, start, deadline,
           held_slips):
    """:func:`solve`'s work, from its arguments (``options`` the keyword ones), its start
    time and deadline (``time.perf_counter()`` values) and the slips its kept prints hold
    (:func:`kept_slips`)."""
    options = posture_options(options)
    constraints = tuple(constraints)

    def build(options, held_prints=None):
        built = build_problem(robot, scene, stance, options, held_prints, held_slips)
        built.constraints.extend(constraints)
        if reference is not None:
            try:
                built.reference = built.check_configuration(reference)
            except ConfigurationError as error:
                raise ConfigurationError(f"reference: {error}") from None
        return built

    problem = build(options)
    refused = _balls_refused_anyway(problem, options)
    if refused:
        # No posture passes verification: a ball where no continuum estimate of its force
        # exists sinks under its least load (ANYmal on a soft step's tread: 0.1-0.2 s of SQP
        # before verification refused it, 0.004 s so).
        return _unsolved(robot, scene, stance, q_init, start, BALLS_REFUSED, "; ".join(refused))
    deformable = any(c.kind == "deformable" for c in problem.contacts)
    if deformable and q_init is None and lam_init is None:
        q_init = initial_configuration(robot, scene, stance)  # not the reaching start (see _reaches)
    warm_iterations, warm_time = 0, 0.0
    rigid, bonded_warm_start = None, False  # the rigid warm start's problem, and whether the bonded one ran
    loose = dict(_WARM_START_TOLERANCES, max_iterations=min(options.max_iterations, _WARM_START_ITERATIONS))
    if lam_init is not None:
        lam_init = np.asarray(lam_init, dtype=float)
        if q_init is None:
            raise StanceError("lam_init needs q_init: the posture those contact variables were solved with")
        if lam_init.shape != (problem.n_variables,):
            raise StanceError(
                f"lam_init must be {problem.n_variables} contact variables (statistics['lambda'] of an "
                f"answer for the same stance and options), got shape {lam_init.shape}"
            )
        if not np.all(np.isfinite(lam_init)):
            raise StanceError(f"lam_init has non-finite entries at indices {np.flatnonzero(~np.isfinite(lam_init)).tolist()}")
    elif options.rigid_warm_start and deformable:
        rigid = build(replace(options, deformable_as_rigid=True, **loose))
        warm_time = time.perf_counter()
        warm = solve_problem(rigid, q_init, deadline=deadline, check=False)
        q_init, warm_iterations, warm_time = warm.q, warm.iterations, time.perf_counter() - warm_time
        if warm.statistics["violation"] > loose["feasibility_tolerance"]:
            # Even held rigid the stance cannot be held: a support that gives a few
            # millimetres will not save it. Cheap rejection, with its reason (the
            # soft solve of such a stance was measured at 10-40 s).
            reason = warm.reason if warm.statistics["status"] == OUT_OF_TIME else f"{HELD_RIGID}{warm.reason}"
            return _refused_held(replace(warm, reason=reason), warm_iterations, options, start, stance, time_budget)
        if options.contact_law == "coulomb":
            # From the rigid posture the prints barely touch: W read off it, A xi(q),
            # leaves every node at the point of lifting off, with no force gradient.
            # W carrying the rigid answer's forces presses the prints as deep as that
            # load does: the Coulomb solve starts there (14 built-in soft stances, every
            # one solved: 6.65 s in all against 7.78 s from the bonded model's answer).
            lam_init = problem.variables_from_rigid(rigid, warm.statistics["lambda"], warm.point_forces)
    stiff, stiff_note = None, None
    left = None if deadline is None else deadline - time.perf_counter()
    if (options.contact_law == "coulomb" and deformable and lam_init is not None and options.stiff_limit
            and options.deformation_cost == "energy" and (left is None or left >= _STIFF_TIME * warm_time)):
        # At most half the time left: where it does not hold, the solve goes on through W
        # with the rest. Not tried where less is left than a few warm starts' time (a
        # tight time budget: the solve through W alone fits where both might not).
        share = None if deadline is None else time.perf_counter() + _STIFF_SHARE * left
        warm_lam = None if rigid is None else (rigid, np.asarray(warm.statistics["lambda"]))
        stiff, stiff_note, refusal = _solve_stiff_limit(problem, build, options, q_init, lam_init, share, warm_lam)
        if refusal is not None:
            # Its soft bodies all too stiff to give, the stance is not held even with their
            # prints held rigid where their nodes reach: their Coulomb forces cannot carry it
            # either (both soles on a 1e10 Pa slab, each centre of pressure on its toe edge,
            # on an 11 mm mesh: refused through W after 40 s, and after 525 s before the
            # held-mode contact solves stopped on their cycles; at once now, 0.16 s).
            return _refused_held(refusal, warm_iterations, options, start, stance, time_budget)
    if stiff is not None:
        result = stiff
    elif options.contact_law == "coulomb" and deformable:
        result = _solve_coulomb(problem, q_init, deadline, lam_init=lam_init)
        # (The bonded model cannot press a ball's nodes: a body a ball presses keeps Coulomb's.)
        balls = any(len(c.point_prints) for c in problem.contacts if c.kind == "deformable")
        if (not result.feasible and result.statistics["status"] != OUT_OF_TIME
                and result.statistics["violation"] <= _CONTACT_SET_VIOLATION and rigid is not None and not balls):
            # Not from there, though near feasible (far from it, the stance cannot be
            # held, wherever it starts: both soles on foam at 3e4 Pa, which the strain
            # bound rules out, took 3.0 s, and 6.6 s with this fallback, which ended the
            # same): from the bonded model's answer (it presses every node),
            # its forces too (the same variables: W read off the posture instead
            # multiplies the warm start's micrometres of placement error by the body's
            # stiffness, thousands of newtons on a steel-stiff cube).
            bonded = build(replace(options, contact_law="bonded", **loose))
            warm = solve_problem(bonded, q_init, deadline=deadline, check=False)  # q_init: the rigid answer
            warm_iterations += result.iterations + warm.iterations
            result = _solve_coulomb(problem, warm.q, deadline, lam_init=np.asarray(warm.statistics["lambda"]))
            bonded_warm_start = True
    else:
        result = solve_problem(problem, q_init, lam_init=lam_init, deadline=deadline)
    if stiff_note is not None and not result.feasible and result.statistics["status"] != OUT_OF_TIME:
        # Before the rows the last step could not meet together, which close the reason.
        head, conflict, rows = result.reason.partition("; no step meets together: ")
        result = replace(result, reason=f"{head}; {stiff_note}{conflict}{rows}")
    statistics = dict(result.statistics, sqp_time=result.solve_time, options=_changed(options))
    if warm_iterations:
        statistics["rigid_warm_start_iterations"] = warm_iterations
    if bonded_warm_start:
        statistics["bonded_warm_start"] = True
    if stiff is not None:
        statistics["stiff_limit"] = True
    # solve_time covers everything this call did: building, warm start, SQP, verification.
    return _timed_out(replace(result, statistics=statistics, solve_time=time.perf_counter() - start), time_budget)


def _refused_held(answer, warm_iterations, options, start, stance, time_budget) -> PostureResult:
    """A stance refused on a solve with its soft supports held rigid (the rigid warm start's,
    or the stiff limit's held solve): that ``answer``, its reason as given, with the warm
    starts' iterations, the options changed, the whole call's time and the caller's stance."""
    statistics = dict(answer.statistics, rigid_warm_start_iterations=warm_iterations, options=_changed(options))
    return _timed_out(replace(answer, statistics=statistics, solve_time=time.perf_counter() - start, stance=stance),
                      time_budget)


def _solve_stiff_limit(problem, build, options, q, lam, deadline=None, warm=None):
    """The stance on soft bodies too stiff to give, in their stiff limit, a note and a refusal:
    ``(result, None, None)``, or ``(None, note, refusal)`` where it is not (the note None but
    where the stance holds rigid; the refusal None but where it does not, see 2.).

    As E grows a soft print's links move by nanometres: its nodes' Coulomb forces carry
    what a rigid contact would where the nodes are, and the posture is the rigid one. The
    soft prints' own variables W do not lead there: the force term weighs W, the wrench
    the nodes would carry bonded, which moves far from what they carry once some lift off
    (``bench/bench_palm_limit.py``), and the palm of hand-on-cube at E = 1e10 Pa stopped
    1.3-2.9 % off the rigid support's force (since the SQP's Hessian carries the Coulomb
    forces' curvature, 2026-12-06: 2.17 % at 1e9 Pa and 0.51 % at 1e10, other optima of
    the same model; the stiff limit's answer is 1.11 % off at every E from 1e9).
    So, in order (no result at the first that fails):

    1. the stiff bodies: those whose contact is a
       :class:`~stances.deformable.DeformableContact` of flat prints, whose bonded
       nodes the loads ``lam`` move less than ``STIFF_GIVE``
       (:meth:`~stances.deformable.DeformableContact.stiff_give`), and some of whose
       nodes would pull or slip under them (not
       :meth:`~stances.deformable.DeformableContact.sticks`: where all stick, W carries
       what they carry and the solve through W tends to the rigid support's); at least one;
    2. the stance with the stiff bodies held rigid, each of their prints' centre of
       pressure where its nodes are, its resultant in a friction pyramid
       (:meth:`~stances.deformable.DeformableContact.held_prints`): at the loosest of
       ``_HELD_LEVELS`` first (the reach of all their nodes, the rigid contact's friction),
       then, where 3. to 5. fail, at the next ones (``friction_margin``'s friction; the
       reach of the nodes their polygons cover a hundredth or more); each solved to
       ``options``' tolerances from ``q``; the other soft bodies stay soft (a foam mat
       beside a steel-stiff block: through W as any Coulomb stance, :func:`_solve_coulomb`,
       from ``lam``); where every soft body is held and the first stops farther from
       feasible than a warm start's tolerance, or stalls farther than verify takes (not for
       want of time), the stance is refused: the held answer, its reason saying so
       (``HELD_AT_NODES``);
    3. each stiff body's W whose Coulomb forces carry that answer's wrenches, and the
       links' motion it asks (:meth:`~stances.deformable.DeformableContact.carrying_variables`),
       less than ``STIFF_GIVE``;
    4. restoration steps from there, the stiff bodies' W held (their forces are the
       carried ones), onto every row (:func:`_lift`: the links moved by that give, the
       other contacts' forces balancing the posture so moved; then a step or two with W
       free too, where a row at its bound stays a few nanometres off), then
       :func:`stances.verify` on the full FEM model, and each stiff print's node forces a
       pressure under its face (:meth:`~stances.deformable.DeformableContact.pressure_fits`);
    5. where 3. or 4. fails at the first level, the held answer itself, each stiff print's wrench
       carried by the least-energy pressure under its face, the face held where the body gives
       under it (:func:`_spread_answer`), verified (once: a tighter level's answer, farther from
       the rigid one, would fail as the first's did, at 1e9 Pa for a field over verify's 1 um;
       tried at each level, climb's platform palm at 1e9 Pa took 0.88 s instead of 0.32): a
       link's own contact carries a held answer whose
       centre of pressure nears an edge only pivoting onto the partly covered nodes past it
       (Romeo's and iCub's palms at 1e10 Pa, both soles 2 mm behind their toe edges on a
       steel-stiff slab), where a converged mesh would carry it by a pressure under the link.

    Where it does not hold, the soft contacts are left as they were (the solve that goes
    on through W starts as it would have without this), and so where ``deadline`` passes
    before its end.

    Parameters
    ----------
    problem : PostureProblem
        The soft problem.
    build : callable
        ``build(options, held_prints) -> PostureProblem`` for the same stance.
    options : PostureOptions
    q : (nq,) float
        The posture to start from (the rigid warm start's).
    lam : (m,) float
        ``problem``'s variables carrying the loads to start from (the warm start's).
    deadline : float, optional
        ``time.perf_counter()`` value.
    warm : (PostureProblem, (m_rigid,) float), optional
        The rigid warm start's problem and answer: the held prints' forces start from
        its (the held solve of hand-on-cube at 1e10 Pa: 12 -> 6 iterations; beside a
        soft mat, the weight shared evenly had ended at another optimum, its palm 1.5 %
        off the rigid support's instead of 0.9 %).

    Returns
    -------
    result : PostureResult or None
        Verified; its iterations the held solves' and the restoration steps, its
        ``qp_time`` the held solves'.
    note : str or None
        Where the stance holds with the stiff bodies rigid but their nodes cannot carry
        that answer within ``STIFF_GIVE``, why, for the reason of an answer through W
        that then fails: both soles on a 1e10 Pa slab, the centre of mass 0.105 m ahead of
        them (each sole's centre of pressure 5 mm behind its toe edge, past its last row of
        nodes), asked them to pivot (a 33 um give), and through W the solve did not converge.
    refusal : PostureResult or None
        The held answer, infeasible, its reason starting with ``HELD_AT_NODES``, where the
        stance is refused in 2.
    """
    soft = [(c, s) for c, s in zip(problem.contacts, problem.variable_slices) if c.deformable_object is not None]
    if any(c.kind == "deformable" and len(c.point_prints) for c, _ in soft):
        # Balls pressing a body's nodes (ball_contact="nodes", a body that is no layer):
        # their contact system exists before the attempt (the rigid answer's loads are
        # shared among the balls through it) and would keep what the attempt's solves
        # leave in it. Such a stance goes through W.
        return None, None, None
    stiff = [(c, s) for c, s in soft
             if c.kind == "deformable" and c.stiff_give(lam[s]) <= STIFF_GIVE and not c.sticks(lam[s])]
    if not stiff:
        return None, None, None
    mixed = len(stiff) < len(soft)  # other soft bodies stay soft in the held solve
    states = [contact.solver_state() for contact, _ in soft]
    start = time.perf_counter()

    def abandon(why, *args, note=None, refusal=None):
        for (contact, _), state in zip(soft, states):
            contact.restore_solver_state(state)
        logger.debug("stiff limit not taken: " + why, *args)
        return None, note, refusal

    def out_of_time():
        return deadline is not None and time.perf_counter() >= deadline

    try:
        iterations, qp_time = 0, 0.0  # of the held solves
        note, why = None, ""  # the nodes' failure to carry a held answer, for the reason; the last failure
        levels = [(c, options.friction_margin if f is None else f) for c, f in _HELD_LEVELS]
        levels = [level for k, level in enumerate(levels) if level not in levels[:k]]
        for k, (coverage, friction) in enumerate(levels):
            if k:  # each level from the same start
                for (contact, _), state in zip(soft, states):
                    contact.restore_solver_state(state)
            held_prints = {}
            for contact, _ in stiff:
                held_prints.update(contact.held_prints(coverage, friction))
            held_options = options if mixed else replace(options, deformable_as_rigid=True)
            held = build(held_options, held_prints)
            answer = _held_solve(held, q, _held_start(held, problem, q, lam, warm), deadline)
            iterations, qp_time = iterations + answer.iterations, qp_time + answer.statistics["qp_time"]
            if not answer.feasible and k:
                why = f"held rigid at a tighter level, {answer.reason}"
                break  # the looser levels' failures stand
            if not answer.feasible:
                # Refused beyond a warm start's tolerance; and, where the held solve stalled with rows
                # that no step meets together, beyond what verify would take and the rounding floor at
                # which a stall is no verdict (stances.stopping; a centre of pressure the
                # prints do not reach by a fraction of a millimetre: the soles' toe edges held by a
                # centre-of-mass row, 0.05 N short, where the solve through W then failed after 5-17 s).
                # No tighter level holds more.
                status, violation = answer.statistics["status"], answer.statistics["violation"]
                refused = (not mixed and status != OUT_OF_TIME and not out_of_time()
                           and (violation > _WARM_START_TOLERANCES["feasibility_tolerance"]
                                or (status == STALLED
                                    and violation > max(NEARLY_FEASIBLE * options.feasibility_tolerance, ROUNDING_FLOOR))))
                refusal = replace(answer, reason=f"{HELD_AT_NODES}{answer.reason}") if refused else None
                return abandon("held rigid, %s", answer.reason, refusal=refusal)
            if out_of_time():
                return abandon("out of time")
            result, why, carry_note = _carried_answer(problem, held, stiff, answer, out_of_time, iterations, qp_time,
                                                      start)
            if result is None and carry_note is None and why is None:
                return abandon("out of time")
            note = carry_note or note
            if result is not None:
                return result, None, None
            if k:
                continue  # the tighter levels serve the nodes' own contact; the spread carries the loosest
            if out_of_time():
                return abandon("out of time")
            # The nodes' own contact does not carry it: the least-energy pressure under each face.
            spread, spread_why = _spread_answer(problem, stiff, held, answer, iterations, qp_time, start,
                                                held_prints, lambda prints: build(held_options, prints), deadline,
                                                out_of_time)
            if spread is not None:
                return spread, None, None
            if spread_why is None:
                return abandon("out of time")
            why = f"{why}; carried by a pressure under the prints, {spread_why}"
        return abandon("%s", why, note=note)
    except ContactStateError as error:
        # A print's contact with no state at a posture the held answer led to: the solve
        # through W goes on, as where the held answer does not hold.
        return abandon("no contact state: %s", error)


def _carried_answer(problem, held, stiff, answer, out_of_time, iterations, qp_time, start):
    """The held ``answer`` carried by the stiff bodies' own Coulomb contact (steps 3 and 4
    of :func:`_solve_stiff_limit`): ``(result, None, None)``, verified and a pressure under
    each stiff print; else ``(None, why, note)``, ``note`` the carry's own failure where it
    failed (for the reason of an answer through W), and all None where the time ran out."""
    carried, carry_note = _carried(problem, held, stiff, answer, out_of_time)
    if carried is None:
        return None, carry_note, carry_note
    lifted = _lift(problem, *carried, [s for _, s in stiff])
    if lifted is None:
        return None, "the rows not met from the held answer", None
    q_lifted, lam_lifted, linearization, steps = lifted
    met = linearization.met(problem.options.feasibility_tolerance)  # else nearly: verify decides
    outcome = SqpOutcome(q_lifted, lam_lifted, linearization, iterations + steps, "converged", 0.0, qp_time,
                         met, "" if met else "the rows not met from the held answer")
    result = posture_result(problem, outcome, time.perf_counter() - start)
    why = result.reason if not result.feasible else _not_pressed(problem, stiff, result)
    return (None, why, None) if why else (result, None, None)


def _held_solve(held, q, lam, deadline):
    """The stance with some soft bodies held (``held``), solved from ``q`` and ``lam``."""
    if any(c.kind == "deformable" for c in held.contacts):
        return _solve_coulomb(held, q, deadline, lam_init=lam)
    # Every body held, or the others balls on layers: no contact sets to settle.
    return solve_problem(held, q, lam_init=lam, deadline=deadline, check=False)


def _spread_answer(problem, stiff, held, answer, iterations, qp_time, start, held_prints, rebuild, deadline,
                   out_of_time):
    """The held ``answer`` with each stiff print's forces those of the least-energy pressure
    under its face with its wrench there
    (:meth:`~stances.deformable.DeformableContact.spread_forces`), its face held where the
    body gives under them (``rebuild(held_prints)``: the held problem with each
    :class:`~stances.deformable.HeldPrint` of ``held_prints`` moved so, solved again from
    ``answer``; where that solve or its spread fails, the answer at rest), checked by
    :func:`stances.verify` on ``problem``: ``(result, None)``, else ``(None, why)``, and
    ``(None, None)`` where ``out_of_time()`` says the time ran out.

    Where the nodes' own contact carries a held answer only by pivoting onto the partly
    covered nodes past an edge (node forces that no pressure under the link gives), a
    pressure under the link carries it as on a converged mesh, and a body this stiff
    gives micrometres under it: verify then finds each node against its link within its
    tolerance, pushing, in its cone (climb-with-soft-support's palm at 1e10 Pa, held at
    rest, had a node slip 1.03 um under its friction). The answer's ``lambda`` is ``problem``'s
    variables with each stiff print's W the one that carries its held wrench
    (:meth:`~stances.deformable.DeformableContact.variables_from_forces`: a start for a later
    solve; their Coulomb forces are not the reported ones).
    """
    model, data = problem.robot.model, problem.data
    point_forces = _spread_forces(problem, stiff, held, answer)
    if isinstance(point_forces, str):
        return None, point_forces
    forces = np.array([p.force for p in point_forces], dtype=float)
    moved = {}
    for contact, _ in stiff:
        on_body = forces[problem.load_slices[problem.contacts.index(contact)]]
        for spec, motion in zip(contact.prints, contact.spread_motions(model, data, on_body)):
            moved[spec.robot_surface] = motion
    held_again = rebuild({surface: replace(print_held, motion=moved.get(surface, print_held.motion))
                          for surface, print_held in held_prints.items()})
    again = _held_solve(held_again, np.asarray(answer.q, dtype=float), np.asarray(answer.statistics["lambda"]),
                        deadline)
    iterations, qp_time = iterations + again.iterations, qp_time + again.statistics["qp_time"]
    if again.statistics["status"] == OUT_OF_TIME or out_of_time():
        return None, None
    if again.feasible:
        moved_forces = _spread_forces(problem, stiff, held_again, again)
        if not isinstance(moved_forces, str):
            held, answer, point_forces = held_again, again, moved_forces
    q = np.asarray(answer.q, dtype=float)
    lam = problem.variables_from_rigid(held, answer.statistics["lambda"], answer.point_forces)
    statistics = {k: v for k, v in dict(answer.statistics, **{"lambda": lam.tolist()}).items() if v is not None}
    statistics.update(pressure_spread=True, qp_time=qp_time)
    result = PostureResult(
        feasible=False, q=q, point_forces=point_forces, torques=answer.torques, iterations=iterations,
        solve_time=time.perf_counter() - start, reason="", stance=problem.stance,
        deformations=deformation_fields(problem, q, point_forces), limits=answer.limits, statistics=statistics,
        held_slips=problem_held_slips(problem),
    )
    verification = verify_shown(problem, result)
    if not verification.ok:
        return None, "; ".join(verification.reasons)
    return replace(result, feasible=True, verification=verification), None


def _spread_forces(problem, stiff, held, answer):
    """``problem``'s point forces at the held ``answer``'s posture: each stiff body's
    spread onto its print nodes (:meth:`~stances.deformable.DeformableContact.spread_forces`),
    every other contact's the held answer's; or why not (a str)."""
    model, data = problem.robot.model, problem.data
    pin.framesForwardKinematics(model, data, np.asarray(answer.q, dtype=float))
    given = {_contact_key(c): answer.point_forces[loads] for c, loads in zip(held.contacts, held.load_slices)}
    point_forces = []
    for contact in problem.contacts:
        if any(contact is other for other, _ in stiff):
            forces = contact.spread_forces(data, answer.point_forces)
            if forces is None:
                return f"no pressure under the prints on {contact.deformable_object.name} carries their loads"
            points = points_in_world(data, contact.loads)
            point_forces.extend(PointForce(f, p, v) for f, p, v in zip(contact.load_frames, points, forces))
        else:
            point_forces.extend(given[_contact_key(contact)])
    return tuple(point_forces)


def _not_pressed(problem, stiff, result) -> str:
    """Why a stiff limit's answer is not a pressure under each stiff body's prints
    (:meth:`~stances.deformable.DeformableContact.unpressed` with ``every``: verify fits
    only the prints of bodies too stiff to give under the robot's whole weight, and the
    stiff limit also holds bodies the stance's own loads sink less than ``STIFF_GIVE``),
    or ``""``."""
    forces = np.array([p.force for p in result.point_forces], dtype=float).reshape(-1, 3)
    for contact, _ in stiff:
        loads = problem.load_slices[problem.contacts.index(contact)]
        reasons = contact.unpressed(forces[loads], VerificationTolerances().pressure_fit, every=True)
        if reasons:
            return reasons[0]
    return ""


def _carried(problem, held, stiff, answer, out_of_time):
    """The held answer's posture and ``problem``'s variables whose stiff bodies' Coulomb
    forces carry its loads (:meth:`~stances.deformable.DeformableContact.carrying_variables`),
    each body giving at most ``STIFF_GIVE``: ``((q, lam), None)``, else ``(None, why)``
    (why None where the time ran out)."""
    q = np.asarray(answer.q, dtype=float)
    lam = problem.variables_from_rigid(held, answer.statistics["lambda"], answer.point_forces)
    for contact, s in stiff:
        if out_of_time():
            return None, None
        # The wrenches themselves, not the W that carries them from held slips (lam's).
        carried = contact.carrying_variables(contact.print_wrenches(problem.robot.model, answer.point_forces))
        give = None if carried is None else contact.link_give(carried[1])
        if give is None or give > STIFF_GIVE:
            if give is None:
                how = "find no motion of the links that carries its loads"
            else:
                how = (f"carry its loads only by giving {1e6 * give:.3g} um, more than the {1e6 * STIFF_GIVE:g} um "
                       "a stiff body's limit takes (on a body this stiff a centre of pressure near a print's last "
                       "row of nodes is carried only if the print pivots, and the mesh's spacing under the print "
                       "sets where that row lies)")
            return None, f"held rigid, the stance holds, but the nodes of {contact.label} {how}"
        lam[s] = carried[0]
    return (q, lam), None


def _balls_refused_anyway(problem, options) -> list:
    """Why verification would refuse a ball of ``problem`` whatever the posture
    (:meth:`~stances.deformable.DeformableContact.balls_refused_anyway`), ``[]`` where
    ``ball_force_error`` is ``inf`` or no ball presses mesh nodes."""
    if not np.isfinite(options.ball_force_error):
        return []
    placement = VerificationTolerances().deformable_placement
    reasons, start = [], 0
    for contact in problem.contacts:
        least = problem.min_normal_loads[start : start + len(contact.print_surfaces)]  # in print_surfaces' order
        start += len(contact.print_surfaces)
        if contact.kind == "deformable" and len(contact.point_prints):
            reasons += contact.balls_refused_anyway(least, placement)
    return reasons


def _held_start(held, problem, q, lam, warm=None):
    """``held``'s variables to start from: ``problem``'s ``lam`` where a contact is the
    same in both (a rigid print's cone coefficients, a body soft in both its W); on the
    prints ``held`` holds, those of the rigid warm start ``warm`` (its problem and
    variables) where given, else the weight shared evenly
    (:meth:`PostureProblem.initial_variables` at ``q``)."""
    out = held.initial_variables(q)
    sources = [(problem, lam)] + ([] if warm is None else [warm])
    for source, values in sources[::-1]:  # problem's last: it wins where both have a contact
        given = {_contact_key(c): s for c, s in zip(source.contacts, source.variable_slices)}
        for contact, s in zip(held.contacts, held.variable_slices):
            mine = given.get(_contact_key(contact))
            if mine is not None:
                out[s] = values[mine]
    return out


def _contact_key(contact) -> tuple:
    """What a contact is across two problems of one stance: its soft body, or the robot
    surface and kind of a print on no soft body."""
    if contact.deformable_object is not None:
        return ("body", contact.deformable_object.name)
    return (contact.kind, contact.robot_surface)


def _lift(problem, q, lam, held):
    """Restoration steps onto the rows of ``problem`` with the variables in the slices
    ``held`` fixed, at most ``_LIFT_STEPS``, then at most ``_FREE_STEPS`` with them free:
    ``(q, lam, Linearization, steps)`` where the rows are met (its feasibility tolerance) or
    nearly (within ``NEARLY_FEASIBLE`` of it: :func:`stances.verify` then decides), else None.

    The soft prints' ``touch`` rows are left out (of the steps and of the Linearization
    returned): they ask the mean height of a print's nodes not above the rest surface, a
    smooth stand-in for pressing that a palm leaning on its edge fails while that edge
    presses; here each print carries the held answer's load, which says it presses.
    """
    nv, workspace = problem.robot.model.nv, QPWorkspace()
    tolerance = problem.options.feasibility_tolerance

    def rows(q, lam):
        try:
            linearization = problem.linearize(q, lam)
        except ContactStateError:
            return None  # a print's contact with no state there: no lift
        return replace(linearization, blocks=[b for b in linearization.blocks if b.name != "touch"])

    linearization = rows(q, lam)
    if linearization is None:
        return None
    for steps in range(_LIFT_STEPS + _FREE_STEPS + 1):
        if linearization.met(tolerance):
            return q, lam, linearization, steps
        if steps == _LIFT_STEPS + _FREE_STEPS:
            break
        lower, upper = linearization.step_lower.copy(), linearization.step_upper.copy()
        for s in held if steps < _LIFT_STEPS else ():
            lower[nv + s.start : nv + s.stop] = upper[nv + s.start : nv + s.stop] = 0.0
        restored = restoration_step(problem, replace(linearization, step_lower=lower, step_upper=upper), q, lam,
                                     workspace)
        if restored is None:
            return None
        q, lam = restored
        linearization = rows(q, lam)
        if linearization is None:
            return None
    # Nearly met, where an SQP's answer may end too (NEARLY_FEASIBLE): verification decides.
    if linearization.max_violation()[0] <= NEARLY_FEASIBLE * tolerance:
        return q, lam, linearization, _LIFT_STEPS + _FREE_STEPS
    return None


def _timed_out(result, time_budget) -> PostureResult:
    """Say first in an infeasible answer's reason that the time budget stopped it, then
    what the last iterate still violated (a state when the time ran out, not a verdict)."""
    if result.feasible or result.statistics.get("status") != OUT_OF_TIME:
        return result
    return replace(result, reason=_budget_spent(time_budget, f"at the last iterate: {result.reason}"))


def _budget_spent(time_budget, state) -> str:
    """The reason of a solve its time budget stopped, then the state it stopped in."""
    return f"time budget of {float(time_budget):g} s spent before convergence; {state}"


def _solve_coulomb(problem, q_init, deadline=None, attempts=3, lam_init=None) -> PostureResult:
    """Coulomb prints: modes read at every linearisation, then, if that stalls, held.

    First the SQP runs for at most ``_FREE_ITERATIONS`` (ending early if it creeps far
    from feasible, :meth:`~stances.stopping.StoppingTest.creeping`) with each node's mode
    (stick, slip, lift off) read again at every linearisation: on the built-in
    soft stances this converges in 3-36 iterations, where holding the modes of
    the bonded posture (what follows) needed up to three attempts of 16-30
    iterations each before the modes settled (hand-on-cube: 63 iterations, 1.7 s,
    against 15 and 0.9 s). But a contact set can flip under steps far smaller than
    an SQP takes (on stiff bodies slips are nanometres), and a line search then
    stalls: from where the first stage stopped, the modes are held, which makes the
    forces linear in the displacements so the SQP converges fast; the answer is
    kept only if :func:`stances.verify` (Signorini and Coulomb at every node, on
    the full FEM model) accepts it, otherwise the modes are read again at the new
    posture; if they are those just held, the contact set has settled and that
    attempt is the answer (unless its iteration cap ended it). If the modes do not
    settle, the SQP runs again with modes updated at every linearisation, without a
    cap: from where the first stage stopped, with its contact variables, if the attempts
    began from the start, else from where they began.

    An infeasible answer is the stage that ended it (the first stage's where it
    came closer than held modes from the start): its ``reason`` and statistics are
    that stage's, ``iterations`` counts every stage. With ``q_init`` None the solve
    starts from :func:`stances.initial_configuration`.
    """
    model = problem.robot.model
    deformable = [(c, s) for c, s in zip(problem.contacts, problem.variable_slices) if c.kind == "deformable"]
    q = starting_configuration(problem, q_init)
    free = solve_problem(problem, q, lam_init=lam_init, max_iterations=_FREE_ITERATIONS, deadline=deadline, creep=True)
    iterations = free.iterations
    status, violation = free.statistics["status"], free.statistics["violation"]
    hopeless = (status in ("stagnated", NO_PROGRESS, QP_FAILED) and violation > _CONTACT_SET_VIOLATION
                and free.iterations > _EARLY_STOP)
    if free.feasible or status == OUT_OF_TIME or hopeless:
        return free  # converged, out of time, or stuck far from feasible at a large penalty: cannot be held
    # Cut short or stalled near a solution: go on from there; far from it: from the start.
    from_start = violation > _CONTACT_SET_VIOLATION
    q = start = q if from_start else free.q
    # From the start, the modes held are those of the start's own contact variables (the
    # rigid answer's loads pressing the prints in): W read off that posture leaves every
    # node lifting off, with no force gradient, and the attempt began each ball's share of
    # the weight short (quadruped-foam: 153 -> 133 solver calls and 2,621 -> 2,293 SQP
    # iterations over 10 seeds; no other suite scene took this path). Later attempts
    # start from W read off their posture, where the last attempt's rows held.
    given = lam_init if from_start else None
    held = None  # the modes the last attempt held
    for _ in range(attempts):
        variables = problem.initial_variables(q)  # runs the kinematics at q
        if given is not None:
            variables = given
        pin.computeJointJacobians(model, problem.data, q)  # the print points' Jacobians
        try:
            modes = [contact.freeze_modes(model, problem.data, variables[s]) for contact, s in deformable]
            if held is not None and all(np.array_equal(a, b) for a, b in zip(modes, held)):
                # Where the last attempt stalled the nodes are in the modes it held: the
                # contact set is settled and it is not what fails. Holding the modes again
                # repeats the stall (a palm stance of rail-over-gap: three attempts of 27
                # iterations each, 0.9 s, ending at the same 2.8e-7), and so did the free
                # stage from the start, its 27 iterations the attempt's (the only two
                # final free stages of the suite's 701 Coulomb solves, 10 seeds: neither
                # feasible). The attempt is the answer, unless its iteration cap, not a
                # stall, ended it: the uncapped free stage below goes on.
                if attempt.statistics["status"] != "iteration limit":
                    return replace(attempt, iterations=iterations)
                break
            held = modes
            attempt = solve_problem(problem, q, lam_init=given, max_iterations=_FROZEN_ITERATIONS, deadline=deadline)
        except ContactStateError:
            # A print's contact with no state where an attempt would start: the first stage's
            # answer stands.
            return replace(free, iterations=iterations)
        finally:
            for contact, _ in deformable:
                contact.release_modes()
        iterations += attempt.iterations
        if attempt.feasible or attempt.statistics["status"] == OUT_OF_TIME:
            return replace(attempt, iterations=iterations)
        if attempt.statistics["violation"] > _CONTACT_SET_VIOLATION:
            # Far from feasible: not a matter of the contact set, a stance that cannot be held.
            if from_start and free.statistics["violation"] < attempt.statistics["violation"]:
                # The attempts began from the start, the first stage having ended far
                # too: its answer came closer, and its posture and reason say more
                # (both soles on 3e4 Pa foam: the first stage stops at the strain
                # bound, 4.9 scaled; held modes read at the rigid answer, where the
                # prints barely touch, stop at a 511 N imbalance).
                return replace(free, iterations=iterations)
            return replace(attempt, iterations=iterations)
        q, given = attempt.q, None
    # Where the attempts began from the start (the first stage having crept far from
    # feasible), the first stage goes on from where it stopped, with its own contact
    # variables: W read off a posture leaves every print lifting off with no force, where
    # the SQP stalls (a palm stance leaning on its centre-of-pressure rows, 100 N short on a
    # normal-load bound at zero force), and from the start it would repeat the first
    # stage's iterations (a palm on rail-over-gap's rail: 79 -> 67 iterations; the suite's
    # plans 21,144 -> 21,118, the same calls and stances). Otherwise from where the
    # attempts began, W read off that posture, where the first stage's rows nearly held.
    if from_start:
        last = solve_problem(problem, free.q, lam_init=np.asarray(free.statistics["lambda"]), deadline=deadline)
    else:
        last = solve_problem(problem, start, deadline=deadline)
    return replace(last, iterations=iterations + last.iterations)


def _changed(options) -> dict:
    """The options that differ from their defaults: what a result records, so that
    a later check (``Plan.check``) verifies with what the stance was solved with."""
    defaults = type(options)()  # resolved defaults (a weight may follow another option)
    return {f.name: getattr(options, f.name) for f in fields(options) if getattr(options, f.name) != getattr(defaults, f.name)}


def _time_budget(value) -> float:
    """A validated time budget, seconds."""
    try:
        seconds = float(value)
    except (TypeError, ValueError):
        raise StanceError(f"time_budget must be a number of seconds or None, got {value!r}") from None
    if not seconds > 0 or not np.isfinite(seconds):
        raise StanceError(f"time_budget must be positive and finite seconds (or None), got {value!r}")
    return seconds


def posture_options(options: dict) -> PostureOptions:
    """PostureOptions from keyword arguments, naming the valid ones on a typo."""
    valid = set(PostureOptions.__dataclass_fields__)
    unknown = sorted(set(options) - valid)
    if unknown:
        raise StanceError(f"unknown posture option(s) {unknown}; valid options: {sorted(valid)}")
    return PostureOptions(**options)
