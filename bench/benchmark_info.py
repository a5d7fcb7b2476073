"""What a benchmark table records about its run: the machine and the code measured."""

from __future__ import annotations

import os
import platform
import subprocess


def machine() -> str:
    """CPU count and model, Python, BLAS threads and load: what a timing depends on."""
    model = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as handle:
            for line in handle:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    with open("/proc/loadavg") as handle:
        load = " ".join(handle.read().split()[:3])
    return (
        f"nproc {len(os.sched_getaffinity(0))}, {model}, Python {platform.python_version()}, "
        f"BLAS threads {os.environ.get('OPENBLAS_NUM_THREADS', 'default')}, load average {load} (shared machine)"
    )


def code_version() -> str:
    """Commit of the code measured, and whether stances/, fem/ or environments/ had uncommitted edits."""
    root = os.path.join(os.path.dirname(__file__), "..")
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True,
                                text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "stances", "fem", "environments"],
                               cwd=root, capture_output=True, text=True, check=True).stdout.split("\n")
    except (OSError, subprocess.CalledProcessError):
        return "unknown commit"
    edited = sorted({line[3:] for line in dirty if line.strip()})
    return f"commit {commit}" + (f", uncommitted edits in {', '.join(edited)}" if edited else "")
