"""Static postures of a humanoid in multi-contact stances, rigid or deformable."""

from .errors import ConfigurationError, FrameNotFound, RobotNotFound, StanceError
from .robot import Robot, RobotSurface, SurfaceDeclaration

__all__ = [
    "ConfigurationError",
    "FrameNotFound",
    "Robot",
    "RobotNotFound",
    "RobotSurface",
    "StanceError",
    "SurfaceDeclaration",
]
