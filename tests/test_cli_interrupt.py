"""Ctrl-C on a real ``python -m cbm plan`` child: the best partial plan is written, exit 130."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from cbm.cli import EXIT_INTERRUPTED
from cbm.plan import Plan

# A goal across a 3 m gap: no plan exists, so with an unbounded expansion budget the
# search runs (hundreds of rigid stances, 300 s by default) until interrupted. A
# real scenario that plans, even a long walk, may finish before Ctrl-C arrives.
SCENARIO = """\
robot: talos
objects:
  - {name: floor, type: floor, size: [3.0, 0.8]}
  - {name: far, type: box, size: [1.0, 0.8, 0.1], center: [5.0, 0.0, 0.05]}
stances:
  start:
    left_sole: {surface: floor, x: 0.0, y: 0.085}
    right_sole: {surface: floor, x: 0.0, y: -0.085}
start: start
goal:
  regions:
    - {robot_surface: left_sole, lower: [4.6, -0.4], upper: [5.4, 0.4]}
    - {robot_surface: right_sole, lower: [4.6, -0.4], upper: [5.4, 0.4]}
"""


def _wait_for(stream, marker, timeout):
    """Read ``stream`` (bytes) until ``marker`` shows; keep draining it afterwards."""
    seen = threading.Event()
    text = bytearray()

    def read():
        for chunk in iter(lambda: stream.read1(4096), b""):
            text.extend(chunk)
            if marker in text:
                seen.set()

    threading.Thread(target=read, daemon=True).start()
    return seen.wait(timeout), text


def test_ctrl_c_during_the_search_writes_the_best_partial_plan_and_exits_130(tmp_path):
    out = tmp_path / "results"
    root = Path(__file__).resolve().parent.parent
    environment = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")])}
    scenario = tmp_path / "gap.yaml"
    scenario.write_text(SCENARIO)
    child = subprocess.Popen(
        [sys.executable, "-m", "cbm", "plan", str(scenario), "--out", str(out), "--no-pictures",
         "--max-expansions", "100000"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=environment,
        # A shell starts background jobs with SIGINT ignored, and the child would
        # inherit that (then Python installs no KeyboardInterrupt handler): the
        # test sends Ctrl-C as a terminal would, so the child starts with the default.
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        # The progress bar shows "solves=" once the start is solved and expanded,
        # so there is a partial plan to keep.
        started, stderr = _wait_for(child.stderr, b"solves=", timeout=240)
        assert started, f"the search did not start: {stderr.decode(errors='replace')}"
        time.sleep(1.0)
        assert child.poll() is None, "the plan ended before Ctrl-C; pick a longer scenario"
        child.send_signal(signal.SIGINT)
        code = child.wait(timeout=240)
    finally:
        child.kill()
        child.wait()
    assert code == EXIT_INTERRUPTED, stderr.decode(errors="replace")
    assert b"writing the best partial plan" in stderr
    data = json.loads((out / "plan.json").read_text())
    assert data["success"] is False
    assert data["reason"].startswith("interrupted (Ctrl-C) after ")
    assert (out / "viewer.html").is_file()
    plan = Plan.load(out / "plan.json")
    assert len(plan.stances) >= 1 and plan.stances[0].move == ""
    # Published through the temporary folder: nothing else is left beside --out.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["gap.yaml", "results"]
