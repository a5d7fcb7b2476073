"""Bad input and unsafe output give the package's own error, never a crash or a wrong answer.

Each case is the smallest input of one kind of fault. Cases that, with the bug back,
would end, hang or exhaust the test process (meshio's ``sys.exit``, an alias bomb, a
huge allocation) run in a child process with a timeout and an address-space limit.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import re

import pytest

import environments
import fem
from cbm import cli
from cbm.errors import CbmError
from cbm.output import OutputDirectoryError, StagedOutput
from cbm.planner import PostureOracle, StanceCheck
from cbm.sampling import MAX_PRINT_CANDIDATES, options_from_scenario, sample_prints
from environments.deformable import MAX_SOFT_BOX_NODES, soft_box_coordinates
from environments.errors import ScenarioError
from fem.errors import MaterialError, MeshError, PrintError
from stances.errors import StanceError

from conftest import coarse_scenario

ROOT = Path(__file__).resolve().parents[1]

# Address space of a child process: far above what importing the packages takes
# (about 1.5 GB of mappings), far below what any of the guarded faults would
# allocate, so a regression fails fast with MemoryError instead of swapping.
_CHILD_MEMORY = 3 << 30


def run_isolated(code: str, timeout: float = 120.0) -> subprocess.CompletedProcess:
    """Run Python code in a child process with a memory limit and a timeout."""

    def limit_memory():
        resource.setrlimit(resource.RLIMIT_AS, (_CHILD_MEMORY, _CHILD_MEMORY))

    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=timeout,
        preexec_fn=limit_memory,
        cwd=ROOT,
    )


def load_isolated(path, timeout: float = 120.0) -> subprocess.CompletedProcess:
    """Load a scenario file in a child process (:func:`run_isolated`); its
    ScenarioError message, if any, is the child's output."""
    return run_isolated(
        f"""
        import environments
        try:
            environments.load({str(path)!r})
        except environments.ScenarioError as error:
            print(error)
        """,
        timeout=timeout,
    )


SCENARIO = """\
robot: talos
objects:
  - {name: floor, type: floor}
  - name: foam
    type: soft_box
    size: [0.6, 0.6, 0.1]
    center: [0.5, 0.0, 0.05]
    material: {E: 1.0e+6, nu: 0.4}
    resolution: coarse
stances:
  stand:
    left_sole: {surface: floor, x: 0.0, y: 0.085}
    right_sole: {surface: floor, x: 0.0, y: -0.085}
start: stand
options:
  print_spacing: 0.1
  theta_values_deg: [0]
"""


# ---------------------------------------------------------------- 1. mesh files
@pytest.mark.parametrize(
    "name, content",
    [
        ("broken.vtu", '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid"><garbage'),
        ("broken.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2 3\n"),
    ],
    ids=["vtu", "msh"],
)
def test_corrupt_mesh_file_gives_mesh_error_naming_the_file_and_the_process_lives_on(tmp_path, name, content):
    path = tmp_path / name
    path.write_text(content)
    # meshio used to call sys.exit(1) on the .vtu: run in a child so that a
    # regression fails this test instead of ending pytest.
    child = run_isolated(
        f"""
        import fem
        try:
            fem.read_mesh({str(path)!r})
        except fem.MeshError as error:
            print("MeshError:", error)
        print("still running")
        """
    )
    assert child.returncode == 0, child.stderr
    assert f"MeshError: cannot read mesh file {str(path)!r}" in child.stdout
    assert child.stdout.rstrip().endswith("still running")
    assert child.stderr == ""  # meshio's own printing is captured into the message


def test_corrupt_mesh_file_in_process_is_a_mesh_error(tmp_path):
    path = tmp_path / "broken.vtu"
    path.write_text("<VTKFile")
    with pytest.raises(MeshError, match="broken.vtu"):
        fem.read_mesh(path)


# ------------------------------------------------------------ 2. YAML aliases
def test_yaml_alias_bomb_is_refused_quickly_with_a_scenario_error(tmp_path):
    rows = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    rows += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, 9)]
    path = tmp_path / "bomb.yaml"
    path.write_text("\n".join(rows) + "\nobjects: [*a8]\nstances: {}\n")
    assert path.stat().st_size < 1024  # a kilobyte expanding to 9^9 values
    child = load_isolated(path, timeout=60)
    assert child.returncode == 0, child.stderr
    assert "bomb.yaml" in child.stdout and "expands to more than 100000 YAML values" in child.stdout


@pytest.mark.parametrize(
    "text, message",
    [
        ("a: &a [1, *a]\nobjects: *a\nstances: {}\n", "refers to a value that contains it"),
        ("objects: " + "[" * 3000 + "]" * 3000 + "\nstances: {}\n", "nested"),
    ],
    ids=["cyclic-alias", "deep-nesting"],
)
def test_cyclic_or_deep_yaml_is_a_scenario_error_not_a_recursion_error(text, message):
    with pytest.raises(ScenarioError, match=message):
        environments.load_string(text, path="case.yaml")


@pytest.mark.parametrize(
    "replaced, by, line, message",
    [
        ("    right_sole: {surface: floor, x: 0.0, y: -0.085}\n",
         "    right_sole: {surface: floor, x: 0.0, y: -0.085}\n    left_sole: {surface: floor, x: 0.1, y: 0.085}\n",
         14, "stances.stand: 'left_sole' is given twice (lines 12 and 14)"),
        ("start: stand\n", "start: stand\nstances: {}\n", 15, "'stances' is given twice (lines 10 and 15)"),
        ("material: {E: 1.0e+6, nu: 0.4}", "material: {E: 1.0e+6, nu: 0.4, E: 2.0e+6}", 8,
         "objects[1].material: 'E' is given twice (lines 8 and 8)"),
        ("start: stand\n", "start: stand\nyes: 1\ntrue: 2\n", 16,
         "'yes' and 'true' are one key to YAML (True), given twice (lines 15 and 16)"),
    ],
    ids=["stance-contact", "top-level", "inline", "one-key-two-spellings"],
)
def test_a_key_given_twice_is_refused_with_both_lines(replaced, by, line, message):
    # YAML keeps the last silently: the first definition would be lost unseen.
    assert replaced in SCENARIO
    with pytest.raises(ScenarioError) as raised:
        environments.load_string(SCENARIO.replace(replaced, by), path="case.yaml")
    assert str(raised.value).startswith(f"case.yaml:{line}: ")
    assert message + "; YAML would keep only the last: remove or rename one" in str(raised.value)


def test_an_empty_stance_is_said_to_be_empty():
    text = SCENARIO.replace("start: stand\n", "start: stand\n").replace("stances:\n", "stances:\n  empty: {}\n", 1)
    with pytest.raises(ScenarioError, match=r"stances\.empty: must be a non-empty mapping .*, got an empty mapping$"):
        environments.load_string(text, path="case.yaml")


def test_merge_keys_may_repeat():
    text = SCENARIO.replace("stances:\n", "base: &b {surface: floor}\nstances:\n").replace(
        "left_sole: {surface: floor, x: 0.0, y: 0.085}", "left_sole: {<<: *b, x: 0.0, y: 0.085}")
    with pytest.raises(ScenarioError, match="unknown key 'base'"):  # the merge itself is read
        environments.load_string(text, path="case.yaml")


@pytest.mark.parametrize("text", [
    "b: &B {k: 0}\na:\n  inner: &A {<<: *B, k: 1}\nx: {<<: *A, m: 3}\n",  # merges built in any order
    "base: &B {k: 0, j: 1}\nx: {<<: *B, k: 2}\n",  # a merged key overridden
    "1: a\n'1': b\n",  # an int and a str key
    "yes: a\n'yes': b\n",  # a bool and a str key
    "=: a\nb: 1\n",  # a plain '=' key, a string once in a mapping
    "!!binary aGVsbG8=: a\nhello: b\n",  # bytes and a str key
], ids=["nested-merge", "override", "int-and-str", "bool-and-str", "value-key", "binary-key"])
def test_what_yaml_keeps_apart_is_no_repeated_key(text):
    import yaml

    from environments.plain_data import load_yaml

    assert load_yaml(text) == yaml.safe_load(text)


@pytest.mark.parametrize("text, message", [
    ("1: a\n1.0: b\n", "'1' and '1.0' are one key to YAML (1), given twice (lines 1 and 2)"),
    ("'<<': a\n'<<': b\n", "'<<' is given twice (lines 1 and 2)"),  # quoted: a string, not a merge
], ids=["int-and-float", "quoted-merge-text"])
def test_one_key_in_two_spellings_is_refused(text, message):
    import yaml

    from environments.plain_data import load_yaml

    with pytest.raises(yaml.constructor.ConstructorError, match=re.escape(message)):
        load_yaml(text)


@pytest.mark.parametrize("text", ["!!seq a: 1\n", "? !!map {a: 1}\n: 1\n"], ids=["seq-tag", "map-key"])
def test_a_key_that_cannot_be_a_key_is_the_yaml_error_it_was(text):
    """Keys YAML cannot build or hash are left to building the document, which says so
    (as yaml.safe_load does): a ScenarioError, not a TypeError."""
    with pytest.raises(ScenarioError, match="found unhashable key"):
        environments.load_string("robot: talos\n" + text, path="case.yaml")


def test_a_small_alias_still_works():
    text = SCENARIO.replace("material: {E: 1.0e+6, nu: 0.4}", "material: &foam {E: 2.0e+6, nu: 0.4}")
    text = text.replace(
        "stances:",
        "  - {name: mat, type: soft_box, size: [0.4, 0.4, 0.05], center: [-1, 0, 0.025], material: *foam,\n"
        "     resolution: coarse}\nstances:",
    )
    scenario = environments.load_string(text)
    assert [o.body.material.young_modulus for o in scenario.scene.deformable_objects] == [2e6, 2e6]


# -------------------------------------------------------- 3. resource limits
def test_tiny_soft_box_resolution_names_the_limit_and_a_resolution_that_fits():
    with pytest.raises(environments.SceneError) as raised:
        soft_box_coordinates((1.0, 1.0, 1.0), 1e-5)
    message = str(raised.value)
    assert f"the limit of {MAX_SOFT_BOX_NODES}" in message
    fits = float(message.split("use a resolution of at least ")[1].split(" m")[0])
    # The suggested spacing must fit, and a spacing 5 % finer must not.
    xs, ys, zs = soft_box_coordinates((1.0, 1.0, 1.0), fits)
    assert xs.size * ys.size * zs.size <= MAX_SOFT_BOX_NODES * 1.05  # estimate within a few per axis
    with pytest.raises(environments.SceneError):
        soft_box_coordinates((1.0, 1.0, 1.0), 0.95 * fits)


def test_tiny_resolution_in_a_scenario_file_is_refused_before_allocating(tmp_path):
    path = tmp_path / "fine.yaml"
    path.write_text(SCENARIO.replace("resolution: coarse", "resolution: 1.0e-7"))
    child = load_isolated(path)
    assert child.returncode == 0, child.stderr
    assert "fine.yaml" in child.stdout and "objects[1]" in child.stdout
    assert "more than the limit of" in child.stdout and "use a resolution of at least" in child.stdout


def test_huge_box_mesh_is_a_mesh_error_before_allocating():
    with pytest.raises(MeshError, match=r"more than the limit of \d+ .*fewer divisions"):
        fem.box_mesh((1.0, 1.0, 1.0), (10**6, 10**6, 10**6))


def test_tiny_print_spacing_names_the_limit_and_a_spacing_that_fits(robot):
    scenario = environments.load_string(SCENARIO)
    polygons = dict(robot.surfaces)
    child = run_isolated(
        """
        import environments, stances
        from cbm.sampling import options_from_scenario, sample_prints
        from cbm.errors import CbmError
        scenario = environments.load_string(%r)
        robot = stances.Robot.load("talos")
        polygons = dict(robot.surfaces)
        try:
            sample_prints(scenario.scene.surfaces, polygons, options_from_scenario({}, 1e-4))
        except CbmError as error:
            print(error)
        """
        % SCENARIO
    )
    assert child.returncode == 0, child.stderr
    message = child.stdout
    assert f"more than the limit of {MAX_PRINT_CANDIDATES}" in message
    fits = float(message.split("use a print_spacing of at least ")[1].split(" m")[0])
    sets = sample_prints(scenario.scene.surfaces, polygons, options_from_scenario({}, fits))
    assert sum(len(s) for s in sets.values()) > 0
    with pytest.raises(CbmError, match="print_spacing"):
        sample_prints(scenario.scene.surfaces, polygons, options_from_scenario({}, 0.95 * fits))


# ------------------------------------------------------- 4. scenario options
@pytest.mark.parametrize(
    "options, key, message",
    [
        ("{print_spacng: 0.1}", "options.print_spacng", "unknown option 'print_spacng'; valid options: print_spacing"),
        ("{theta_values_deg: 0}", "options.theta_values_deg", "must be a non-empty list of numbers"),
        ("{robot_surfaces: left_sole}", "options.robot_surfaces", "must be a non-empty list of robot surface names"),
        ("{print_spacing: -0.1}", "options.print_spacing", "must be a number > 0"),
        ("{print_spacing: yes}", "options.print_spacing", "got bool True"),
        ("{print_margin: .nan}", "options.print_margin", "must be a number >= 0"),
        ("{sampling_region: {lower: [0, 0]}}", "options.sampling_region", "{lower: [x, y], upper: [x, y]}"),
        ("{sampling_region: {lower: [1, 0], upper: [0, 1]}}", "options.sampling_region", "must be <= upper"),
        ("{theta_values_deg: [0, ninety]}", "options.theta_values_deg[1]", "got 'ninety'"),
    ],
    ids=["typo", "scalar-for-list", "string-for-list", "negative", "bool", "nan", "region-no-upper",
         "region-inverted", "word-in-list"],
)
def test_bad_scenario_option_names_file_key_line_and_what_is_valid(tmp_path, options, key, message):
    path = tmp_path / "case.yaml"
    text = SCENARIO.replace("options:\n  print_spacing: 0.1\n  theta_values_deg: [0]\n", f"options: {options}\n")
    path.write_text(text)
    line = text.splitlines().index(f"options: {options}") + 1
    with pytest.raises(ScenarioError) as raised:
        environments.load(path)
    assert str(raised.value).startswith(f"{path}:{line}: {key}: ")
    assert message in str(raised.value)


def test_options_given_in_python_are_validated_too():
    with pytest.raises(ScenarioError, match="options.robot_surfaces: must be a non-empty list"):
        options_from_scenario({"robot_surfaces": "left_sole"})
    scenario = environments.load_string(SCENARIO)
    with pytest.raises(ScenarioError, match="unknown option 'spacing'"):
        environments.Scenario(scenario.name, scenario.scene, options={"spacing": 0.1})


# ------------------------------------------------- 5. silently wrong physics
def test_repeated_tet_is_a_mesh_error():
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (2, 2, 2))
    tets = np.vstack([mesh.tets, mesh.tets[[5]][:, [1, 0, 3, 2]]])  # same nodes, other order
    with pytest.raises(MeshError, match=rf"tets 5 and {mesh.n_tets} have the same nodes"):
        fem.TetMesh(mesh.nodes, tets, fix_orientation=True)


@pytest.mark.parametrize(
    "polygon, message",
    [
        ([[0.2, 0.2], [0.8, 0.8], [0.8, 0.2], [0.2, 0.8]], "self-intersecting: edge 0-1 meets edge 2-3"),
        ([[0.2, 0.2], [0.8, 0.2], [0.8, 0.2], [0.2, 0.8]], "vertices 1 and 2 coincide"),
        ([[0.2, 0.2], [0.8, 0.2], [0.5, 0.2], [0.5, 0.8]], "folds back on itself at vertex 1"),
    ],
    ids=["bow-tie", "repeated-vertex", "spike"],
)
def test_self_intersecting_print_polygon_is_a_print_error(polygon, message):
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (4, 4, 2))
    with pytest.raises(PrintError, match=message):
        fem.nodes_in_polygon(mesh, [[x, y, 1.0] for x, y in polygon])


@pytest.mark.parametrize(
    "polygon",
    [
        # An arrow, non-convex (its edges pass through no node of the 0.1 m grid).
        [[0.21, 0.23], [0.79, 0.22], [0.52, 0.49], [0.78, 0.81], [0.22, 0.79]],
        # Non-convex, counter-clockwise: in the polygon's own plane axes an edge's end
        # vertex lies inside the bounding box of a later edge, on its inner side, which
        # the intersection test must not take for a touch (found by random search).
        [[0.72, 0.52], [0.61, 0.69], [0.32, 0.66], [0.29, 0.69], [0.59, 0.33]],
    ],
    ids=["arrow", "pentagon"],
)
def test_simple_print_polygons_are_accepted_and_hold_the_nodes_inside(polygon):
    from matplotlib.path import Path as PolygonPath

    mesh = fem.box_mesh((1.0, 1.0, 1.0), (10, 10, 2))
    found = fem.nodes_in_polygon(mesh, [[x, y, 1.0] for x, y in polygon])
    top = np.flatnonzero(mesh.nodes[:, 2] == 1.0)
    inside = top[PolygonPath(polygon).contains_points(mesh.nodes[top, :2])]
    assert found.size > 0 and set(found.tolist()) == set(inside.tolist())


@pytest.mark.parametrize("young_modulus", [1e308, 1e13], ids=["1e308", "1e13"])
def test_enormous_young_modulus_is_a_material_error(young_modulus):
    with pytest.raises(MaterialError, match="young_modulus must be <= 1e\\+12 Pa"):
        fem.LinearElasticMaterial(young_modulus, 0.4)


def test_enormous_young_modulus_in_a_scenario_names_the_material_key():
    with pytest.raises(ScenarioError, match=r"objects\[1\]\.material\.E: must be <= 1e\+12 Pa"):
        environments.load_string(SCENARIO.replace("E: 1.0e+6", "E: 1.0e+308"), path="case.yaml")



@pytest.mark.parametrize(
    "option, value, message",
    [
        ("posture_weight", float("nan"), "posture_weight must be >= 0 and finite, got nan"),
        ("base_orientation_weight", float("inf"), "base_orientation_weight must be >= 0 and finite, got inf"),
        ("force_weight", -1e-5, "force_weight must be >= 0 and finite, got -1e-05"),
        ("collision_distance", float("nan"), "collision_distance must be >= 0 and finite, got nan"),
        ("collision_activation", -0.1, "collision_activation must be >= 0 and finite, got -0.1"),
        ("min_normal_force", float("inf"), "min_normal_force must be >= 0 and finite, got inf"),
        ("optimality_tolerance", float("nan"), "optimality_tolerance must be > 0 and finite, got nan"),
        ("max_slip", -1.0, "max_slip must be > 0 and finite, got -1.0"),
        ("max_mesh_overlap", 0.0, "max_mesh_overlap must be > 0 and finite, got 0.0"),
        ("trust_region", float("inf"), "trust_region must be > 0 and finite, got inf"),
        ("max_indentation", float("nan"), "max_indentation must be > 0 metres and finite (or None), got nan"),
        ("posture_weight", "1", "posture_weight must be a number, got '1'"),
        ("torque_weight", True, "torque_weight must be a number, got True"),
        ("max_iterations", float("nan"), "max_iterations must be a whole number >= 0, got nan"),
        ("max_iterations", 2.5, "max_iterations must be a whole number >= 0, got 2.5"),
        ("max_collision_rows", -1, "max_collision_rows must be a whole number >= 0, got -1"),
        ("ball_force_error", 0.0, "ball_force_error must be > 0 (a fraction; inf accepts every ball), got 0.0"),
        ("ball_force_error", -0.05, "ball_force_error must be > 0 (a fraction; inf accepts every ball), got -0.05"),
        ("ball_force_error", float("nan"), "ball_force_error must be > 0 (a fraction; inf accepts every ball), got nan"),
        ("ball_force_error", "5 %", "ball_force_error must be a number, got '5 %'"),
        ("corner_sinking", 1.0, "corner_sinking must be a share in [0, 1) of a print's mean sinking, got 1.0"),
        ("corner_sinking", -0.1, "corner_sinking must be a share in [0, 1) of a print's mean sinking, got -0.1"),
        ("corner_sinking", float("nan"), "corner_sinking must be a share in [0, 1) of a print's mean sinking, got nan"),
        ("max_corner_lift", 0.0, "max_corner_lift must be > 0 metres (inf lets prints pivot on an edge), got 0.0"),
        ("max_corner_lift", float("nan"), "max_corner_lift must be > 0 metres (inf lets prints pivot on an edge), got nan"),
        ("max_corner_lift", "1 mm", "max_corner_lift must be a number, got '1 mm'"),
    ],
    ids=lambda v: str(v) if isinstance(v, str) and len(v) < 30 else None,
)
def test_every_number_of_the_posture_options_is_checked(option, value, message):
    """A NaN weight once made every QP fail and the stance read "print unreachable";
    a NaN collision distance was ignored; a NaN iteration cap was numpy's ValueError."""
    from stances.errors import StanceError
    from stances.problem import PostureOptions

    with pytest.raises(StanceError) as raised:
        PostureOptions(**{option: value})
    assert str(raised.value) == message


def test_a_nan_weight_given_to_solve_is_bad_input_not_an_infeasible_stance(robot):
    import stances
    from stances.errors import StanceError

    scenario = environments.load("hand-on-table")
    with pytest.raises(StanceError, match="^posture_weight must be >= 0 and finite, got nan$"):
        stances.solve(robot, scenario.scene, scenario.stance("hand-on-table"), posture_weight=float("nan"))


# ------------------------------------------------------------ 6. CLI output
@pytest.fixture
def fake_planning(monkeypatch):
    """``cbm plan`` with the search and the writing replaced by instant stand-ins."""
    calls = []

    class Result:
        success = True
        reason = ""
        stances = ()
        rejections = {}
        frontier = ()

        class statistics:  # noqa: N801 - stands in for PlanStatistics
            expanded = solver_calls = cache_hits = 0
            time = cpu_time = 0.0
            prefiltered = {}
            print_spacing = None

    def plan(*args, **kwargs):
        calls.append("plan")
        return Result()

    def write_outputs(result, scenario, robot, out, pictures=True, motions=None):
        from cbm.output import OutputFiles

        (Path(out) / "plan.json").write_text("{}")
        (Path(out) / "viewer.html").write_text("")
        return OutputFiles(Path(out) / "plan.json", (), (), Path(out) / "viewer.html")

    monkeypatch.setattr("cbm.planner.plan", plan)
    monkeypatch.setattr("cbm.output.write_outputs", write_outputs)
    return calls


def test_out_that_is_a_file_exits_2_before_the_search(tmp_path, fake_planning, capsys):
    out = tmp_path / "results"
    out.write_text("not a folder")
    assert cli.main(["plan", "stand", "--out", str(out), "--quiet"]) == cli.EXIT_BAD_INPUT
    assert "is a file, not a folder" in capsys.readouterr().err
    assert fake_planning == []


def test_out_that_cannot_be_written_exits_2_before_the_search(tmp_path, fake_planning, monkeypatch, capsys):
    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    # A read-only parent, simulated: tests may run as root, which ignores modes.
    monkeypatch.setattr("tempfile.mkdtemp", refuse)
    assert cli.main(["plan", "stand", "--out", str(tmp_path / "results"), "--quiet"]) == cli.EXIT_BAD_INPUT
    assert "cannot write output folder" in capsys.readouterr().err
    assert fake_planning == []


def test_out_under_a_file_exits_2(tmp_path, fake_planning, capsys):
    (tmp_path / "file").write_text("")
    assert cli.main(["plan", "stand", "--out", str(tmp_path / "file" / "deeper" / "results"), "--quiet"]) == 2
    assert f"{str(tmp_path / 'file')!r} is a file, not a folder" in capsys.readouterr().err
    assert fake_planning == []


def test_missing_folders_above_out_are_made(tmp_path):
    staged = StagedOutput(tmp_path / "runs" / "today" / "results")
    (staged.folder / "plan.json").write_text("{}")
    assert staged.publish() == tmp_path / "runs" / "today" / "results"
    assert [p.name for p in (tmp_path / "runs" / "today" / "results").iterdir()] == ["plan.json"]


def test_non_empty_out_is_refused_unless_forced_and_then_replaced_whole(tmp_path, fake_planning, capsys):
    out = tmp_path / "results"
    out.mkdir()
    (out / "stance_07.png").write_text("from an older plan")
    assert cli.main(["plan", "stand", "--out", str(out), "--quiet"]) == cli.EXIT_BAD_INPUT
    assert "not empty" in capsys.readouterr().err and fake_planning == []
    assert cli.main(["plan", "stand", "--out", str(out), "--quiet", "--force"]) == cli.EXIT_OK
    assert sorted(p.name for p in out.iterdir()) == ["plan.json", "viewer.html"]
    assert [p.name for p in tmp_path.iterdir()] == ["results"]  # no temporary folder left


def test_ctrl_c_during_the_search_exits_130_and_leaves_out_untouched(tmp_path, monkeypatch, capsys):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("cbm.planner.plan", interrupted)
    out = tmp_path / "results"
    assert cli.main(["plan", "stand", "--out", str(out), "--quiet"]) == cli.EXIT_INTERRUPTED
    assert "interrupted" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_failure_while_writing_leaves_the_previous_plan_in_place(tmp_path, fake_planning, monkeypatch):
    out = tmp_path / "results"
    out.mkdir()
    (out / "plan.json").write_text('{"old": true}')

    def half_written(result, scenario, robot, folder, pictures=True, motions=None):
        (Path(folder) / "plan.json").write_text("{}")
        raise KeyboardInterrupt  # Ctrl-C between the plan and the viewer

    monkeypatch.setattr("cbm.output.write_outputs", half_written)
    assert cli.main(["plan", "stand", "--out", str(out), "--quiet", "--force"]) == cli.EXIT_INTERRUPTED
    assert json.loads((out / "plan.json").read_text()) == {"old": True}
    assert [p.name for p in tmp_path.iterdir()] == ["results"]


def test_staged_output_publishes_with_the_permissions_of_a_new_folder(tmp_path):
    staged = StagedOutput(tmp_path / "results")
    (staged.folder / "plan.json").write_text("{}")
    umask = os.umask(0)
    os.umask(umask)
    assert staged.publish() == tmp_path / "results"
    assert (tmp_path / "results").stat().st_mode & 0o777 == 0o777 & ~umask
    with pytest.raises(OutputDirectoryError, match="not empty"):
        StagedOutput(tmp_path / "results")


def test_help_documents_the_exit_codes(capsys):
    assert cli.main(["plan", "--help"]) == 0
    text = capsys.readouterr().out
    for code, meaning in (("0", "plan found"), ("1", "no plan"), ("2", "bad input"), ("130", "interrupted")):
        assert any(line.split()[:1] == [code] and meaning in line for line in text.splitlines()), text


# ---------------------------------------------- 7. only the library's errors
def test_cli_lets_a_bug_propagate_instead_of_calling_it_bad_input(tmp_path, monkeypatch):
    def buggy(*args, **kwargs):
        raise np.linalg.LinAlgError("Singular matrix")  # a ValueError, but not bad input

    monkeypatch.setattr("cbm.planner.plan", buggy)
    with pytest.raises(np.linalg.LinAlgError):
        cli.main(["plan", "stand", "--out", str(tmp_path / "results"), "--quiet"])
    assert list(tmp_path.iterdir()) == []


def test_cli_still_reports_the_library_errors_as_bad_input(tmp_path, monkeypatch, capsys):
    def refused(*args, **kwargs):
        raise CbmError("scenario 'stand' has no goal; pass goal=")

    monkeypatch.setattr("cbm.planner.plan", refused)
    assert cli.main(["plan", "stand", "--out", str(tmp_path / "results"), "--quiet"]) == cli.EXIT_BAD_INPUT
    assert "has no goal" in capsys.readouterr().err


@pytest.fixture
def oracle_with(monkeypatch, robot):
    """A PostureOracle whose solver raises a given exception."""
    scenario = environments.load("stand")

    def make(error):
        def solve(*args, **kwargs):
            raise error

        monkeypatch.setattr("cbm.planner.posture_api", lambda: (solve, None))
        return PostureOracle(robot, scenario.scene, retry_cold=False), scenario.stance("stand")

    return make


def test_oracle_lets_a_linear_algebra_bug_propagate(oracle_with):
    oracle, stance = oracle_with(np.linalg.LinAlgError("Singular matrix"))
    with pytest.raises(np.linalg.LinAlgError):
        oracle(stance)


@pytest.mark.parametrize(
    "error",
    [StanceError("the stance has no contact"), PrintError("print covers 2 nodes"), environments.SceneError("off")],
    ids=["stances", "fem", "environments"],
)
def test_oracle_turns_the_library_errors_into_infeasible(oracle_with, error):
    oracle, stance = oracle_with(error)
    check = oracle(stance)
    assert check == StanceCheck(False, f"{type(error).__name__}: {error}", bad_input=True)


def test_cli_check_of_a_stance_the_solver_refuses_is_bad_input(tmp_path, capsys):
    """Two soles pressing the same foam nodes: the stance a user wrote is at fault, exit 2."""
    text = coarse_scenario("cross-soft-block").text.replace(
        "stances:\n",
        "stances:\n  overlap:\n    left_sole: {surface: foam_top, x: 0.0, y: 0.0}\n"
        "    right_sole: {surface: foam_top, x: 0.0, y: 0.05}\n", 1)
    path = tmp_path / "overlap.yaml"
    path.write_text(text)
    assert cli.main(["check", str(path), "--stance", "overlap"]) == cli.EXIT_BAD_INPUT
    captured = capsys.readouterr()
    assert captured.err.startswith("cbm check: error: stance 'overlap': StanceError: the prints of left_sole on "
                                   "foam_top and right_sole on foam_top overlap")
    assert "move one print" in captured.err and "infeasible" not in captured.out


def test_cli_check_of_a_body_too_soft_for_its_own_weight_is_bad_input(tmp_path, capsys):
    """A scene at fault exits 2 with the reason, before any solve, not 'infeasible'."""
    text = environments.builtin_scenario_path("step-on-cube").read_text()
    path = tmp_path / "soft.yaml"
    path.write_text(text.replace("E: 1.0e+6", "E: 1.0e+4").replace("resolution: default", "resolution: 0.04"))
    assert cli.main(["check", str(path), "--stance", "step-on-cube"]) == cli.EXIT_BAD_INPUT
    captured = capsys.readouterr()
    # Named by the file, the object's key and its line, as any other error in the file.
    line = next(i for i, row in enumerate(path.read_text().splitlines(), 1) if "name: cube" in row)
    assert captured.err.startswith(f"cbm check: error: {path}:{line}: objects[")
    assert "]: object 'cube': its own weight strains it" in captured.err
    assert "infeasible" not in captured.out


@pytest.mark.parametrize("swap, message", [
    ("robot name", "robot must be a stances.Robot, got the name 'talos': load it once with stances.Robot.load('talos')"),
    ("scenario", "scene must be an environments.Scene, got a scenario: pass scenario.scene"),
    ("stance name", "stance must be an environments.Stance, got the name 'stand': scenario.stance('stand') gives"),
    ("stance dict", "stance must be an environments.Stance, got a mapping: environments.Stance.from_dict(...) reads one"),
])
def test_a_name_or_a_scenario_in_place_of_the_robot_scene_or_stance_is_a_type_error_saying_what_to_pass(robot, swap, message):
    import stances

    scenario = environments.load("stand")
    arguments = {"robot name": ("talos", scenario.scene, scenario.stance("stand")),
                 "scenario": (robot, scenario, scenario.stance("stand")),
                 "stance name": (robot, scenario.scene, "stand"),
                 "stance dict": (robot, scenario.scene, scenario.stance("stand").to_dict())}[swap]
    with pytest.raises(TypeError, match=re.escape(message)):
        stances.solve(*arguments)
    with pytest.raises(TypeError, match=re.escape(message)):
        stances.verify(*arguments, result=None)


def test_plan_takes_a_robot_by_name_as_the_command_line_does_and_refuses_one_the_scenario_cannot_use():
    import cbm

    with pytest.raises(ScenarioError, match="robot surface 'left_sole' is not a surface of robot 'anymal'"):
        cbm.plan(coarse_scenario("hand-on-cube"), robot="anymal")


def test_a_material_warning_is_said_at_the_scenario_files_line_and_key(tmp_path):
    from fem.errors import FemWarning

    material = "material: {E: 1.0e+6, nu: 0.4}"
    path = tmp_path / "nu.yaml"
    path.write_text(SCENARIO.replace(material, material.replace("nu: 0.4", "nu: 0.49")))
    line = next(i for i, row in enumerate(path.read_text().splitlines(), 1) if "nu: 0.49" in row)
    with pytest.warns(FemWarning, match=r"^objects\[1\]\.material\.nu: 0\.49 is above 0\.45: linear tetrahedra lock") as caught:
        environments.load(path)
    assert [(w.filename, w.lineno) for w in caught if issubclass(w.category, FemWarning)] == [(str(path), line)]
