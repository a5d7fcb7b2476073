"""docs/scenarios.md: its worked example loads, solves and plans; it names every key a scenario takes."""

import re
from pathlib import Path

import pytest

import environments
import stances
from environments.options import SCENARIO_OPTIONS
from environments.scenario_reader import NESTED_KEYS, OBJECT_KEYS, SCENARIO_KEYS

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "scenarios.md"


def worked_example():
    """The YAML block of the doc's worked-example section."""
    section = DOC.read_text().split("## Worked example", 1)[1]
    blocks = re.findall(r"```yaml\n(.*?)```", section, flags=re.DOTALL)
    assert len(blocks) == 1, "the worked example must hold exactly one yaml block"
    return blocks[0]


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    path = tmp_path_factory.mktemp("doc") / "my-scene.yaml"
    path.write_text(worked_example())
    return environments.load(path)


def test_readme_links_the_scenario_docs():
    assert "(docs/scenarios.md)" in (ROOT / "README.md").read_text()


def test_worked_example_stance_solves_and_verifies(example):
    robot = stances.Robot.load(example.robot)
    result = stances.solve(robot, example.scene, example.stance("right-on-mat"))
    assert result.feasible, result.reason
    assert stances.verify(robot, example.scene, result.stance, result).ok
    mat_frame = robot.surfaces["right_sole"].frame
    on_mat = sum(f.force[2] for f in result.point_forces if f.frame == mat_frame)
    said = float(re.search(r"about (\d+) N on the right sole", DOC.read_text()).group(1))
    assert on_mat == pytest.approx(said, rel=0.05)
    assert 0.0 < result.verification.measures["indentation of mat"] < 1e-3  # "a tenth of a millimetre"


def test_worked_example_softened_as_the_doc_says(example):
    """"at E = 5e4 Pa it is pressed about D mm deep and strained S %, ... leaves the mat about F N"."""
    text = " ".join(DOC.read_text().split("## Worked example", 1)[1].split())
    claim = re.search(r"at E = 5e4 Pa it is pressed about ([\d.]+) mm deep and strained ([\d.]+) %.*?"
                      r"leaves the mat about (\d+) N", text)
    depth, strain, force = (float(claim.group(i)) for i in (1, 2, 3))
    soft = environments.load_string(worked_example().replace("E: 2.0e+6", "E: 5.0e+4"), path="my-scene.yaml")
    robot = stances.Robot.load(soft.robot)
    result = stances.solve(robot, soft.scene, soft.stance("right-on-mat"))
    assert result.feasible, result.reason
    measures = result.verification.measures
    on_mat = sum(f.force[2] for f in result.point_forces if f.frame == robot.surfaces["right_sole"].frame)
    assert on_mat == pytest.approx(force, rel=0.05)
    assert 1e3 * measures["indentation of mat"] == pytest.approx(depth, rel=0.1)
    assert 100 * measures["largest strain of mat"] == pytest.approx(strain, rel=0.05)
    assert measures["largest strain of mat"] < 0.05  # within the strain limit, not on it


def test_worked_example_plans_to_its_goal(example):
    import cbm

    plan = cbm.plan(example, max_expansions=40, time_limit=120.0)
    assert plan.success, plan.reason
    assert len(plan.stances) == 11  # the doc says "a plan of 11 stances"


@pytest.mark.parametrize(
    "keys",
    [("top level", SCENARIO_KEYS), ("options", tuple(SCENARIO_OPTIONS))]
    + [(f"type {kind}", (kind,) + keys) for kind, keys in OBJECT_KEYS.items()]
    + [(what, keys) for what, keys in NESTED_KEYS.items()],
    ids=lambda keys: keys[0],
)
def test_doc_names_every_key_a_scenario_takes(keys):
    text = DOC.read_text()
    missing = [key for key in keys[1] if f"`{key}`" not in text and f"`{key}:" not in text]
    assert not missing, f"{keys[0]}: {missing} not described in docs/scenarios.md"
