"""Static postures of a humanoid in multi-contact stances, rigid or deformable.

Build a problem, solve it, check it::

    >>> import environments, stances
    >>> scenario = environments.load("stand")
    >>> robot = stances.Robot.load("talos")
    >>> result = stances.solve(robot, scenario.scene, scenario.stance("stand"))
    >>> result.feasible, stances.verify(robot, scenario.scene, result.stance, result).ok
    (True, True)
"""

from .cold_start import initial_configuration, reaching_configuration
from .description import (
    RobotDescription,
    RobotDescriptionError,
    SupportRule,
    builtin_robot_names,
    read_description,
    read_description_text,
)
from .errors import ConfigurationError, FrameNotFound, RobotNotFound, StanceError
from .problem import PostureOptions, PostureProblem, build_problem
from .results import NodeSlips, PointForce, PostureResult, SolveStatistics, Verification
from .refined_check import RefinedCheck, check_refined
from .robot import Robot, RobotSurface, SurfaceDeclaration
from .sqp import solve_problem
from .stages import kept_slips, solve
from .terms import CentreOfMassBounds
from .verify import verify, verify_problem

__all__ = [
    "CentreOfMassBounds",
    "ConfigurationError",
    "FrameNotFound",
    "NodeSlips",
    "PointForce",
    "PostureOptions",
    "PostureProblem",
    "PostureResult",
    "SolveStatistics",
    "RefinedCheck",
    "Robot",
    "RobotDescription",
    "RobotDescriptionError",
    "RobotNotFound",
    "RobotSurface",
    "StanceError",
    "SupportRule",
    "SurfaceDeclaration",
    "Verification",
    "build_problem",
    "builtin_robot_names",
    "check_refined",
    "initial_configuration",
    "kept_slips",
    "reaching_configuration",
    "read_description",
    "read_description_text",
    "solve",
    "solve_problem",
    "verify",
    "verify_problem",
]
