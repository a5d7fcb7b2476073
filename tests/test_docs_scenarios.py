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
    assert 250.0 < on_mat < 400.0  # the doc says "about 330 N on the right sole"
    assert 0.0 < result.verification.measures["indentation of mat"] < 1e-3  # "a tenth of a millimetre"


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
