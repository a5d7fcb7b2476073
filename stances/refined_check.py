"""A soft stance solved again on its supports meshed finer: is the answer the mesh's?

A posture found on the default soft meshes carries their discretisation error
(a few percent in a print's force, more in its depth). :func:`check_refined`
takes an answer, meshes every soft object of the scenario ``factor`` times finer
(:func:`environments.refined`) and solves the same stance there from the answer's
posture and contact variables (``stances.solve(q_init=..., lam_init=...)``), so a
user learns how far the coarse answer is from feasible on the finer mesh, whether
a posture nearby holds there, and how much the posture and the soft prints'
forces move: what an independent computation on a converged mesh would say.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

import environments
from fem.errors import ContactStateError

from .errors import StanceError
from .problem import build_problem
from .results import PostureResult
from .stages import posture_options, solve

__all__ = ["RefinedCheck", "check_refined", "soft_robot_surfaces"]

#: ``RefinedCheck.start_row`` where a soft print's contact has no Coulomb state at the
#: answer's posture on the refined meshes (its ``start_violation`` is then inf).
NO_STATE_AT_START = "contact of a soft print with no Coulomb state at the answer's posture"


@dataclass(frozen=True)
class RefinedCheck:
    """An answer on the default meshes against the same stance on meshes ``factor`` times finer.

    Attributes
    ----------
    factor : int
        How many times finer the refined meshes are.
    nodes : tuple of (str, int, int)
        Each soft object's name and node counts, default then refined.
    start_violation : float
        How far the given answer (posture and contact variables) is from holding
        on the refined meshes: its most violated constraint row's violation, in
        that row's units (metres or radians for a print's placement, newtons...);
        0 if it holds there as it is; inf where a soft print's contact has no Coulomb
        state there (very high friction).
    start_row : str
        The label of that row, or ``NO_STATE_AT_START``.
    result : PostureResult
        The stance solved on the refined meshes, started from the answer.
    joint_change : float
        Largest change of the posture, ``max |pin.difference(q, q_refined)|``
        (radians, or metres for the base translation); NaN if infeasible.
    print_forces : tuple of (str, (3,) float, (3,) float)
        Each soft print's robot surface and the total force on the robot
        through it, world frame, newtons: on the default and the refined meshes.
    held : tuple of str
        The robot surfaces whose prints the answer started from held slips (the stance
        before's): over the default meshes' nodes, they start from rest on the refined ones.
    """

    factor: int
    nodes: tuple
    start_violation: float
    start_row: str
    result: PostureResult
    joint_change: float
    print_forces: tuple
    held: tuple = ()

    @property
    def ok(self) -> bool:
        """Whether the stance holds (solved and verified) on the refined meshes."""
        return bool(self.result.feasible)

    @property
    def force_change(self) -> float:
        """Largest change of a soft print's force, relative to the robot's weight
        carried through all soft prints on the default meshes (NaN if infeasible)."""
        if not self.ok or not self.print_forces:
            return float("nan")
        carried = sum(np.linalg.norm(coarse) for _, coarse, _ in self.print_forces)
        change = max(np.linalg.norm(fine - coarse) for _, coarse, fine in self.print_forces)
        return float(change / carried) if carried > 0 else float("nan")

    def lines(self) -> list[str]:
        """A few lines for a person: meshes, the answer's violation there, the re-solve."""
        meshes = ", ".join(f"{name} {coarse:,} -> {fine:,} nodes" for name, coarse, fine in self.nodes)
        if self.start_row == NO_STATE_AT_START:
            start = f"  the answer there as it is: {NO_STATE_AT_START}"
        elif self.start_violation > 0:
            start = (f"  the answer there as it is: {self.start_row} off by {self.start_violation:.3g} (m, rad or N, "
                     "as the row)")
        else:
            start = "  the answer holds there as it is"
        out = [f"meshes refined {self.factor}x: {meshes}", start]
        if self.held:
            out.append(f"  (its kept prints {', '.join(sorted(self.held))} from rest there: their held slips are "
                       "over the coarse mesh's nodes)")
        result = self.result
        if not self.ok:
            out.append(f"  re-solved there: infeasible: {result.reason}")
            return out
        out.append(f"  re-solved there: feasible, verified, {result.iterations} iterations, {result.solve_time:.2f} s; "
                   f"posture moved at most {self.joint_change:.2g} rad or m")
        for surface, coarse, fine in self.print_forces:
            out.append(f"  {surface}: force [{', '.join(f'{v:.1f}' for v in coarse)}] -> "
                       f"[{', '.join(f'{v:.1f}' for v in fine)}] N")
        return out


def check_refined(robot, scenario, result: PostureResult, factor: int = 2, refined=None, **options) -> RefinedCheck:
    """Solve a soft stance's answer again on its scenario's soft meshes ``factor`` times finer.

    Parameters
    ----------
    robot : stances.Robot
    scenario : environments.Scenario
        The scenario ``result`` was solved in (read from a file: its text is refined).
    result : PostureResult
        A feasible answer of :func:`stances.solve` for one of its stances.
    factor : int
        How many times finer (2: every cell halved; the node count grows about 8x).
    refined : environments.Scenario, optional
        ``environments.refined(scenario, factor)`` made already: checks of several
        answers in one scenario (a plan's stances) then share its bodies and their
        factorisations.
    **options
        Posture options; by default those ``result`` was solved with.

    Returns
    -------
    RefinedCheck

    Raises
    ------
    StanceError
        If ``result`` is not feasible, or its stance has no print on a soft surface.
    SceneError
        As :func:`environments.refined` (a scenario built in code, a factor below 2...),
        or a soft object whose own weight strains it beyond its bound on the finer mesh
        (its clamped base's corners strain more as the mesh is refined:
        :attr:`environments.DeformableObject.self_weight_field`).
    """
    if not result.feasible:
        raise StanceError(f"check_refined needs a feasible answer; this one is not: {result.reason}")
    stance = result.stance
    soft = soft_robot_surfaces(scenario.scene, stance)
    if not soft:
        raise StanceError("the stance has no print on a soft surface: nothing to refine")
    options = {**result.statistics.get("options", {}), **options}
    fine = environments.refined(scenario, factor) if refined is None else refined
    lam = np.asarray(result.statistics["lambda"], dtype=float)
    problem = build_problem(robot, fine.scene, stance, posture_options(options))
    if lam.shape != (problem.n_variables,):
        raise StanceError(
            f"the answer has {lam.size} contact variables, the refined problem {problem.n_variables}: "
            "was it solved with other options?"
        )
    try:
        _, start_row, start_violation = problem.evaluate(result.q, lam).worst_row()
    except ContactStateError:
        # At very high friction a refined print's contact may have no Coulomb state at the
        # answer's posture (fem.contact.HIGH_FRICTION): the answer does not hold there as
        # it is; the solve below starts from it all the same and answers for itself.
        start_row, start_violation = NO_STATE_AT_START, float("inf")
    answer = solve(robot, fine.scene, stance, q_init=result.q, lam_init=lam, **options)
    joint_change = (float(np.abs(pin.difference(robot.model, result.q, answer.q)).max())
                    if answer.feasible else float("nan"))
    coarse, refined_forces = _link_forces(robot, result), _link_forces(robot, answer)
    return RefinedCheck(
        factor=factor,
        nodes=tuple((a.name, a.mesh.n_nodes, b.mesh.n_nodes)
                    for a, b in zip(scenario.scene.deformable_objects, fine.scene.deformable_objects)),
        start_violation=start_violation,
        start_row=start_row,
        result=answer,
        joint_change=joint_change,
        print_forces=tuple((s, coarse[s], refined_forces[s]) for s in soft) if answer.feasible else (),
        held=tuple(sorted(getattr(result, "held_slips", None) or {})),
    )


def soft_robot_surfaces(scene, stance) -> tuple:
    """The robot surfaces of a stance whose prints lie on a soft (deformable) surface, in stance order."""
    return tuple(c.robot_surface for c in stance.contacts if scene.surfaces[c.contact_print.surface].deformable)


def _link_forces(robot, result) -> dict:
    """Total force on the robot through each contact surface of the stance, world frame, newtons."""
    totals = {}
    for contact in result.stance.contacts:
        forces = result.forces_on(robot.surface(contact.robot_surface).frame)
        totals[contact.robot_surface] = sum((np.asarray(p.force, dtype=float) for p in forces), np.zeros(3))
    return totals
