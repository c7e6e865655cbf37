"""``run`` watches every node until it has exited: a node that fails after the recorder has
finished (in its teardown or summary) fails the run, with its log; clean exits do not.

The children are real processes standing in for the nodes (Python one-liners with the exit
statuses and timings wanted), watched by the run's own loop; no ROS is started.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from strapdown_ros.pipeline import PipelineError
from strapdown_ros.pipeline.processes import Child, Children
from strapdown_ros.pipeline.run import _LiveRun


def _child(children: Children, name: str, code: str) -> Child:
    child = Child(name, [sys.executable, "-c", code], children.env, children.log_dir)
    children.started.append(child)
    return child


def _watch(tmp_path: Path, source_exit: str) -> None:
    children = Children(tmp_path / "bag", domain_id=7)
    try:
        recorder = _child(children, "bag_recorder", "import time; time.sleep(0.3)")
        source = _child(children, "trajectory_node", "import sys, time; print('publishing', "
                        f"flush=True); time.sleep(1.0); {source_exit}")  # fmt: skip
        run = _LiveRun(None, tmp_path / "bag", None, False, 1.0, False, children,  # type: ignore[arg-type]
                       lambda line: None)  # fmt: skip
        assert recorder is children.started[0]
        run.wait(source, timeout_s=30.0)
    finally:
        children.reap()


def test_a_node_failing_after_the_recording_fails_the_run(tmp_path: Path) -> None:
    with pytest.raises(PipelineError, match="trajectory_node exited with status 3 after the "
                       "recording ended") as err:  # fmt: skip
        _watch(tmp_path, "print('summary failed', flush=True); sys.exit(3)")
    assert "summary failed" in err.value.log


def test_nodes_ending_cleanly_after_the_recording_pass(tmp_path: Path) -> None:
    _watch(tmp_path, "sys.exit(0)")
