"""Talos's palm plates: geometry and mass in the model, and only the plate touches a support."""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ElementTree

import numpy as np
import pinocchio as pin
import pytest

import environments
from clearance import robot_clearances
from conftest import coarse_scenario
from stances import Robot, StanceError
from stances.collision import contact_exclusions
from stances.plates import PlateDeclaration, geometry_reach
from stances.problem import PostureOptions
from stances.description import read_description
from stances.robot import example_robot_data_share
from stances import solve

try:
    import coal
except ImportError:  # pragma: no cover
    import hppfcl as coal

PALMS = ("left_palm", "right_palm")
TALOS = read_description("talos")
THICKNESS = 0.01
# The collision block lets the QP eat 0.1 mm of the clearance (its slack).
CLEARANCE_TOLERANCE = 1e-4 + 1e-9


def _talos_files():
    share = example_robot_data_share()
    talos = share / "example-robot-data" / "robots" / "talos_data"
    return share, talos / "robots" / "talos_reduced.urdf", talos / "srdf" / "talos.srdf"


def _urdf_link_masses():
    _, urdf, _ = _talos_files()
    masses = {}
    for link in ElementTree.parse(urdf).getroot().iter("link"):
        mass = link.find("inertial/mass")
        masses[link.get("name")] = float(mass.get("value")) if mass is not None else 0.0
    return masses


def _distance_to_half_space_below(robot, geometry_name, frame_name):
    """Distance from a geometry to the half-space beyond a frame's xy plane (its -z side),
    measured by coal on the full mesh."""
    model = robot.model
    frame = model.frames[model.getFrameId(frame_name)]
    geometry_model = pin.GeometryModel()
    for geometry_object in robot.collision_model.geometryObjects:
        if geometry_object.name == geometry_name:
            geometry_model.addGeometryObject(geometry_object.copy())
    # A 2 m slab whose top face is the frame's xy plane, fixed to the same joint.
    slab = frame.placement * pin.SE3(np.eye(3), np.array([0.0, 0.0, -1.0]))
    geometry_model.addGeometryObject(pin.GeometryObject("slab", frame.parentJoint, 0, slab, coal.Box(2.0, 2.0, 2.0)))
    geometry_model.addCollisionPair(pin.CollisionPair(0, 1))
    geometry_data = pin.GeometryData(geometry_model)
    q = robot.reference_configuration
    pin.computeDistances(model, model.createData(), geometry_model, geometry_data, q)
    return geometry_data.distanceResults[0].min_distance


@pytest.mark.parametrize("palm", PALMS)
def test_each_palm_is_the_outer_face_of_a_box_plate_on_the_wrist(robot, palm):
    surface = robot.surface(palm)
    assert surface.contact_geometries == (f"{palm}_plate",)
    collision_model = robot.collision_model
    plate = collision_model.geometryObjects[collision_model.getGeometryId(f"{palm}_plate")]
    assert isinstance(plate.geometry, coal.Box)
    np.testing.assert_allclose(plate.geometry.halfSide, [0.05, 0.035, 0.5 * THICKNESS])
    frame_id = robot.frame_id(surface.frame)
    assert plate.parentFrame == frame_id
    side = palm.split("_")[0]
    assert plate.parentJoint == robot.model.getJointId(f"arm_{side}_7_joint")
    # In the contact frame (z into the wrist), the plate spans z in [0, thickness]:
    # the contact surface is its outer face.
    plate_in_contact = robot.model.frames[frame_id].placement.actInv(plate.placement)
    np.testing.assert_allclose(plate_in_contact.rotation, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(plate_in_contact.translation, [0.0, 0.0, 0.5 * THICKNESS], atol=1e-12)


def test_the_grippers_are_gone_and_the_robot_keeps_talos_mass(robot):
    masses = _urdf_link_masses()
    names = [geometry.name for geometry in robot.collision_model.geometryObjects]
    assert not [name for name in names if name.startswith("gripper_")]
    # The reduced model keeps every link's mass (locked joints included): the
    # plates carry the grippers' mass, so the total is the URDF's.
    assert robot.mass == pytest.approx(sum(masses.values()), abs=1e-9)
    for side in ("left", "right"):
        gripper = sum(mass for link, mass in masses.items() if link.startswith(f"gripper_{side}_"))
        assert gripper == pytest.approx(1.18407, abs=1e-9)
        hand = ("arm_{}_7_link", "wrist_{}_ft_link", "wrist_{}_ft_tool_link")
        wrist_joint = robot.model.getJointId(f"arm_{side}_7_joint")
        expected = sum(masses[name.format(side)] for name in hand) + gripper
        assert robot.model.inertias[wrist_joint].mass == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize("palm", PALMS)
def test_the_plate_moves_the_gripper_mass_to_the_plate_centre(robot, palm):
    """Against a Talos built with the gripper kept: same mass on the wrist, its
    first moment shifted by (gripper mass) x (plate centre - gripper centre)."""
    share, urdf, srdf = _talos_files()
    without_plates = [dataclasses.replace(d, plate=None) for d in TALOS.surfaces]
    gripped = Robot.from_urdf("talos", urdf, srdf, [share], without_plates, TALOS.locked_joints)
    side = palm.split("_")[0]
    joint = robot.model.getJointId(f"arm_{side}_7_joint")
    before, after = gripped.model.inertias[joint], robot.model.inertias[joint]
    assert after.mass == pytest.approx(before.mass, abs=1e-12)
    gripper = pin.Inertia.Zero()
    for frame in gripped.model.frames:
        if frame.name.startswith(f"gripper_{side}_"):
            gripper += frame.placement.act(frame.inertia)
    collision_model = robot.collision_model
    plate = collision_model.geometryObjects[collision_model.getGeometryId(f"{palm}_plate")]
    shift = gripper.mass * (plate.placement.translation - gripper.lever)
    np.testing.assert_allclose(after.mass * after.lever - before.mass * before.lever, shift, atol=1e-12)


@pytest.mark.parametrize("palm", PALMS)
def test_the_plate_lies_past_every_other_geometry_of_the_wrist(robot, palm):
    """Measured by coal on the full meshes: with the palm flat on a support, the
    wrist is a plate's thickness away; the forearm mesh (17.0 mm past the flange)
    touches the plate's inner face, so nothing is wasted either."""
    model, collision_model = robot.model, robot.collision_model
    joint = model.frames[robot.frame_id(robot.surface(palm).frame)].parentJoint
    others = [
        geometry.name
        for geometry in collision_model.geometryObjects
        if geometry.parentJoint == joint and geometry.name != f"{palm}_plate"
    ]
    side = palm.split("_")[0]
    assert sorted(others) == sorted(
        [f"arm_{side}_7_link_0", f"wrist_{side}_ft_link_0", f"wrist_{side}_ft_tool_link_0"]
    )
    clearances = {name: _distance_to_half_space_below(robot, name, robot.surface(palm).frame) for name in others}
    assert min(clearances.values()) == pytest.approx(THICKNESS, abs=1e-6)
    # The flange (tool frame) to the palm: 17.03 mm of forearm mesh, then the plate.
    flange = model.frames[model.getFrameId(f"wrist_{side}_ft_tool_link")].placement
    contact = model.frames[robot.frame_id(robot.surface(palm).frame)].placement
    assert flange.actInv(contact).translation[2] == pytest.approx(-(0.01703 + THICKNESS), abs=1e-5)


@pytest.mark.parametrize("sole", ["left_sole", "right_sole"])
def test_the_foot_mesh_is_the_sole_and_reaches_at_most_half_a_millimetre_past_it(robot, sole):
    """The foot mesh's bottom is not exactly flat: a few vertices lie 0.40 mm
    below the sole plane. It is the sole's own contact geometry (the only
    geometry of the foot link); the ankle above stays clear of the ground."""
    side = sole.split("_")[0]
    foot = f"leg_{side}_6_link_0"
    assert robot.surface(sole).contact_geometries == (foot,)
    depth = -_distance_to_half_space_below(robot, foot, robot.surface(sole).frame)
    assert 0.0 < depth < 5e-4
    assert _distance_to_half_space_below(robot, f"leg_{side}_5_link_0", robot.surface(sole).frame) > 0.02


def test_contact_exclusions_exempt_only_the_plate(robot):
    assert contact_exclusions(robot, "right_palm", "cube") == [("right_palm_plate", "cube")]
    assert contact_exclusions(robot, "left_palm_contact", "table") == [("left_palm_plate", "table")]
    # Any other frame: every geometry on its joint, as before.
    frame = contact_exclusions(robot, "wrist_left_ft_tool_link", "table")
    assert sorted(name for name, _ in frame) == sorted(
        ["arm_left_7_link_0", "wrist_left_ft_link_0", "wrist_left_ft_tool_link_0", "left_palm_plate"]
    )


def test_geometry_reach_of_primitives_is_exact(robot):
    cylinder = robot.collision_model.geometryObjects[robot.collision_model.getGeometryId("wrist_left_ft_tool_link_0")]
    # Radius 25 mm, length 9.75 mm, axis along the joint's z; its centre 63.725 mm down.
    assert geometry_reach(cylinder, [0.0, 0.0, -1.0]) == pytest.approx(0.063725 + 0.004875, abs=1e-12)
    assert geometry_reach(cylinder, [1.0, 0.0, 0.0]) == pytest.approx(0.025, abs=1e-12)


@pytest.mark.parametrize(
    "plate",
    [
        dict(thickness=0.0), dict(thickness=-0.01), dict(thickness=float("nan")), dict(thickness=0.01, mass=-1.0),
        dict(thickness=0.01, replaces=["RFinger", ""]), dict(thickness=0.01, replaces=3),
    ],
)
def test_bad_plates_are_rejected(plate):
    with pytest.raises(StanceError, match="plate"):
        PlateDeclaration(**plate)


def test_a_plate_cannot_replace_a_moving_part():
    share, urdf, srdf = _talos_files()
    with pytest.raises(StanceError, match="gripper_left_joint"):
        Robot.from_urdf("talos", urdf, srdf, [share], TALOS.surfaces, ("head_1_joint", "head_2_joint"))


def _palm_stances():
    """Every named stance of the built-in scenarios with a palm on something, and
    the climb's start (the gripper used to sit inside the soft box there)."""
    cases = [("climb-with-soft-support", "start")]
    for name in environments.scenario_names():
        scenario = environments.load_string(environments.builtin_scenario_path(name).read_text(), name=name)
        for stance_name, stance in scenario.stances.items():
            if any(contact.robot_surface in PALMS for contact in stance):
                cases.append((name, stance_name))
    return cases


PALM_STANCES = _palm_stances()


@pytest.fixture(scope="module")
def romeo():
    return Robot.load("romeo")


@pytest.fixture(scope="module")
def icub():
    return Robot.load("icub")


@pytest.mark.parametrize("scenario_name, stance_name", PALM_STANCES, ids=[f"{a}/{b}" for a, b in PALM_STANCES])
def test_only_the_contact_geometry_comes_near_a_support(robot, romeo, icub, scenario_name, stance_name):
    """In every accepted palm stance, each robot geometry but a surface's own is at
    least collision_distance from every scene object: the solver's convex hulls
    cannot hide a wrist inside the table, coal on the full meshes would see it.
    Soft objects are measured at rest (what the solver keeps clear) and deformed."""
    scenario = coarse_scenario(scenario_name)
    robot = {"talos": robot, "romeo": romeo, "icub": icub}[scenario.robot]
    stance = scenario.stance(stance_name)
    result = solve(robot, scenario.scene, stance)
    if not result.feasible:
        # A coarse mesh can leave a stance just short of convergence (climb's
        # hand-on-cube stops 1e-8 rad off its print): use the scenario's own mesh.
        scenario = environments.load(scenario_name)
        result = solve(robot, scenario.scene, stance)
    assert result.feasible, result.reason
    minimum = PostureOptions().collision_distance - CLEARANCE_TOLERANCE
    for deformations in (None, result.deformations or None):
        clearances = robot_clearances(robot, scenario.scene, stance, result.q, deformations)
        close = {pair: distance for pair, distance in clearances.items() if distance < minimum}
        assert not close, close


@pytest.mark.parametrize("side", ["left", "right"])
def test_romeo_palm_is_a_plate_in_place_of_the_fingers_just_past_the_palm_mesh(romeo, side):
    """Romeo's hand mesh is domed on both faces, so its locked fingers and thumb
    (massless in the URDF) give way to a plate: the robot keeps its URDF mass,
    the plate is the palm's only contact geometry, and on the full mesh the palm
    lies exactly a plate thickness behind the contact plane."""
    palm, letter = f"{side}_palm", side[0].upper()
    surface = romeo.surface(palm)
    assert (surface.role, surface.limb) == ("hand", f"{side}_arm")
    assert surface.contact_geometries == (f"{palm}_plate",)
    model, collision_model = romeo.model, romeo.collision_model
    joint = model.frames[romeo.frame_id(surface.frame)].parentJoint
    assert model.names[joint] == f"{letter}WristPitch"
    names = [geometry.name for geometry in collision_model.geometryObjects]
    assert not [name for name in names if name.startswith((f"{letter}Finger", f"{letter}Thumb"))]
    others = [g.name for g in collision_model.geometryObjects if g.parentJoint == joint and g.name != f"{palm}_plate"]
    assert others == [f"{side[0]}_wrist_0"]
    assert _distance_to_half_space_below(romeo, others[0], surface.frame) == pytest.approx(THICKNESS, abs=1e-6)
    # The plate under the palm's centre: 8 cm along the fingers, 6 cm across.
    plate = collision_model.geometryObjects[collision_model.getGeometryId(f"{palm}_plate")]
    np.testing.assert_allclose(plate.geometry.halfSide, [0.04, 0.03, 0.5 * THICKNESS])
    np.testing.assert_allclose(model.frames[romeo.frame_id(surface.frame)].placement.translation[:2], [0.065, 0.0])
    description = read_description("romeo")
    urdf_mass = sum(
        float(mass.get("value")) for mass in ElementTree.parse(description.urdf).getroot().iter("mass")
    )
    assert romeo.mass == pytest.approx(urdf_mass, abs=1e-9)


@pytest.mark.parametrize("side", ["left", "right"])
def test_icub_palm_is_the_flat_face_of_its_hand_box_without_a_plate(icub, side):
    """iCub's hand is a box with a flat palm face: the surface is that face, on the
    side of the URDF's palm frame, and the box is its contact geometry; no plate,
    so iCub keeps its URDF mass."""
    palm = f"{side}_palm"
    surface = icub.surface(palm)
    assert (surface.role, surface.limb) == ("hand", f"{side}_arm")
    assert surface.contact_geometries == (f"{side[0]}_hand_0",)
    names = [geometry.name for geometry in icub.collision_model.geometryObjects]
    assert not [name for name in names if name.endswith("_plate")]
    # The whole hand box lies behind the contact plane, its palm face on it.
    assert _distance_to_half_space_below(icub, f"{side[0]}_hand_0", surface.frame) == pytest.approx(0.0, abs=1e-6)
    model = icub.model
    frame = model.frames[icub.frame_id(surface.frame)]
    dh = model.frames[model.getFrameId(f"{side[0]}_hand_dh_frame")]
    assert frame.parentJoint == dh.parentJoint
    # The URDF's palm frame lies 3.9 mm beyond the face, on its outer side.
    assert (frame.placement.inverse() * dh.placement).translation[2] == pytest.approx(-0.0039, abs=1e-4)
    urdf_mass = sum(
        float(mass.get("value")) for mass in ElementTree.parse(read_description("icub").urdf).getroot().iter("mass")
    )
    assert icub.mass == pytest.approx(urdf_mass, abs=1e-9)


def test_clearance_helper_measures_a_mesh_object_like_its_box(robot):
    """The independent clearance helper takes any rigid object: the table as its
    plain triangle mesh gives the distances of the table as a box."""
    import dataclasses
    from types import SimpleNamespace

    scenario = environments.load("hand-on-table")
    stance = scenario.stance("hand-on-table")
    q = solve(robot, scenario.scene, stance).q
    as_box = robot_clearances(robot, scenario.scene, stance, q)
    objects = dict(scenario.scene.objects)
    objects["table"] = dataclasses.replace(objects["table"], box_size=None)
    as_mesh = robot_clearances(robot, SimpleNamespace(objects=objects, surface=scenario.scene.surface), stance, q)
    table = [key for key in as_box if key[1] == "table"]
    assert table and set(as_mesh) == set(as_box)
    assert max(abs(as_box[key] - as_mesh[key]) for key in table) < 1e-5
