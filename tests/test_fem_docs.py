"""The Examples sections of the fem docstrings run and give what they show."""

import doctest
import importlib

import pytest

MODULES = ["fem.material", "fem.meshing", "fem.assembly", "fem.body", "fem.prints"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_run(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0


def test_public_api_is_exported():
    import fem

    for name in fem.__all__:
        assert hasattr(fem, name), name
    for name in ("FemError", "TetMesh", "box_mesh", "tensor_mesh", "read_mesh", "write_mesh",
                 "mesh_from_surface", "LinearElasticMaterial", "element_strain_matrices",
                 "assemble_stiffness", "DeformableBody", "ContactPatch", "nodes_in_polygon"):
        assert name in fem.__all__
    assert issubclass(fem.FemError, ValueError)
