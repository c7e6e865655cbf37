"""``strapdown-sim replay --into navigator``: a bag's navigator input played into a live
``navigator_node``, its output recorded and compared with the offline navigator."""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from strapdown_ros.config import load_scenario
from strapdown_ros.pipeline.processes import Child, Children, PipelineError, check_out, list_param
from strapdown_ros.pipeline.result import ReplayResult
from strapdown_ros.pipeline.run import RECORDER_GRACE_S, STARTUP_TIMEOUT_S, say_to_stderr

if TYPE_CHECKING:
    from strapdown_ros.bag.reader import BagContents
    from strapdown_ros.config import Scenario
    from strapdown_ros.config.navigator import NavigatorSpec

__all__ = ["replay_into_navigator"]


def replay_into_navigator(
    bag: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    scenario_path: str | os.PathLike[str] | None = None,
    overrides: Sequence[str] = (),
    rate_factor: float = 1.0,
    force: bool = False,
    domain_id: int | None = None,
    timeout_s: float | None = None,
    progress: bool = True,
) -> ReplayResult:
    """Play a bag's navigator input into a live ``navigator_node`` and record its output.

    ``bag_player`` publishes the navigator's IMU and truth topics of ``bag`` paced at
    ``rate_factor`` (hardware-in-the-loop style); ``navigator_node`` (settings: the scenario's
    ``navigator`` section, else the node's defaults) processes them; ``bag_recorder`` writes
    ``/navigator/*`` to ``out``. The recording is then compared payload for payload with the
    offline navigator on the same messages (the bag's own ``/navigator/*`` topics when they were
    written with the same settings, else :func:`strapdown_ros.stages.navigator.navigate_messages`).
    """
    from strapdown_ros.bag.reader import read_bag
    from strapdown_ros.stages.navigator import OUTPUT_TOPICS, navigate_messages

    t_start = time.monotonic()
    out = Path(out)
    check_out(out, force)
    scenario, topics, settings = _navigator_settings(scenario_path, overrides)
    inputs = [settings.imu_topic] + ([settings.truth_topic] if settings.truth_topic else [])
    contents = read_bag(bag, inputs, raw=True)
    imu = contents.topics[settings.imu_topic]
    truth = contents.topics.get(settings.truth_topic) if settings.truth_topic else None
    if timeout_s is None:
        timeout_s = _duration_s(imu.log_time_ns) / max(rate_factor, 1e-3) + 120.0
    expected = navigate_messages(
        settings, imu.fields, truth.fields if truth else None,
        initial=scenario.initial if scenario else None,
        start_ns=scenario.start_time_ns if scenario else None,
    )  # fmt: skip
    out_topics = {k: topics[v] for k, v in OUTPUT_TOPICS.items()}
    recorded = [t for k, t in out_topics.items() if settings.truth_topic or not k.startswith("e")]
    children = Children(out, domain_id)
    say = say_to_stderr("replay", progress)
    try:
        say(f"ROS_DOMAIN_ID={children.domain}; logs in {children.log_dir}")
        recorder = children.start(
            "bag_recorder", f"output:={out}", "stop_when_done:=true",
            f"force:={str(force).lower()}", list_param("topics", recorded),
        )  # fmt: skip
        nav = children.start(
            "navigator_node", *_navigator_params(settings, scenario_path, overrides, recorded)
        )
        nav.wait_for("subscribed to", STARTUP_TIMEOUT_S, children.started)
        say(f"navigator_node subscribed; playing {', '.join(inputs)} of {bag}")
        player = children.start(
            "bag_player", f"bag:={Path(bag).resolve()}", f"rate_factor:={float(rate_factor)}",
            list_param("topics", inputs), "publish_clock:=false", "wait_for_subscribers:=1",
            "qos_depth:=10000",
        )  # fmt: skip
        _wait(children, recorder, nav, player, timeout_s)
    except BaseException:
        children.stop_all()
        raise
    finally:
        children.reap()
    result = _compare(read_bag(out, raw=True), out_topics, recorded, expected, out)
    result.elapsed_s = time.monotonic() - t_start
    return result


def _navigator_settings(
    scenario_path: str | os.PathLike[str] | None, overrides: Sequence[str]
) -> tuple[Scenario | None, dict[str, str], NavigatorSpec]:
    """``(scenario or None, recording topics, resolved NavigatorSpec)``: the scenario's
    navigator section, else the defaults."""
    from strapdown_ros.config import DEFAULT_TOPICS
    from strapdown_ros.config.navigator import NavigatorSpec, resolve_navigator

    if scenario_path is None:
        topics = dict(DEFAULT_TOPICS)
        return None, topics, resolve_navigator(NavigatorSpec(), topics, "j2")
    scenario = load_scenario(scenario_path, list(overrides))
    topics = dict(scenario.recording.topics)
    spec = scenario.navigator or NavigatorSpec()
    return scenario, topics, resolve_navigator(spec, topics, scenario.gravity_model)


def _duration_s(log_time_ns: np.ndarray) -> float:
    """Seconds of data of N messages at their median spacing ((N + 1) intervals; 0: N < 2)."""
    n = len(log_time_ns)
    return (n + 1) * float(np.median(np.diff(log_time_ns))) * 1e-9 if n > 1 else 0


def _navigator_params(
    settings: NavigatorSpec,
    scenario_path: str | os.PathLike[str] | None,
    overrides: Sequence[str],
    recorded: Sequence[str],
) -> list[str]:
    params = [f"imu_topic:={settings.imu_topic}", "qos_depth:=10000", "idle_timeout_s:=2.0"]
    params.append(f"truth_topic:={settings.truth_topic or '-'}")
    if scenario_path is not None:
        params.append(f"scenario:={Path(scenario_path).resolve()}")
        if overrides:
            params.append(list_param("overrides", overrides))
    params.append(list_param("subscribers_per_topic", [f"{t}=1" for t in recorded]))
    return params


def _wait(children: Children, recorder: Child, nav: Child, player: Child, timeout_s: float) -> None:
    """Until the recorder has finished (SIGTERM to it RECORDER_GRACE_S after the player and
    the navigator); PipelineError when a child fails or ``timeout_s`` passes."""
    deadline = time.monotonic() + timeout_s
    done_at: float | None = None
    while recorder.poll() is None:
        children.check()
        if player.poll() == 0 and nav.poll() == 0:
            done_at = done_at or time.monotonic()
            if time.monotonic() - done_at > RECORDER_GRACE_S:
                recorder.stop()
        if time.monotonic() > deadline:
            raise PipelineError(f"the replay did not finish within {timeout_s:g} s", nav.log)
        time.sleep(0.1)
    if recorder.proc.returncode != 0:
        raise PipelineError(f"bag_recorder exited with {recorder.proc.returncode}", recorder.log)


def _compare(
    got: BagContents,
    out_topics: dict[str, str],
    recorded: Sequence[str],
    expected: dict[str, list[bytes]],
    out: Path,
) -> ReplayResult:
    """The recorded payloads of each output topic against the offline navigator's."""
    result = ReplayResult(out=out, reference="the offline navigator on the bag's messages")
    for key, topic in out_topics.items():
        if topic not in recorded:
            continue
        payloads = [bytes(p) for p in got.topics[topic].payloads] if topic in got.topics else []
        result.counts[topic] = len(payloads)
        ref = expected.get(key, [])
        if payloads != ref:
            result.mismatches[topic] = f"{len(payloads)} recorded vs {len(ref)} expected" + (
                "" if len(payloads) != len(ref) else ", payloads differ"
            )
    return result
