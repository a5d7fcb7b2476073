"""Robots as data: built-in descriptions, a description file of another robot, bad files, reach."""

import re
import textwrap

import numpy as np
import pinocchio as pin
import pytest
import yaml

import environments
import stances
from environments.errors import ScenarioError
from stances import Robot, RobotDescriptionError, RobotNotFound, StanceError
from stances.collision import _robot_geometry
from stances.description import BUILTIN_DIRECTORY, builtin_robot_names, example_robot_data_share, read_description
from stances.problem import PostureOptions, build_problem

from cbm.cli import EXIT_BAD_INPUT, main
from cbm.plan import Plan
from cbm.planner import plan
from cbm.reach import ReachModel
from cbm.sampling import obstacle_boxes, options_from_scenario, sample_prints

BUILTIN = ["talos", "romeo", "icub"]


@pytest.fixture(scope="module")
def romeo():
    return Robot.load("romeo")


@pytest.fixture(scope="module")
def icub():
    return Robot.load("icub")


@pytest.fixture(scope="module")
def feet_only_romeo_file(tmp_path_factory):
    """Romeo's description without its palms: a robot that stands but has no hand."""
    data = yaml.safe_load((BUILTIN_DIRECTORY / "romeo.yaml").read_text())
    data["surfaces"] = {name: surface for name, surface in data["surfaces"].items() if surface["role"] == "foot"}
    data["limbs"] = {limb: joint for limb, joint in data["limbs"].items() if limb.endswith("_leg")}
    return _write(tmp_path_factory.mktemp("feet_only") / "romeo.yaml", data)


@pytest.fixture(scope="module")
def feet_only_romeo(feet_only_romeo_file):
    return Robot.load(feet_only_romeo_file)


@pytest.mark.parametrize("name", BUILTIN)
def test_each_builtin_description_loads_its_surfaces_limbs_and_locked_joints(name, robot, romeo, icub):
    loaded = {"talos": robot, "romeo": romeo, "icub": icub}[name]
    description = read_description(name)
    assert name in builtin_robot_names()
    assert [(s.name, s.role, s.limb) for s in loaded.surfaces.values()] == [
        (s.name, s.role, s.limb) for s in description.surfaces
    ]
    assert loaded.limbs == description.limbs
    # Every locked joint left the model: one degree of freedom each.
    full = pin.buildModelFromUrdf(str(description.urdf), pin.JointModelFreeFlyer())
    assert loaded.nv == full.nv - len(description.locked_joints)
    # At the reference posture the feet are level and their contact frames'
    # z axes point up, into the feet (the contact-frame convention), within
    # 0.3 degrees (Talos's half-sitting tilts its feet by 1.7 mrad); iCub's SRDF
    # half-sitting pitches both soles by 3.6 degrees (0.063 rad), its posture solves level them.
    tilt = {"icub": 0.065}.get(name, 5e-3)
    data = loaded.model.createData()
    pin.framesForwardKinematics(loaded.model, data, loaded.reference_configuration)
    feet = [data.oMf[loaded.frame_id(loaded.surfaces[f].frame)] for f in loaded.surfaces_with_role("foot")]
    assert len(feet) == 2
    assert abs(feet[0].translation[2] - feet[1].translation[2]) < 1e-3
    for foot in feet:
        np.testing.assert_allclose(foot.rotation[:, 2], [0.0, 0.0, 1.0], atol=tilt)
    # Each limb's root joint is above its surfaces in the kinematic tree.
    for surface in loaded.surfaces.values():
        joint = loaded.model.frames[loaded.frame_id(surface.frame)].parentJoint
        chain = []
        while joint > 0:
            chain.append(loaded.model.names[joint])
            joint = loaded.model.parents[joint]
        assert loaded.limbs[surface.limb] in chain


@pytest.mark.parametrize("name, feet_apart, kilograms", [("romeo", 0.096, 40.5), ("icub", 0.105, 28.3)])
def test_a_humanoid_stands_on_the_floor_with_a_verified_posture(request, name, feet_apart, kilograms):
    robot = request.getfixturevalue(name)
    scenario = environments.load_string(
        textwrap.dedent(
            f"""
            robot: {name}
            objects: [{{name: floor, type: floor}}]
            stances:
              stand:
                left_sole: {{surface: floor, x: 0.0, y: {feet_apart}}}
                right_sole: {{surface: floor, x: 0.0, y: {-feet_apart}}}
            """
        )
    )
    result = stances.solve(robot, scenario.scene, scenario.stance("stand"))
    assert result.feasible, result.reason
    assert stances.verify(robot, scenario.scene, result.stance, result).ok
    # Both feet carry the robot's weight.
    assert robot.mass == pytest.approx(kilograms, abs=0.05)
    vertical = sum(f.force[2] for f in result.point_forces)
    assert vertical == pytest.approx(robot.mass * 9.81, rel=1e-6)


def _world_vertices(robot, q, geometry_name):
    """(n, 3) world vertices of a collision mesh at configuration ``q``."""
    model, data = robot.model, robot.model.createData()
    pin.forwardKinematics(model, data, q)
    geometry = robot.collision_model.geometryObjects[robot.collision_model.getGeometryId(geometry_name)]
    placement = data.oMi[geometry.parentJoint] * geometry.placement
    return np.asarray(geometry.geometry.vertices()) @ placement.rotation.T + placement.translation


def test_icub_meshes_lie_where_its_kinematics_puts_its_links(icub):
    """example-robot-data's iCub meshes come out of the loader a quarter turn about
    their x axis; icub.yaml's mesh_rotations turn them back: each limb segment's
    mesh holds the joints its link joins, the foot's bottom face lies on the sole
    plane and runs along the sole's x (as loaded it ran sideways), and the hands,
    left as loaded, are boxes thin along the wrist yaw axis."""
    q = icub.reference_configuration
    data = icub.model.createData()
    pin.framesForwardKinematics(icub.model, data, q)

    def joint(name):
        return data.oMi[icub.model.getJointId(name)].translation

    for side in "lr":
        for mesh, ends in ((f"{side}_upper_leg_0", ("hip_yaw", "knee")), (f"{side}_lower_leg_0", ("knee", "ankle_pitch")),
                           (f"{side}_upper_arm_0", ("shoulder_yaw", "elbow")),
                           (f"{side}_forearm_0", ("wrist_prosup", "wrist_pitch"))):
            points = _world_vertices(icub, q, mesh)
            for end in ends:
                assert np.all(points.min(axis=0) - 1e-3 <= joint(f"{side}_{end}")), (mesh, end)
                assert np.all(joint(f"{side}_{end}") <= points.max(axis=0) + 1e-3), (mesh, end)
        sole = data.oMf[icub.frame_id(f"{side}_sole")]
        foot = (_world_vertices(icub, q, f"{side}_foot_0") - sole.translation) @ sole.rotation
        assert foot[:, 2].min() == pytest.approx(0.0, abs=1e-4)
        bottom = foot[foot[:, 2] < 1e-4]
        assert np.ptp(bottom[:, 0]) > 0.15 and np.ptp(bottom[:, 1]) < 0.065  # 15.6 cm long, 6.1 cm wide
        hand = data.oMi[icub.model.getJointId(f"{side}_wrist_yaw")]
        box = (_world_vertices(icub, q, f"{side}_hand_0") - hand.translation) @ hand.rotation
        np.testing.assert_allclose(np.ptp(box, axis=0), [0.069, 0.065, 0.0243], atol=1e-3)


def test_icub_steps_onto_foot_on_blocks_block_beyond_its_step_height(icub):
    """foot-on-block's 0.2 m block is past iCub's step height by the reach model
    (0.37 x 0.48 m legs = 0.18 m) but iCub holds the goal stance: the planner offers
    the goal's last step and the posture solve accepts it."""
    reach = ReachModel.of(icub)
    assert reach.limits.step_height * reach.limbs["right_leg"].length < 0.2
    result = plan("foot-on-block", robot=icub, max_expansions=10, print_spacing=0.1)  # a coarse grid: quicker
    assert result.success, result.reason
    assert [planned.move for planned in result.stances][1:] == [
        "lift right_sole", "place right_sole on block_top at x -0.020 m, y 0.020 m, theta 0 deg in block_top's frame",
    ]


def test_a_pair_nearer_than_the_solver_keeps_at_the_reference_is_not_checked(icub, tmp_path):
    """iCub's pelvis and left hip-pitch disc hulls are 0.6 mm apart at the reference
    posture and at any hip pitch (the disc turns about its own axis): under the 5 mm
    the solver keeps, so that pair would fail every stance. Loading leaves such pairs
    unchecked, as those already touching; checked_pairs keeps one checked."""
    from stances.collision import KEPT_DISTANCE, CollisionChecker

    pair = ("root_link_0", "l_hip_1_0")
    listed = yaml.safe_load((BUILTIN_DIRECTORY / "icub.yaml").read_text())
    data = {key: value for key, value in listed.items() if key != "ignored_pairs"}
    found = Robot.load(_write(tmp_path / "icub-found.yaml", data))
    # The built-in file lists exactly the pairs the loader finds (so it does not warn at every load).
    assert {frozenset(p) for p in found.ignored_pairs} == {frozenset(p) for p in listed["ignored_pairs"]}
    checked = Robot.load(_write(tmp_path / "icub.yaml", {**data, "checked_pairs": [list(pair)]}))
    checker = CollisionChecker(checked, [], margin=KEPT_DISTANCE)

    def distance(q):
        pinocchio_data = checked.model.createData()
        pin.forwardKinematics(checked.model, pinocchio_data, q)
        (measured,) = [
            p.distance for p in checker.pairs(checked.model, pinocchio_data) if {p.name_a, p.name_b} == set(pair)
        ]
        return measured

    q = np.array(icub.reference_configuration)
    assert 0.0 < distance(q) < KEPT_DISTANCE
    q[icub.model.idx_qs[icub.model.getJointId("l_hip_pitch")]] += 0.5
    assert 0.0 < distance(q) < KEPT_DISTANCE
    assert pair in icub.ignored_pairs and pair not in checked.ignored_pairs
    names = [g.name for g in icub.collision_model.geometryObjects]
    assert frozenset(pair) not in {frozenset((names[p.first], names[p.second])) for p in icub.collision_model.collisionPairs}


def _talos_data():
    return yaml.safe_load((BUILTIN_DIRECTORY / "talos.yaml").read_text())


def _write(path, data):
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_a_description_file_of_another_robot_plans_by_role(tmp_path):
    """Talos's model with feet only, called ``paw_a`` and ``paw_b`` (no side or
    "sole" in their names), from a scenario naming the file: the planner walks it
    forward, telling the feet apart by role and the sides by the hips."""
    data = _talos_data()
    data["name"] = "pawed"
    data["surfaces"] = {
        "paw_a": {**data["surfaces"]["left_sole"], "limb": "a"},
        "paw_b": {**data["surfaces"]["right_sole"], "limb": "b"},
    }
    data["limbs"] = {"a": "leg_left_1_joint", "b": "leg_right_1_joint"}
    del data["checked_pairs"]
    _write(tmp_path / "pawed.yaml", data)
    scenario_path = tmp_path / "walk.yaml"
    scenario_path.write_text(
        textwrap.dedent(
            """
            robot: pawed.yaml
            objects: [{name: floor, type: floor, size: [3, 2]}]
            stances:
              start:
                paw_a: {surface: floor, x: 0.0, y: 0.085}
                paw_b: {surface: floor, x: 0.0, y: -0.085}
            start: start
            goal:
              regions:
                - {robot_surface: paw_a, lower: [0.3, 0.0], upper: [0.7, 0.5]}
                - {robot_surface: paw_b, lower: [0.3, -0.5], upper: [0.7, 0.0]}
            options: {print_spacing: 0.1, sampling_region: {lower: [-0.3, -0.4], upper: [0.8, 0.4]}}
            """
        )
    )
    scenario = environments.load(scenario_path)
    assert scenario.robot == str(tmp_path / "pawed.yaml")
    result = plan(scenario, max_expansions=30, time_limit=240.0, solver_options={"max_iterations": 40})
    assert result.success, result.reason
    # Both feet move at least 0.3 m: lift and place each, from the start.
    assert len(result.stances) >= 5
    assert scenario.goal.is_satisfied(result.stances[-1].stance, scenario.scene)
    # The plan names its robot's file, and its check loads that robot again.
    assert result.robot["source"] == str(tmp_path / "pawed.yaml")
    assert Plan.from_dict(result.to_dict()).robot == result.robot
    assert result.check(scenario).ok
    for planned in result.stances:
        assert planned.stance.robot_surfaces  # never airborne
        if len(planned.stance) == 2:
            a, b = (planned.stance.contact(name).contact_print for name in ("paw_a", "paw_b"))
            assert a.y > b.y  # paw_a stays on the left, as its hip


BAD_DESCRIPTIONS = {
    "missing link": (
        lambda d: d["surfaces"]["left_sole"].update(link="no_such_link"),
        "robot surface 'left_sole': unknown frame 'no_such_link'; known frames: ",
    ),
    "unknown role": (
        lambda d: d["surfaces"]["left_sole"].update(role="paw"),
        "surfaces.left_sole.role: unknown role 'paw'; roles: foot, hand",
    ),
    "clockwise polygon": (
        lambda d: d["surfaces"]["left_sole"].update(polygon=d["surfaces"]["left_sole"]["polygon"][::-1]),
        "surfaces.left_sole: robot surface 'left_sole': polygon must be convex with its vertices counter-clockwise",
    ),
    "two-vertex polygon": (
        lambda d: d["surfaces"]["left_sole"].update(polygon=[[0, 0], [1, 0]]),
        "surfaces.left_sole.polygon: must be a list of at least 3 [x, y] vertices, got a list of 2",
    ),
    "unknown limb": (
        lambda d: d["surfaces"]["left_sole"].update(limb="tail"),
        "surfaces.left_sole.limb: unknown limb 'tail'; limbs: left_leg, right_leg, left_arm, right_arm",
    ),
    "limb root not above the surface": (
        lambda d: d["limbs"].update(left_leg="arm_left_1_joint"),
        "robot surface 'left_sole' on limb 'left_leg' is not below the limb's root joint 'arm_left_1_joint'",
    ),
    "polygon and point": (
        lambda d: d["surfaces"]["left_sole"].update(point={"radius": 0.02}),
        "surfaces.left_sole: give its shape: either polygon (a sole, a palm) or point (a point foot), not both",
    ),
    "zero point radius": (
        lambda d: d["surfaces"]["left_sole"].pop("polygon") and d["surfaces"]["left_sole"].update(point={"radius": 0}),
        "surfaces.left_sole.point.radius: must be a positive number of metres, got int 0",
    ),
    "unknown contact geometry": (
        lambda d: d["surfaces"]["left_sole"].update(geometries=["no_such_geometry"]),
        "robot surface 'left_sole': unknown collision geometry 'no_such_geometry'; known collision geometrys: ",
    ),
    "pair both checked and ignored": (
        lambda d: d.update(ignored_pairs=[d["checked_pairs"][0][::-1]]),
        "ignored_pairs: pairs both checked and ignored: [('arm_left_5_link_0', 'wrist_left_ft_link_0')]",
    ),
    "unknown ignored geometry": (
        lambda d: d.update(ignored_pairs=[["no_such_geometry", "base_link_0"]]),
        "unknown collision geometry 'no_such_geometry'; known collision geometrys: ",
    ),
    "mesh rotation of an unknown link": (
        lambda d: d.update(mesh_rotations=[{"links": ["no_such_link"], "rpy_deg": [90, 0, 0]}]),
        "mesh_rotations: unknown link 'no_such_link'; known links: ",
    ),
    "mesh rotation of a link without a mesh": (
        lambda d: d.update(mesh_rotations=[{"links": ["left_sole_link"], "rpy_deg": [90, 0, 0]}]),
        "mesh_rotations: link 'left_sole_link' has no collision mesh to turn; links with meshes: arm_left_1_link,",
    ),
    "mesh rotation of two angles": (
        lambda d: d.update(mesh_rotations=[{"links": ["base_link"], "rpy_deg": [90, 0]}]),
        "mesh_rotations[0].rpy_deg: must be a list of 3 numbers, got a list of 2",
    ),
    "link turned twice": (
        lambda d: d.update(mesh_rotations=[{"links": ["base_link"], "rpy_deg": [90, 0, 0]},
                                           {"links": ["base_link"], "rpy_deg": [0, 90, 0]}]),
        "mesh_rotations: link 'base_link' is listed twice; give each link one rotation",
    ),
    "support load not a share": (
        lambda d: d.update(support={"role": "foot", "keep": 1, "load": 1.5}),
        "support 'load' must be a share of the robot's weight in [0, 1), got 1.5",
    ),
    "support load the feet cannot all carry": (
        lambda d: d.update(support={"role": "foot", "keep": 1, "load": 0.5}),
        "robot 'talos': the support rule asks each of its 2 foot surfaces to carry 0.5 of the weight, 1 in all "
        "when all touch; give a 'load' below 0.5",
    ),
    "unknown key": (
        lambda d: d["surfaces"]["left_sole"].update(colour="red"),
        "surfaces.left_sole.colour: unknown key 'colour'; valid keys: role, limb, link, xyz, rpy_deg, polygon, point, plate, geometries",
    ),
}


@pytest.mark.parametrize("case", BAD_DESCRIPTIONS, ids=list(BAD_DESCRIPTIONS))
def test_a_bad_description_file_gets_an_error_naming_the_file_and_the_fault(tmp_path, case):
    change, message = BAD_DESCRIPTIONS[case]
    data = _talos_data()
    change(data)
    path = _write(tmp_path / "bad.yaml", data)
    with pytest.raises(RobotDescriptionError, match=re.escape(message)) as caught:
        Robot.load(path)
    assert str(caught.value).startswith(str(path))


def test_a_surface_given_twice_in_a_description_file_is_refused(tmp_path):
    text = (BUILTIN_DIRECTORY / "talos.yaml").read_text()
    start = text.index("  left_sole:")
    block = text[start:text.index("\n  right_sole:", start) + 1]
    path = tmp_path / "twice.yaml"
    path.write_text(text.replace(block, block + block, 1))
    with pytest.raises(RobotDescriptionError, match="'left_sole' is given twice") as caught:
        Robot.load(path)
    assert str(caught.value).startswith(str(path))


def test_a_surface_whose_contact_frame_name_the_model_already_has_is_refused(tmp_path):
    """Each robot surface gets a contact frame ``<surface>_contact``; a model with a frame
    of that name (here Talos with its left sole link renamed so) would get two, and every
    lookup by name would fail inside pinocchio ("Several frames match the filter"): the
    description is refused, naming the surface and the frame."""
    share = example_robot_data_share()
    talos = share / "example-robot-data" / "robots" / "talos_data"
    for source, target in (("robots/talos_reduced.urdf", "talos.urdf"), ("srdf/talos.srdf", "talos.srdf")):
        (tmp_path / target).write_text((talos / source).read_text().replace("left_sole_link", "left_sole_contact"))
    data = _talos_data()
    data["model"] = {"urdf": "talos.urdf", "srdf": "talos.srdf", "package_dirs": [str(share)]}
    data["surfaces"]["left_sole"]["link"] = "left_sole_contact"
    path = _write(tmp_path / "clash.yaml", data)
    with pytest.raises(RobotDescriptionError, match=re.escape(
            "robot surface 'left_sole': its contact frame would be named 'left_sole_contact', which the robot's "
            "model already has; give the surface another name")):
        Robot.load(path)


def test_an_unknown_robot_name_lists_the_builtin_robots():
    with pytest.raises(RobotNotFound, match=re.escape(
        "unknown robot 'tals' (not a built-in robot); built-in robots: anymal, icub, romeo, talos"
    )):
        Robot.load("tals")


def test_a_stance_naming_a_surface_the_robot_lacks_is_refused_before_planning(feet_only_romeo):
    path = environments.builtin_scenario_path("hand-on-table")
    line = next(i for i, text in enumerate(path.read_text().splitlines(), 1) if text.strip().startswith("right_palm:"))
    expected = (
        f"{path}:{line}: stances.hand-on-table.right_palm: robot surface 'right_palm' is not a surface of "
        "robot 'romeo'; its surfaces: left_sole, right_sole"
    )
    with pytest.raises(ScenarioError) as caught:
        plan("hand-on-table", robot=feet_only_romeo)
    assert str(caught.value) == expected


def test_a_goal_region_naming_a_surface_the_robot_lacks_is_refused(feet_only_romeo):
    scenario = environments.load_string(
        textwrap.dedent(
            """
            objects: [{name: floor, type: floor}]
            stances: {stand: {left_sole: {surface: floor, y: 0.1}, right_sole: {surface: floor, y: -0.1}}}
            goal: {regions: [{robot_surface: left_hand, lower: [0, 0], upper: [1, 1]}]}
            """
        )
    )
    with pytest.raises(ScenarioError, match=re.escape(
        "<scenario>:4: goal.regions[0].robot_surface: robot surface 'left_hand' is not a surface of robot 'romeo'; "
        "its surfaces: left_sole, right_sole"
    )):
        scenario.check_robot_surfaces(feet_only_romeo.surfaces, "robot 'romeo'")


def test_the_command_line_takes_a_robot_and_refuses_a_scenario_it_cannot_stand(capsys, feet_only_romeo_file):
    assert main(["check", "hand-on-table", "--stance", "stand", "--robot", str(feet_only_romeo_file)]) == EXIT_BAD_INPUT
    error = capsys.readouterr().err
    assert "robot surface 'right_palm' is not a surface of robot 'romeo'; its surfaces: left_sole, right_sole" in error
    assert main(["robots"]) == 0
    listed = capsys.readouterr().out
    assert all(name in listed for name in BUILTIN)
    assert "left_palm (hand, left_arm)" in listed
    # Romeo's palms as well as Talos's.
    romeo_entry = listed[listed.index("romeo"):]
    assert "right_palm (hand, right_arm)" in romeo_entry[: romeo_entry.index("talos")]


def test_a_scenario_naming_a_missing_robot_file_is_a_scenario_error(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text("robot: nowhere.yaml\nobjects: [{name: floor, type: floor}]\nstances: {s: {a: {surface: floor}}}\n")
    with pytest.raises(ScenarioError, match=re.escape(f"s.yaml:1: robot: robot description file not found: {tmp_path / 'nowhere.yaml'}")):
        environments.load(path)


def test_talos_feet_by_role_go_where_soles_went_by_name(robot):
    """The built-in roles agree with the names' old reading (``sole`` = foot), and
    feet get prints only on surfaces facing up, hands anywhere they fit."""
    assert {name: s.role for name, s in robot.surfaces.items()} == {
        name: "foot" if "sole" in name else "hand" for name in robot.surfaces
    }
    scenario = environments.load("hand-on-table")
    sets = sample_prints(scenario.scene.surfaces, robot.surfaces, options_from_scenario({}, 0.2), obstacle_boxes(scenario.scene))
    up = {name for name, s in scenario.scene.surfaces.items() if s.transform_surface_to_world[2, 2] > np.cos(np.radians(20))}
    for name, print_set in sets.items():
        used = {p.surface for p in print_set.prints}
        assert used <= up if robot.surfaces[name].role == "foot" else used
    assert {p.surface for p in sets["left_palm"].prints} == {p.surface for p in sets["left_sole"].prints}


def test_the_reach_model_bounds_every_posture_and_is_measured_once(robot):
    reach = ReachModel.of(robot)
    assert ReachModel.of(robot) is reach
    model, data = robot.model, robot.model.createData()
    rng = np.random.default_rng(0)
    lower, upper = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
    for _ in range(200):
        q = np.array(robot.reference_configuration)
        q[7:] = rng.uniform(lower, upper)
        pin.framesForwardKinematics(model, data, q)
        for name, surface in robot.surfaces.items():
            root = data.oMi[model.getJointId(robot.limbs[surface.limb])].translation
            frame = data.oMf[robot.frame_id(surface.frame)].translation
            assert np.linalg.norm(frame - root) <= reach.limbs[surface.limb].length + 1e-9
    # Talos is left-right symmetric: so are its limb roots (within its URDF's 0.4 mm).
    for left, right in (("left_leg", "right_leg"), ("left_arm", "right_arm")):
        mirrored = reach.limbs[right].root_in_support * np.array([1.0, -1.0, 1.0])
        np.testing.assert_allclose(reach.limbs[left].root_in_support, mirrored, atol=1e-3)


def test_a_goal_given_to_plan_naming_a_surface_the_robot_lacks_is_refused(feet_only_romeo):
    from environments.goal import Goal, GoalRegion

    from cbm.errors import CbmError

    goal = Goal(regions=(GoalRegion("right_palm", (0.0, 0.0), (1.0, 1.0)),))
    with pytest.raises(CbmError, match=re.escape(
        "the goal names robot surface 'right_palm', not a surface of robot 'romeo'; its surfaces: left_sole, right_sole"
    )):
        plan("stand", goal=goal, robot=feet_only_romeo)


SOLO = {
    "name": "solo12",
    "description": "ODRI Solo-12 quadruped with ball feet of 16 mm radius (a robot that is not built in).",
    "model": {"example_robot_data": "solo_description", "urdf": "robots/solo12.urdf", "srdf": "srdf/solo.srdf"},
    "reference_posture": "standing",
    "support": {"role": "foot", "keep": 3},
    # Their hulls overlap by 4 mm standing (the meshes never meet).
    "ignored_pairs": [["base_link_0", f"{leg}_UPPER_LEG_0"] for leg in ("FL", "FR", "HL", "HR")],
    "limbs": {"left_front_leg": "FL_HAA", "right_front_leg": "FR_HAA", "left_hind_leg": "HL_HAA", "right_hind_leg": "HR_HAA"},
    "surfaces": {
        f"{side}_{end}_foot": {
            "role": "foot", "limb": f"{side}_{end}_leg", "link": f"{prefix}_FOOT", "point": {"radius": 0.016},
            "geometries": [f"{prefix}_FOOT_0"],
        }
        for side, end, prefix in (("left", "front", "FL"), ("right", "front", "FR"), ("left", "hind", "HL"), ("right", "hind", "HR"))
    },
}

SOLO_FOAM = """
robot: solo12.yaml
objects:
  - {name: floor, type: floor}
  - name: foam
    type: soft_box
    size: [0.3, 0.6, 0.04]
    center: [0.45, 0.0, 0.02]
    material: {E: 2.0e+5, nu: 0.4, rho: 100.0}
    RESOLUTION
stances:
  start:
    left_front_foot: {surface: floor, x: 0.195, y: 0.169}
    right_front_foot: {surface: floor, x: 0.195, y: -0.169}
    left_hind_foot: {surface: floor, x: -0.195, y: 0.169}
    right_hind_foot: {surface: floor, x: -0.195, y: -0.169}
start: start
goal:
  regions:
    - {robot_surface: left_front_foot, lower: [0.33, -0.3], upper: [0.6, 0.3]}
    - {robot_surface: right_front_foot, lower: [0.33, -0.3], upper: [0.6, 0.3]}
"""


def test_a_quadruped_from_example_robot_data_plans_onto_foam_with_default_planner_options(tmp_path):
    """Solo-12, described in a short file as a new user would: its base and upper-leg
    hulls overlap by 4 mm standing, so the file ignores those pairs (else no stance
    holds); the default print grid follows its 0.17 m step (0.042 m, not 0.1 m); the
    front feet reach the foam (meshed at 12 mm) and the saved plan verifies again, run
    through the command line in child processes, as a user would. On the foam's default
    mesh (22.5 mm) a 16 mm ball reaches two nodes within the indentation bound: a stance
    with a front foot there is refused, saying the mesh is too coarse for the print and
    which keys refine it (what a failed plan reports, tests/test_cbm_plan.py)."""
    import subprocess
    import sys

    _write(tmp_path / "solo12.yaml", SOLO)
    (tmp_path / "solo-foam.yaml").write_text(SOLO_FOAM.replace("RESOLUTION", "resolution: 0.012"))

    def cbm(*arguments):
        return subprocess.run([sys.executable, "-m", "cbm", *arguments], capture_output=True, text=True, timeout=300)

    found = cbm("plan", str(tmp_path / "solo-foam.yaml"), "--out", str(tmp_path / "out"), "--no-pictures",
                "--max-expansions", "30", "--quiet")
    assert found.returncode == 0, found.stdout + found.stderr
    assert "plan found" in found.stdout and "on foam_top" in found.stdout
    checked = cbm("check", str(tmp_path / "out" / "plan.json"))
    assert checked.returncode == 0 and "every stance verifies" in checked.stdout, checked.stdout + checked.stderr

    default = environments.load_string(SOLO_FOAM.replace("RESOLUTION", ""), path=tmp_path / "solo-default.yaml")
    solo = Robot.load(tmp_path / "solo12.yaml")
    stance = environments.Stance.from_dict({
        **default.stance("start").to_dict(), "left_front_foot": {"surface": "foam_top", "x": -0.1, "y": 0.169},
    })
    # Pressing the nodes, a ball needs three under it; the layer's law (the default here,
    # the foam a layer under the ball) reads no node.
    with pytest.raises(StanceError, match=re.escape(
        "the print of left_front_foot on foam_top holds 2 mesh node(s); at least 3 are needed: refine the mesh of "
        "'foam' where prints land (a scenario's soft_box takes resolution and refine)"
    )):
        build_problem(solo, default.scene, stance, PostureOptions(ball_contact="nodes"))
    assert "layer" in [c.kind for c in build_problem(solo, default.scene, stance).contacts]


def test_pairs_whose_hulls_touch_at_the_reference_are_not_checked_and_named(tmp_path, caplog):
    """Without ignored_pairs, Solo-12's four base/upper-leg pairs (hulls 4 mm into each
    other standing) are left out at load, listed on the robot and in a warning; a pair
    in checked_pairs stays checked."""
    data = {key: value for key, value in SOLO.items() if key != "ignored_pairs"}
    overlap = {frozenset(("base_link_0", f"{leg}_UPPER_LEG_0")) for leg in ("FL", "FR", "HL", "HR")}
    with caplog.at_level("WARNING", logger="stances.robot"):
        robot = Robot.load(_write(tmp_path / "solo12.yaml", data))
    assert {frozenset(pair) for pair in robot.ignored_pairs} == overlap
    names = [g.name for g in robot.collision_model.geometryObjects]
    checked = {frozenset((names[p.first], names[p.second])) for p in robot.collision_model.collisionPairs}
    assert not overlap & checked and len(checked) > 100
    # The checker's cached geometry (hulls kept from the load) reads the pairs left.
    assert len(_robot_geometry(robot).self_pairs) == len(robot.collision_model.collisionPairs)
    assert "4 self-collision pairs whose convex hulls already touch at the reference posture" in caplog.text
    assert "base_link_0-FL_UPPER_LEG_0" in caplog.text

    data["checked_pairs"] = [["base_link_0", "FL_UPPER_LEG_0"]]
    kept = Robot.load(_write(tmp_path / "solo12-checked.yaml", data))
    assert {frozenset(pair) for pair in kept.ignored_pairs} == overlap - {frozenset(("base_link_0", "FL_UPPER_LEG_0"))}
    names = [g.name for g in kept.collision_model.geometryObjects]
    assert frozenset(("base_link_0", "FL_UPPER_LEG_0")) in {
        frozenset((names[p.first], names[p.second])) for p in kept.collision_model.collisionPairs
    }


def test_mesh_rotations_turn_a_links_collision_meshes_in_their_own_frame(tmp_path, robot):
    """A description's mesh_rotations multiply the placement of each mesh of the
    links it lists by the rotation, on the right (in the mesh's own frame, before
    the URDF's origin); the other links' meshes stay where the URDF puts them. (The
    visual model the pictures draw gets the same rotations: tests/test_cbm_output.py
    draws iCub.)"""
    data = _talos_data()
    data["mesh_rotations"] = [{"links": ["leg_left_6_link", "base_link"], "rpy_deg": [90, 0, 30]}]
    turned = Robot.load(_write(tmp_path / "talos.yaml", data))
    rotation = pin.rpy.rpyToMatrix(np.radians(90), 0.0, np.radians(30))
    assert turned.mesh_rotations == read_description(tmp_path / "talos.yaml").mesh_rotations
    for plain, moved in zip(robot.collision_model.geometryObjects, turned.collision_model.geometryObjects):
        assert moved.name == plain.name
        expected = plain.placement.rotation @ rotation if plain.name in ("leg_left_6_link_0", "base_link_0") else (
            plain.placement.rotation
        )
        np.testing.assert_allclose(moved.placement.rotation, expected, atol=1e-12)
        np.testing.assert_allclose(moved.placement.translation, plain.placement.translation, atol=1e-12)


def test_ignored_pairs_are_not_checked(tmp_path):
    """A description's ignored_pairs leave the collision model and are listed on the robot."""
    data = _talos_data()
    data["ignored_pairs"] = [["base_link_0", "leg_left_3_link_0"]]
    robot = Robot.load(_write(tmp_path / "talos.yaml", data))
    names = [g.name for g in robot.collision_model.geometryObjects]
    pairs = {frozenset((names[p.first], names[p.second])) for p in robot.collision_model.collisionPairs}
    assert robot.ignored_pairs == (("base_link_0", "leg_left_3_link_0"),)
    assert frozenset(("base_link_0", "leg_left_3_link_0")) not in pairs
    assert len(pairs) == len(Robot.load("talos").collision_model.collisionPairs) - 1
