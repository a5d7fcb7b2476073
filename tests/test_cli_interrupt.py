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

# The benchmark's long walk (30+ stances) plans for tens of seconds; its first
# expansions take about a second.
SCENARIO = str(Path(__file__).resolve().parent.parent / "bench" / "scenes" / "long-walk.yaml")


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
    child = subprocess.Popen(
        [sys.executable, "-m", "cbm", "plan", SCENARIO, "--out", str(out), "--no-pictures"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=environment,
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
    assert [p.name for p in tmp_path.iterdir()] == ["results"]
