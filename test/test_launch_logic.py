"""``strapdown_ros.launch_logic``: what ``launch/pipeline.launch.py`` starts, without ``launch``.

* The per-node subscription counts and the set of nodes equal what ``strapdown-sim run``
  passes its children (``run_pipeline`` with its process class replaced by a recorder of the
  command lines: no process starts), for default.yaml and for car.yaml (no variation, no IMU
  errors, no navigator: counts that config/params.yaml, written for default.yaml, gets wrong).
* The output directory: time-stamped by default, never an existing one, an existing ``out:=``
  refused unless ``force:=true``, relative paths made absolute.
* A failing node: :func:`exit_reason` gives the shutdown reason, and the launch file's exit
  handlers (run here against a minimal stand-in of the ``launch`` API, since ``launch`` is not
  installable from PyPI) raise :class:`NodeFailedError` with it for a non-zero exit (launch
  then shuts everything down and exits 1) and do nothing for 0.

The launch file on the real ``launch``/``launch_ros`` (OnProcessExit → Shutdown, a second
launch into the same out) is checked by hand with a scratch Jazzy ``ros2 launch``; see
test_launch.py for the tests that run when ``launch`` is importable.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import types
from pathlib import Path

import pytest
import yaml
from launch_standin import LAUNCH_API_CLASSES

from strapdown_ros import launch_logic
from strapdown_ros.config import ScenarioError, load_scenario
from strapdown_ros.pipeline import processes, run_pipeline

REPO = Path(__file__).resolve().parent.parent
SCENARIOS = REPO / "config" / "scenarios"
LAUNCH = REPO / "launch" / "pipeline.launch.py"
#: Short runs: the counts' structure does not depend on the duration (the cycle counts do not
#: enter subscribers_per_topic), and a short scenario builds in well under a second.
DURATION = 5.0


class _StopError(Exception):
    """Raised by the stand-in child process when the last node of run_pipeline starts."""


def _run_children(scenario: Path, tmp_path: Path, rate_factor: float) -> dict[str, list[str]]:
    """Node → its ``-p`` parameters, as ``run_pipeline`` starts them (nothing is started)."""
    started: dict[str, list[str]] = {}

    class FakeProc:
        returncode = 0

        def poll(self):
            return 0

        def wait(self, timeout=None):
            return 0

        def kill(self):
            pass

    class FakeChild:
        def __init__(self, name, args, env, log_dir):
            self.name, self.proc, self.cpu_s = name, FakeProc(), None
            params = [args[i + 1] for i, a in enumerate(args) if a in ("-p", "-r")]
            started[name] = params  # parameters and remaps (-r __node:=NAME)
            if name == "trajectory_node":
                raise _StopError

        def poll(self):
            return 0

        def wait_for(self, text, timeout_s, others):
            pass

        def stop(self):
            pass

        def close(self):
            pass

    real = processes.Child
    processes.Child = FakeChild
    try:
        with pytest.raises(_StopError):
            run_pipeline(
                scenario, tmp_path / "out", duration_s=DURATION, rate_factor=rate_factor,
                progress=False,
            )  # fmt: skip
    finally:
        processes.Child = real
    return started


def _param(params: list[str], name: str) -> str:
    values = [p.split(":=", 1)[1] for p in params if p.startswith(name + ":=")]
    assert len(values) == 1, (name, params)
    return values[0]


def _as_list(text: str) -> list[str]:
    return [s.strip().strip("'") for s in text.strip("[]").split(",") if s.strip()]


@pytest.mark.parametrize("name", ["default.yaml", "car.yaml", "aided_car_noisy.yaml"])
@pytest.mark.parametrize("rate_factor", [1.0, 5.0])
def test_counts_and_nodes_equal_strapdown_sim_run(name, rate_factor, tmp_path) -> None:
    """Shipped scenarios (default.yaml: two imu_errors models, two imu_model_node processes),
    and a test scenario; all three have an aided section (aided_node)."""
    path = SCENARIOS / name if (SCENARIOS / name).exists() else REPO / "test" / "data" / name
    run = _run_children(path, tmp_path, rate_factor)
    plan = launch_logic.plan_launch(
        str(path), str(tmp_path / "launch_out"), duration_s=DURATION, rate_factor=rate_factor,
    )  # fmt: skip
    assert {n.name for n in plan.nodes} == set(run)
    assert "aided_node" in run
    models = 2 if name == "default.yaml" else 1
    imu_nodes = ["imu_model_node", "imu_model_node_1"][:models]
    assert sorted(n for n in run if n.startswith("imu_model")) == imu_nodes
    for i, node_name in enumerate(imu_nodes):  # each its own model, name and output
        node = plan.node(node_name)
        assert node.executable == "imu_model_node" and node.parameters["model"] == i
        assert _param(run[node_name], "model") == str(i)
        assert ("__node:=imu_model_node_1" in run[node_name]) == (i == 1)
    if models == 2:
        outs = [plan.node(n).parameters["subscribers_per_topic"][0] for n in imu_nodes]
        assert outs == ["/variation/imu_measured=1", "/reference/imu_measured=2"]
    for node in plan.nodes:
        if node.name == "bag_recorder":
            continue
        got = node.parameters["subscribers_per_topic"]
        assert got == _as_list(_param(run[node.name], "subscribers_per_topic")), node.name
    traj = plan.node("trajectory_node").parameters
    assert traj["time_source"] == _param(run["trajectory_node"], "time_source")
    if rate_factor > 1:  # flow control, on the same nodes, in the same order
        assert traj["flow_nodes"] == _as_list(_param(run["trajectory_node"], "flow_nodes"))
    else:
        assert "flow_nodes" not in traj


def test_car_counts_are_not_the_params_file_ones(tmp_path) -> None:
    """params.yaml's counts are default.yaml's; car.yaml (no variation/navigator: only the
    recorder, the aiding node, the IMU model and the aided filter listen) needs others, which
    the launch passes over them."""
    static = yaml.safe_load((REPO / "config" / "params.yaml").read_text())
    file_counts = dict(
        item.rsplit("=", 1)
        for item in static["trajectory_node"]["ros__parameters"]["subscribers_per_topic"]
    )
    plan = launch_logic.plan_launch(str(SCENARIOS / "car.yaml"), str(tmp_path / "o"),
                                    duration_s=DURATION)  # fmt: skip
    car = dict(
        item.rsplit("=", 1) for item in plan.node("trajectory_node").parameters[
            "subscribers_per_topic"]
    )  # fmt: skip
    assert file_counts["/reference/odom"] == "4" and car["/reference/odom"] == "3"
    assert file_counts["/reference/imu"] == "3" and car["/reference/imu"] == "2"
    assert {n.name for n in plan.nodes} == {"bag_recorder", "trajectory_node", "aiding_node",
                                            "imu_model_node", "aided_node"}  # fmt: skip


def test_default_out_is_time_stamped_and_never_existing(tmp_path) -> None:
    now = 1767225600.0
    first = launch_logic.default_out(tmp_path, now)
    assert first.parent == tmp_path and first.name.startswith("strapdown_run_20")
    assert len(first.name) == len("strapdown_run_YYYY_MM_DD-HH_MM_SS")
    first.mkdir()
    second = launch_logic.default_out(tmp_path, now)  # the same second: a new name
    assert second != first and not second.exists()
    auto = launch_logic.resolve_out("", False, tmp_path)  # out:= unset: now, in cwd
    assert auto.parent == tmp_path and auto.name.startswith("strapdown_run_")
    assert not auto.exists()


def test_repeated_out_is_refused_before_anything_starts(tmp_path) -> None:
    out = tmp_path / "run1"
    out.mkdir()
    with pytest.raises(launch_logic.LaunchError, match="force:=true"):
        launch_logic.resolve_out(str(out), False, tmp_path)
    with pytest.raises(launch_logic.LaunchError, match="exists already"):
        launch_logic.plan_launch(str(SCENARIOS / "car.yaml"), "run1", cwd=tmp_path,
                                 duration_s=DURATION)  # fmt: skip
    plan = launch_logic.plan_launch(str(SCENARIOS / "car.yaml"), "run1", cwd=tmp_path,
                                    force="true", duration_s=DURATION)  # fmt: skip
    assert plan.out == out
    recorder = plan.node("bag_recorder").parameters
    assert recorder["output"] == str(out) and recorder["force"] is True


def test_relative_paths_are_made_absolute(tmp_path) -> None:
    plan = launch_logic.plan_launch(str(SCENARIOS / "car.yaml"), "sub/dir", cwd=tmp_path,
                                    duration_s=DURATION)  # fmt: skip
    assert plan.out == tmp_path / "sub" / "dir"
    assert Path(plan.node("trajectory_node").parameters["scenario"]).is_absolute()


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ({"force": "maybe"}, "force:=maybe: must be true or false"),
        ({"duration_s": "abc"}, "duration_s:=abc: must be a number"),
        ({"duration_s": "-1"}, "must be >= 0"),
        ({"rate_factor": "fast"}, "rate_factor:=fast"),
    ],
)
def test_bad_launch_arguments(args, match, tmp_path) -> None:
    with pytest.raises(launch_logic.LaunchError, match=match):
        launch_logic.plan_launch(str(SCENARIOS / "car.yaml"), "", cwd=tmp_path, **args)


def test_offline_only_sections_are_refused_before_anything_starts(tmp_path) -> None:
    """A scenario with a section no node runs live (the suite's timing.yaml) is refused as
    strapdown-sim run refuses it, instead of launching a pipeline that lacks its topics."""
    with pytest.raises(launch_logic.LaunchError, match=r"its timing section\(s\) run in "):
        launch_logic.plan_launch(str(REPO / "config" / "suite" / "timing.yaml"), "", cwd=tmp_path,
                                 duration_s=DURATION)  # fmt: skip
    with pytest.raises(ScenarioError, match="timing"):  # what run says
        run_pipeline(REPO / "config" / "suite" / "timing.yaml", tmp_path / "r", duration_s=DURATION,
                     progress=False)  # fmt: skip
    assert not list(tmp_path.iterdir())


def test_bad_scenario_is_reported_by_key(tmp_path) -> None:
    from strapdown_ros.config import ScenarioError

    bad = tmp_path / "bad.yaml"
    bad.write_text((SCENARIOS / "car.yaml").read_text().replace("rate_hz: 100", "rate_hz: -5"))
    with pytest.raises(ScenarioError, match="rate_hz"):
        launch_logic.plan_launch(str(bad), "", cwd=tmp_path)


def test_exit_reason() -> None:
    assert launch_logic.exit_reason("navigator_node", 0) is None
    reason = launch_logic.exit_reason("bag_recorder", 2)
    assert "bag_recorder exited with status 2" in reason and "invalid" in reason
    assert "failure while running" in launch_logic.exit_reason("aiding_node", 1)
    assert "signal 9" in launch_logic.exit_reason("trajectory_node", -9)
    # stopped by the launch's own shutdown (an earlier failure, Ctrl-C): no second reason
    assert launch_logic.exit_reason("bag_recorder", -2, shutting_down=True) is None
    assert launch_logic.exit_reason("aiding_node", 1, shutting_down=True) is None


# --- where the plan is computed: the nodes' interpreter ------------------------------------------


def _script(prefix: Path, text: str) -> Path:
    path = prefix / "lib" / "strapdown_ros" / "trajectory_node"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def test_node_interpreter_reads_the_executables_interpreter_line(tmp_path) -> None:
    _script(tmp_path, "#!/home/u/venv/bin/python3\nimport sys\n")
    assert launch_logic.node_interpreter(tmp_path) == "/home/u/venv/bin/python3"
    # pip's form for a path too long (or with spaces) for a #! line
    _script(tmp_path, "#!/bin/sh\n'''exec' \"/a b/venv/bin/python\" \"$0\" \"$@\"\n' '''\n")
    assert launch_logic.node_interpreter(tmp_path) == "/a b/venv/bin/python"
    _script(tmp_path, "#!/usr/bin/env python3\n")
    assert Path(launch_logic.node_interpreter(tmp_path)).name.startswith("python3")
    _script(tmp_path, "import sys\n")
    with pytest.raises(launch_logic.LaunchError, match="no interpreter line"):
        launch_logic.node_interpreter(tmp_path)
    with pytest.raises(launch_logic.LaunchError, match="colcon build"):
        launch_logic.node_interpreter(tmp_path / "not_built")


@pytest.mark.slow  # ~5 s: two planner child processes
def test_plan_in_the_nodes_interpreter_is_the_plan(tmp_path) -> None:
    """plan_launch_with (a child process, JSON) gives exactly plan_launch's plan, and relays
    its refusals as LaunchError with the same message (about 1.5 s of CPU per child)."""
    args = {"duration_s": "5.0", "rate_factor": "5.0", "cwd": tmp_path}
    here = launch_logic.plan_launch(str(SCENARIOS / "car.yaml"), "o", **args)
    child = launch_logic.plan_launch_with(sys.executable, str(SCENARIOS / "car.yaml"), "o",
                                          **args)  # fmt: skip
    assert child == here
    (tmp_path / "o").mkdir()
    with pytest.raises(launch_logic.LaunchError, match=r"out:=o: .* exists already"):
        launch_logic.plan_launch_with(sys.executable, str(SCENARIOS / "car.yaml"), "o", **args)


def test_planner_with_noble_pydantic_names_the_fix(tmp_path, monkeypatch) -> None:
    """A node interpreter that sees noble's pydantic 1.10 first (a dist-info of that version
    ahead on its path): the launch stops with the pip command, before any node starts."""
    old = tmp_path / "site" / "pydantic-1.10.14.dist-info"
    old.mkdir(parents=True)
    (old / "METADATA").write_text("Metadata-Version: 2.1\nName: pydantic\nVersion: 1.10.14\n")
    path = os.pathsep.join(p for p in (str(tmp_path / "site"), os.environ.get("PYTHONPATH")) if p)
    monkeypatch.setenv("PYTHONPATH", path)
    with pytest.raises(launch_logic.LaunchError) as err:
        launch_logic.plan_launch_with(sys.executable, str(SCENARIOS / "car.yaml"), "",
                                      cwd=tmp_path)  # fmt: skip
    text = str(err.value)
    assert "pydantic >= 2.11.5 is required (1.10.14 is installed)" in text
    assert "pip install 'pydantic>=2.11.5'" in text and "requirements/ros-overlay.txt" in text


# --- the launch file's wiring, on a minimal stand-in of the launch API --------------------------

#: A stand-in of the parts of launch / launch_ros that pipeline.launch.py uses (exec'd here and in
#: child processes): actions record their arguments; a context is a dict of the launch arguments
#: and "_prefix" (what FindPackagePrefix finds).
FAKE_LAUNCH = LAUNCH_API_CLASSES + """
mods = {n: types.ModuleType(n) for n in (
    "launch", "launch.actions", "launch.event_handlers", "launch.substitutions",
    "launch_ros", "launch_ros.actions", "launch_ros.substitutions")}
for name in ("RegisterEventHandler", "LogInfo"):
    setattr(mods["launch.actions"], name, type(name, (_Action,), {}))
mods["launch.event_handlers"].OnProcessExit = type("OnProcessExit", (_Action,), {})
mods["launch.substitutions"].LaunchConfiguration = LaunchConfiguration
mods["launch_ros.actions"].Node = type("Node", (_Action,), {})
mods["launch_ros.substitutions"].FindPackagePrefix = FindPackagePrefix
"""


def _fake_launch_modules() -> dict[str, types.ModuleType]:
    namespace: dict = {}
    exec(FAKE_LAUNCH, namespace)  # the test's own stand-in
    return namespace["mods"]


def _load_launch_file(name: str):
    spec = importlib.util.spec_from_file_location(name, LAUNCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


class _Params:
    def perform(self, _context):
        return "/share/strapdown_ros/config/params.yaml"


def _context(tmp_path: Path, scenario: str = "car.yaml") -> dict[str, str]:
    """The launch arguments, and a package prefix whose node executables run this Python."""
    prefix = tmp_path / "prefix"
    _script(prefix, f"#!{sys.executable}\n")
    return {"scenario": str(SCENARIOS / scenario), "out": str(tmp_path / "o"), "force": "false",
            "duration_s": str(DURATION), "rate_factor": "1.0", "_prefix": str(prefix)}  # fmt: skip


@pytest.mark.slow  # ~3 s: child processes
def test_launch_file_stops_on_a_failing_node(tmp_path, monkeypatch) -> None:
    for name, module in _fake_launch_modules().items():
        monkeypatch.setitem(sys.modules, name, module)
    module = _load_launch_file("pipeline_launch_fake")
    actions = module._nodes(_context(tmp_path), _Params())
    nodes = [a for a in actions if type(a).__name__ == "Node"]
    handlers = [a for a in actions if type(a).__name__ == "RegisterEventHandler"]
    assert {n.kwargs["executable"] for n in nodes} == {"bag_recorder", "trajectory_node",
                                                       "imu_model_node", "aiding_node",
                                                       "aided_node"}  # fmt: skip
    assert len(handlers) == len(nodes)
    for node, handler in zip(nodes, handlers, strict=True):
        on_exit = handler.args[0]
        assert on_exit.kwargs["target_action"] is node
        params = node.kwargs["parameters"]
        assert params[0].endswith("params.yaml") and isinstance(params[1], dict)
        callback = on_exit.kwargs["on_exit"]
        running, stopping = (types.SimpleNamespace(is_shutdown=v) for v in (False, True))
        assert callback(types.SimpleNamespace(returncode=0), running) == []
        with pytest.raises(launch_logic.NodeFailedError, match=(
                f"{node.kwargs['executable']} exited with status 2")):  # fmt: skip
            callback(types.SimpleNamespace(returncode=2), running)
        # the nodes that shutdown stops (SIGINT) exit after it: nothing more is raised
        assert callback(types.SimpleNamespace(returncode=-2), stopping) == []


@pytest.mark.slow  # ~3 s: child processes
def test_launch_file_needs_no_library_in_the_launch_process(tmp_path) -> None:
    """The launch file run by a Python that can import none of the package's libraries (as
    /usr/bin/python3 running ros2 launch on noble lacks pydantic 2 and numba): the nodes and
    their parameters still come out, planned by the nodes' interpreter, equal to plan_launch's."""
    context = _context(tmp_path, "default.yaml")
    code = FAKE_LAUNCH + f"""
import importlib.abc, importlib.util, json
BLOCKED = {{"numpy", "scipy", "pydantic", "yaml", "numba", "rosbags", "mcap", "matplotlib",
           "rclpy"}}

class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ImportError(f"{{name}} is blocked in this process")

sys.meta_path.insert(0, Block())
sys.modules.update(mods)
spec = importlib.util.spec_from_file_location("pipeline_launch_blocked", {str(LAUNCH)!r})
module = importlib.util.module_from_spec(spec)
spec.loader.exec_module(module)

class Params:
    def perform(self, context):
        return "params.yaml"

actions = module._nodes({context!r}, Params())
nodes = [a for a in actions if type(a).__name__ == "Node"]
print(json.dumps([[n.kwargs["name"], n.kwargs["executable"], n.kwargs["parameters"][1]]
                  for n in nodes]))
print(sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED))
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    got, loaded = proc.stdout.splitlines()
    want = launch_logic.plan_launch(context["scenario"], context["out"], duration_s=DURATION)
    assert json.loads(got) == [[n.name, n.executable, n.parameters] for n in want.nodes]
    assert loaded == "[]"


def test_scenarios_all_plan(tmp_path) -> None:
    """Every shipped scenario gives a plan whose every node waits on at least one topic, or
    (a section no node runs yet, e.g. transfer_alignment) a clear refusal naming it."""
    from strapdown_ros.plan import resolve_plan
    from strapdown_ros.plan.chain import offline_only

    for path in sorted(SCENARIOS.glob("*.yaml")):
        offline = offline_only(resolve_plan(load_scenario(path, duration_s=2.0)))
        if offline:
            with pytest.raises(launch_logic.LaunchError, match=offline[0]):
                launch_logic.plan_launch(str(path), "", cwd=tmp_path, duration_s=2.0)
            continue
        plan = launch_logic.plan_launch(str(path), "", cwd=tmp_path, duration_s=2.0)
        for node in plan.nodes:
            if node.name != "bag_recorder":
                assert node.parameters["subscribers_per_topic"], (path.name, node.name)
        assert load_scenario(path).name
