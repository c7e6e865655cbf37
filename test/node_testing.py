"""Helpers shared by the node tests: child processes, executables, payload comparison."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import time
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parent.parent


def executable(name: str) -> str:
    local = Path(sys.executable).parent / name
    found = str(local) if local.exists() else shutil.which(name)
    if not found:
        pytest.skip(f"{name} is not installed (make setup)")
    return found


class Proc:
    """A child process whose stdout/stderr go to files (no pipe can fill up)."""

    def __init__(self, args: list[str], env: dict[str, str], log_dir: Path, name: str) -> None:
        self.name = name
        self.out_path = log_dir / f"{name}.out"
        self.err_path = log_dir / f"{name}.err"
        with open(self.out_path, "w") as out, open(self.err_path, "w") as err:
            self.proc = subprocess.Popen(
                args, env=env, stdin=subprocess.DEVNULL, stdout=out, stderr=err, cwd=REPO
            )

    @property
    def output(self) -> str:
        return self.out_path.read_text() + self.err_path.read_text()

    def wait_for(self, pattern: str, deadline: float) -> None:
        """Block until the output matches ``pattern`` (regex); fail at ``deadline`` or exit."""
        while not re.search(pattern, self.output):
            if self.proc.poll() is not None and not re.search(pattern, self.output):
                pytest.fail(f"{self.name} exited before {pattern!r}:\n{self.describe()}")
            if time.monotonic() > deadline:
                pytest.fail(f"timeout waiting for {pattern!r} from {self.name}:\n{self.describe()}")
            time.sleep(0.05)

    def wait(self, deadline: float) -> int:
        try:
            return self.proc.wait(timeout=max(deadline - time.monotonic(), 0.1))
        except subprocess.TimeoutExpired:
            pytest.fail(f"timeout waiting for {self.name} to exit:\n{self.describe()}")

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=10)

    def describe(self) -> str:
        return f"--- {self.name} (pid {self.proc.pid}, rc {self.proc.poll()})\n{self.output}"


def padded(payload: bytes) -> bytes:
    """``payload`` as a subscriber in another process receives it from Fast DDS.

    RTPS submessages are 4-byte aligned and the reader takes the serialized payload's length
    from the submessage, so a payload whose length is not a multiple of 4 (NavSatFix: 133
    bytes) arrives with 1-3 zero bytes appended, whoever published it (rclpy's own serializer
    too). The CDR content is unchanged.
    """
    return bytes(payload) + bytes(-len(payload) % 4)


def bitwise_equal(a, b) -> bool:
    """Field containers equal bit for bit (dtype, shape and bytes of every array)."""
    if type(a) is not type(b):
        return False
    for f in fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, str) or isinstance(y, str):
            if x != y:
                return False
            continue
        x, y = np.ascontiguousarray(x), np.ascontiguousarray(y)
        if x.dtype != y.dtype or x.shape != y.shape or x.tobytes() != y.tobytes():
            return False
    return True


def scenario_without_tf(path: Path, *, aiding: bool = True) -> Path:
    """A copy of scenario ``path`` with ``tf: {enabled: false, map_odometry: false}`` (and
    without its ``aiding`` section when ``aiding`` is false).

    The node tests compare a node's own streams with ``generate``'s; TF and the map-frame
    odometry (published beside them by every node) are tested by test_tf.py (against truth) and
    test_pipeline.py (``run`` equals ``generate``). Same file name, so the scenario name stays.
    """
    import os
    import tempfile

    import yaml

    doc = yaml.safe_load(path.read_text())
    doc.setdefault("name", path.stem)
    doc["tf"] = {"enabled": False, "map_odometry": False}
    if not aiding:
        doc.pop("aiding", None)
    tag = "" if aiding else "_no_aiding"
    out = Path(tempfile.gettempdir()) / f"strapdown_no_tf{tag}_{os.getpid()}" / path.name
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out
