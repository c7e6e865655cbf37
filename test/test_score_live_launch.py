"""``launch/score_live.launch.py`` and :mod:`strapdown_ros.score.live_launch`, without ``launch``.

``launch``/``launch_ros`` are not on PyPI, so the launch file runs here against a minimal
stand-in of their API (as test_launch_logic.py does for pipeline.launch.py): its handlers are
called with the events a real launch would emit, in the order of a live score, and the actions
they return are checked — the player started by the recorder's "subscribed to" line, SIGINT to
the node ``linger_s`` after the play, SIGINT to the recorder after the node, the scorer on the
recording after the recorder, the shutdown after the scorer; a node exiting before the end of
the play, a wrong type or a failing process raise the reason; during a shutdown (Ctrl-C)
nothing follows. The same path for real: test_score_live.py (``strapdown-sim score --node``).
"""

from __future__ import annotations

import importlib.util
import signal
import sys
import types
from pathlib import Path

import pytest
from launch_standin import LAUNCH_API_CLASSES

from strapdown_ros.launch_logic import LaunchError, NodeFailedError
from strapdown_ros.score.live_launch import LiveSequence, Step, plan_score_live

REPO = Path(__file__).resolve().parent.parent
LAUNCH = REPO / "launch" / "score_live.launch.py"
TOPIC = "/my_filter/odom"

FAKE_LAUNCH = LAUNCH_API_CLASSES + """
def matches_action(action):
    return ("matches", action)

mods = {n: types.ModuleType(n) for n in (
    "launch", "launch.actions", "launch.event_handlers", "launch.events", "launch.events.process",
    "launch.substitutions", "launch_ros", "launch_ros.actions", "launch_ros.substitutions")}
for name in ("EmitEvent", "ExecuteProcess", "LogInfo", "RegisterEventHandler", "TimerAction",
             "DeclareLaunchArgument", "OpaqueFunction"):
    setattr(mods["launch.actions"], name, type(name, (_Action,), {}))
for name in ("OnProcessExit", "OnProcessIO"):
    setattr(mods["launch.event_handlers"], name, type(name, (_Action,), {}))
mods["launch.events"].Shutdown = type("Shutdown", (_Action,), {})
mods["launch.events"].matches_action = matches_action
mods["launch.events.process"].SignalProcess = type("SignalProcess", (_Action,), {})
mods["launch.substitutions"].LaunchConfiguration = LaunchConfiguration
mods["launch_ros.actions"].Node = type("Node", (_Action,), {})
mods["launch_ros.substitutions"].FindPackagePrefix = FindPackagePrefix
mods["launch"].LaunchDescription = type("LaunchDescription", (_Action,), {})
"""


def _bag(tmp_path: Path) -> Path:
    bag = tmp_path / "bag"
    bag.mkdir(parents=True, exist_ok=True)
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    return bag


def _prefix(tmp_path: Path) -> Path:
    script = tmp_path / "prefix" / "lib" / "strapdown_ros" / "trajectory_node"
    script.parent.mkdir(parents=True)
    script.write_text(f"#!{sys.executable}\n")
    return tmp_path / "prefix"


@pytest.fixture
def launch_file(monkeypatch):
    namespace: dict = {}
    exec(FAKE_LAUNCH, namespace)  # the test's own stand-in
    for name, module in namespace["mods"].items():
        monkeypatch.setitem(sys.modules, name, module)
    spec = importlib.util.spec_from_file_location("score_live_launch_fake", LAUNCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def _context(tmp_path: Path, **over: str) -> dict[str, str]:
    args = {"bag": str(_bag(tmp_path)), "node": f"{sys.executable} -c pass", "topic": TOPIC,
            "inputs": "/variation/imu_measured, /gnss/fix", "out": "", "force": "false",
            "rate_factor": "1.0", "linger_s": "2.5", "scenario": "",
            "_prefix": str(_prefix(tmp_path))}  # fmt: skip
    return {**args, **over}


def _kind(action) -> str:
    return type(action).__name__


def test_launch_file_runs_the_live_score_in_order(tmp_path, launch_file) -> None:
    context = _context(tmp_path)
    actions = launch_file._actions(context)
    handlers = [a.args[0] for a in actions if _kind(a) == "RegisterEventHandler"]
    started = [a for a in actions if _kind(a) in ("Node", "ExecuteProcess")]
    assert [_kind(a) for a in started] == ["Node", "ExecuteProcess"]
    recorder, node = started
    assert recorder.kwargs["executable"] == "bag_recorder"
    params = recorder.kwargs["parameters"][0]
    bag = Path(context["bag"])
    assert params["topics"] == [TOPIC] and params["output"] == str(bag / "score" / "estimate")
    assert node.kwargs["cmd"] == [sys.executable, "-c", "pass"]
    exits = {h.kwargs["target_action"].kwargs.get("name"): h.kwargs["on_exit"]
             for h in handlers if _kind(h) == "OnProcessExit"}  # fmt: skip
    (io,) = [h for h in handlers if _kind(h) == "OnProcessIO"]
    assert io.kwargs["target_action"] is recorder
    running = types.SimpleNamespace(is_shutdown=False)

    def event(text: str):
        return types.SimpleNamespace(text=text.encode())

    # 1. the recorder's lines: nothing until it subscribed to the node's publisher; then the
    #    player, once
    assert io.kwargs["on_stderr"](event("[INFO] recording 1 topic(s) into ...")) == []
    line = f"[INFO] [bag_recorder]: subscribed to {TOPIC} (nav_msgs/msg/Odometry, reliable)"
    (player,) = io.kwargs["on_stderr"](event(line))
    assert _kind(player) == "Node" and player.kwargs["executable"] == "bag_player"
    pp = player.kwargs["parameters"][0]
    assert pp["topics"] == ["/variation/imu_measured", "/gnss/fix"]
    assert pp["wait_for_subscribers"] == 1 and pp["bag"] == str(bag)
    assert io.kwargs["on_stdout"](event(f"subscribed to {TOPIC} (nav_msgs/msg/Odometry,")) == []
    # 2. the play ends: SIGINT to the node after linger_s
    (timer,) = exits["bag_player"](types.SimpleNamespace(returncode=0), running)
    assert _kind(timer) == "TimerAction" and timer.kwargs["period"] == 2.5
    (emit,) = timer.kwargs["actions"]
    sig = emit.kwargs["event"]
    assert sig.kwargs["signal_number"] == signal.SIGINT
    assert sig.kwargs["process_matcher"] == ("matches", node)
    # 3. the node ends: SIGINT to the recorder
    (emit,) = exits["node"](types.SimpleNamespace(returncode=0), running)
    assert emit.kwargs["event"].kwargs["process_matcher"] == ("matches", recorder)
    # 4. the recorder closed the bag: the scorer on it
    (score,) = exits["bag_recorder"](types.SimpleNamespace(returncode=0), running)
    assert _kind(score) == "ExecuteProcess"
    cmd = score.kwargs["cmd"]
    assert cmd[0] == str(Path(sys.executable).parent / "strapdown-sim")
    assert cmd[1:] == ["score", str(bag), "--topic", TOPIC, "--estimate-bag",
                       str(bag / "score" / "estimate"), "--out", str(bag / "score")]  # fmt: skip
    # 5. scored: shutdown
    (emit,) = exits["score"](types.SimpleNamespace(returncode=0), running)
    assert _kind(emit.kwargs["event"]) == "Shutdown"


def _sequence(tmp_path: Path) -> LiveSequence:
    return LiveSequence(plan_score_live(str(_bag(tmp_path)), f"{sys.executable} x.py", TOPIC,
                                        "/gnss/fix"))  # fmt: skip


def test_sequence_errors_end_the_launch(tmp_path) -> None:
    seq = _sequence(tmp_path)
    with pytest.raises(NodeFailedError, match="publishes /my_filter/odom as std_msgs/msg/String"):
        seq.on_output("bag_recorder", f"subscribed to {TOPIC} (std_msgs/msg/String, reliable)")
    seq = _sequence(tmp_path)
    with pytest.raises(NodeFailedError, match="exited with status 0 before the bag was played"):
        seq.on_exit("node", 0, False)
    seq = _sequence(tmp_path)
    with pytest.raises(NodeFailedError, match="bag_player exited with status 1"):
        seq.on_exit("bag_player", 1, False)
    seq = _sequence(tmp_path)
    with pytest.raises(NodeFailedError, match="bag_recorder exited with status 0"):
        seq.on_exit("bag_recorder", 0, False)  # before the node: it stopped by itself
    seq = _sequence(tmp_path)
    seq.on_exit("bag_player", 0, False)
    seq.on_exit("node", 0, False)
    seq.on_exit("bag_recorder", 0, False)
    with pytest.raises(NodeFailedError, match="strapdown-sim score exited with status 1"):
        seq.on_exit("score", 1, False)


def test_sequence_during_a_shutdown_does_nothing(tmp_path) -> None:
    """Ctrl-C: launch stops every process; their exits start nothing and give no reason."""
    seq = _sequence(tmp_path)
    for name, code in (("node", -2), ("bag_player", -2), ("bag_recorder", 0), ("score", 1)):
        assert seq.on_exit(name, code, True) == []


def test_node_ending_by_itself_after_the_play(tmp_path) -> None:
    """After the play, a node that ends by itself (status 0) lets the recorder stop; a failing
    one (status 1) ends the launch."""
    seq = _sequence(tmp_path)
    assert seq.on_exit("bag_player", 0, False) == [Step("signal", "node", "SIGINT", 2.0)]
    assert seq.on_exit("node", 0, False) == [Step("signal", "bag_recorder", "SIGINT")]
    with pytest.raises(NodeFailedError, match="the node exited with status 1"):
        _after_play(tmp_path).on_exit("node", 1, False)


def _after_play(tmp_path: Path) -> LiveSequence:
    seq = LiveSequence(plan_score_live(str(_bag(tmp_path / "a")), f"{sys.executable}", TOPIC,
                                       "/gnss/fix"))  # fmt: skip
    seq.on_exit("bag_player", 0, False)
    return seq


@pytest.mark.parametrize(
    ("over", "match"),
    [
        ({"node": "no-such-filter-command --x"}, "no-such-filter-command: command not found"),
        ({"node": ""}, "node:= is required"),
        ({"inputs": ""}, "inputs:= is required"),
        ({"inputs": TOPIC}, "is the estimate topic"),
        ({"topic": "odom"}, "an absolute name"),
        ({"rate_factor": "0"}, "must be > 0"),
        ({"force": "maybe"}, "must be true or false"),
    ],
)
def test_bad_launch_arguments_are_refused_before_anything_starts(tmp_path, launch_file, over,
                                                                 match) -> None:  # fmt: skip
    with pytest.raises(LaunchError, match=match):
        launch_file._actions(_context(tmp_path, **over))


def test_existing_recording_is_refused_unless_forced(tmp_path, launch_file) -> None:
    context = _context(tmp_path, out=str(tmp_path / "o"))
    (tmp_path / "o" / "estimate").mkdir(parents=True)
    with pytest.raises(LaunchError, match="exists already"):
        launch_file._actions(context)
    assert launch_file._actions({**context, "force": "true"})
    with pytest.raises(LaunchError, match="not a bag directory"):
        launch_file._actions({**context, "bag": str(tmp_path)})


def test_launch_description_declares_every_argument(launch_file) -> None:
    desc = launch_file.generate_launch_description()
    declared = [a.args[0] for a in desc.args[0] if type(a).__name__ == "DeclareLaunchArgument"]
    assert declared == list(launch_file.ARGUMENTS)
