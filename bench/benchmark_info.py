"""What a benchmark table records about its run: the machine and the code measured."""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
import time

import environments


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


def write_report(path: str, title: str, started: float, preamble: str, lines: list) -> str:
    """A benchmark's markdown report: title, date, code, machine and run time, preamble, table.

    Printed and written to ``path`` (its folder made if needed); ``started`` is the
    ``time.perf_counter()`` of the run's start. Returns the text.
    """
    text = (
        f"# {title}\n\n"
        f"{datetime.date.today()}, {code_version()}; {machine()}. Total run time {time.perf_counter() - started:.0f} s.\n\n"
        f"{preamble}\n\n" + "\n".join(lines) + "\n"
    )
    print(text)
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    with open(path, "w") as handle:
        handle.write(text)
    return text


def scenario_at_resolution(name: str, resolution: float, directory: str) -> str:
    """A built-in scenario's file with its soft meshes at another spacing, written in ``directory``.

    The built-in file's ``resolution: default`` lines become ``resolution: <resolution>``
    (metres); returns the new file's path, for ``environments.load`` or a fresh process.
    """
    text = environments.builtin_scenario_path(name).read_text()
    if "resolution: default" not in text:
        raise RuntimeError(f"{name}.yaml no longer says 'resolution: default'; update this benchmark")
    path = os.path.join(directory, f"{name}-{resolution:g}.yaml")
    with open(path, "w") as handle:
        handle.write(text.replace("resolution: default", f"resolution: {resolution}"))
    return path
