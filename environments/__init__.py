"""Scenes for contact-before-motion planning on rigid and deformable supports.

Rigid objects, deformable (FEM) objects, the contact surfaces on them, stances
(sets of contact prints), goals, and scenario files that put them together.
"""

from .deformable import DeformableObject, RefineLines, soft_box
from .errors import ScenarioError, SceneError
from .goal import Goal, GoalRegion
from .mesh_surfaces import SurfaceSearch, auto_surfaces, find_surfaces
from .objects import RigidObject, box, box_surfaces, floor, mesh_object
from .refinement import refined
from .rigid_twin import rigid_twin
from .scenario import Scenario, builtin_scenario_path, load, load_string, scenario_names
from .scene import Scene
from .soft_mesh import FixedPlane, soft_mesh
from .stance import Contact, ContactPrint, Stance
from .surfaces import ContactSurface, rectangle

__all__ = [
    "Contact",
    "ContactPrint",
    "ContactSurface",
    "DeformableObject",
    "FixedPlane",
    "Goal",
    "GoalRegion",
    "RefineLines",
    "RigidObject",
    "Scenario",
    "ScenarioError",
    "Scene",
    "SceneError",
    "Stance",
    "SurfaceSearch",
    "auto_surfaces",
    "box",
    "box_surfaces",
    "builtin_scenario_path",
    "find_surfaces",
    "floor",
    "load",
    "load_string",
    "mesh_object",
    "rectangle",
    "refined",
    "rigid_twin",
    "scenario_names",
    "soft_box",
    "soft_mesh",
]
