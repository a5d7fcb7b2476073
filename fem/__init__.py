"""Linear elasticity on linear tetrahedra for deformable contact supports.

Implements section II and eqs. (22)-(44) of Bouyarmane & Kheddar, "FEM-based static
posture planning for a humanoid robot on deformable contact support": a body is a
tetrahedral mesh, a material and a fixed base; a contact print is a set of surface
nodes displaced by a robot link; the forces pushing back on the robot are linear in
the print displacements, with an exact, cached Jacobian.
"""

from .assembly import assemble_stiffness, element_stiffness_matrices, element_strain_matrices
from .contact import LIFT, SLIP, STICK, PrintContact, PrintContactSystem, print_contact_with_modes, solve_print_contact
from .body import DeformableBody, rotate_voigt, voigt_to_tensor_strain, von_mises
from .cache import DiskCache
from .deadline import SetupTimeout, check_deadline, deadline
from .errors import BoundaryError, ContactStateError, FemError, FemWarning, MaterialError, MeshError, PrintError, SolverError
from .io import read_mesh, write_mesh, write_pvd
from .layer_contact import BallOnLayer, sphere_on_layer_force
from .layer_strain import LayerBallStrain, axisymmetric_layer_field
from .material import LOCKING_POISSON_RATIO, LinearElasticMaterial
from .mesh import TetMesh
from .meshing import box_mesh, graded_coordinates, mesh_from_surface, tensor_mesh
from .patch import ContactPatch
from .pressure_loads import hertz_load_shares, pressure_corners, pressure_fit
from .prints import MINIMUM_COVERAGE, coverage_reach, nodes_in_polygon, print_coverage, split_shared_nodes
from .solvers import available_solvers
from .strain_average import frobenius_norms

__all__ = [
    "FemError",
    "MeshError",
    "MaterialError",
    "BoundaryError",
    "PrintError",
    "SolverError",
    "ContactStateError",
    "FemWarning",
    "LOCKING_POISSON_RATIO",
    "TetMesh",
    "box_mesh",
    "tensor_mesh",
    "graded_coordinates",
    "mesh_from_surface",
    "read_mesh",
    "write_mesh",
    "write_pvd",
    "LinearElasticMaterial",
    "MINIMUM_COVERAGE",
    "element_strain_matrices",
    "element_stiffness_matrices",
    "assemble_stiffness",
    "DeformableBody",
    "DiskCache",
    "SetupTimeout",
    "deadline",
    "check_deadline",
    "ContactPatch",
    "sphere_on_layer_force",
    "BallOnLayer",
    "LayerBallStrain",
    "axisymmetric_layer_field",
    "hertz_load_shares",
    "pressure_corners",
    "pressure_fit",
    "von_mises",
    "voigt_to_tensor_strain",
    "frobenius_norms",
    "rotate_voigt",
    "nodes_in_polygon",
    "print_coverage",
    "split_shared_nodes",
    "coverage_reach",
    "available_solvers",
    "PrintContact",
    "PrintContactSystem",
    "solve_print_contact",
    "print_contact_with_modes",
    "STICK",
    "SLIP",
    "LIFT",
]
