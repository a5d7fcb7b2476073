"""Batch checks: a local Dask cluster answers like checks run one by one; bad batch files are named."""

import json

import numpy as np
import pyarrow.parquet as pq  # the batch extra is part of the test extra: a broken install fails here
import pytest

from cbm.batch import BatchFileError, read_checks, run_check
from cbm.cli import main

BATCH = """
solver_options: {max_iterations: 40}
checks:
  - {scenario: stand, stance: stand, id: stand}
  - {scenario: cross-soft-block, stance: start}
  - {scenario: cross-soft-block, stance: beyond}
  - scenario: cross-soft-block
    id: off-edge
    stance:   # the left sole hangs off the foam block: refused, an infeasible answer
      left_sole: {surface: foam_top, x: 0.2, y: 0.085}
      right_sole: {surface: floor, x: 0.2, y: -0.085}
"""


@pytest.fixture(scope="module")
def batch_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("batch") / "checks.yaml"
    path.write_text(BATCH)
    return path


def test_a_local_cluster_of_two_workers_answers_like_checks_run_one_by_one(batch_file, tmp_path, capsys, robot):
    checks, options = read_checks(batch_file)
    one_by_one = [run_check(check, options) for check in checks]
    assert main(["batch", str(batch_file), "--out", str(tmp_path), "--workers", "2", "--quiet"]) == 0
    assert "4 checks: 3 feasible, 1 infeasible" in capsys.readouterr().out
    table = pq.read_table(tmp_path / "checks.parquet").to_pylist()
    assert [row["id"] for row in table] == ["stand", "1", "2", "off-edge"]
    assert [row["feasible"] for row in table] == [True, True, True, False]
    assert "lies off surface 'foam_top'" in table[3]["reason"]
    for row, expected in zip(table, one_by_one):
        assert row["feasible"] == expected.feasible and row["reason"] == expected.reason
        assert json.loads(row["stance"]) == expected.stance
        assert np.array_equal(row["q"], expected.q)
        assert np.array_equal(np.array(row["forces"]).reshape(-1, 3), expected.forces)
        assert row["force_frames"] == list(expected.force_frames)
    # A feasible answer holds the robot up: its contact forces carry its weight (1e-6 relative: solver tolerance).
    weight = robot.mass * 9.81
    for row in table:
        if row["feasible"]:
            assert np.array(row["forces"]).sum(axis=0)[2] == pytest.approx(weight, rel=1e-6)


@pytest.mark.parametrize(
    "text, message",
    [
        ("checks: []", "checks: no check listed"),
        ("checks:\n  - {scenario: stand}", "checks[0]: missing key 'stance'"),
        ("checks:\n  - {scenario: stand, stance: sit}", "checks[0].stance: unknown stance 'sit' in scenario 'stand'; its stances: stand"),
        ("checks:\n  - {scenario: nowhere.yaml, stance: stand}", "checks[0].scenario: 'nowhere.yaml' is neither a file nor a built-in scenario"),
        ("checks:\n  - {scenario: stand, stance: stand, robott: talos}", "checks[0]: unknown key(s) ['robott']; valid keys: ['scenario', 'stance', 'robot', 'id']"),
        ("checks:\n  - {scenario: stand, stance: {left_sole: {surface: roof, x: 0, y: 0}}}", "checks[0].stance: scene 'stand': unknown surface 'roof'; known surfaces: floor"),
        ("checks:\n  - {scenario: stand, stance: stand, id: a}\n  - {scenario: stand, stance: stand, id: a}", "checks: repeated id(s) ['a']"),
        ("checks: [", "not valid YAML"),
        ("checks:\n  - {scenario: stand, stance: stand, stance: sit}", "'stance' is given twice (lines 2 and 2)"),
    ],
    ids=["empty", "no-stance", "unknown-stance", "unknown-scenario", "unknown-key", "unknown-surface", "repeated-id",
         "syntax", "repeated-key"],
)
def test_bad_batch_file_names_the_check_and_key_at_fault(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(BatchFileError) as error:
        read_checks(path)
    assert str(error.value).startswith(f"{path}: ")
    assert message in str(error.value)


def test_csv_batch_file_reads_like_yaml(tmp_path):
    path = tmp_path / "checks.csv"
    path.write_text("scenario,stance,id\nstand,stand,a\ncross-soft-block,beyond,b\n")
    checks, options = read_checks(path)
    assert [c.id for c in checks] == ["a", "b"] and options == {}
    assert checks[1].stance["left_sole"]["x"] == 0.9


def test_cli_batch_reports_a_bad_file_with_exit_code_2(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text("checks:\n  - {scenario: stand}\n")
    assert main(["batch", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "cbm batch: error: " in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
