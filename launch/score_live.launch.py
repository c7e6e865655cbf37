"""Play a bag into your node, record what it publishes, score it (``ros2 launch``).

    ros2 launch strapdown_ros score_live.launch.py bag:=out/suite/car_city \
        node:='ros2 run my_pkg my_filter' topic:=/my_filter/odom \
        inputs:='/variation/imu_measured,/gnss/fix' [out:=DIR] [force:=true] \
        [rate_factor:=1.0] [linger_s:=2.0] [scenario:=config/suite/car_city.yaml]

The same as ``strapdown-sim score BAG --topic TOPIC --node CMD --input ...`` (docs/score.md,
"Live"), as launch actions: ``bag_recorder`` on ``topic`` and your node start; once the
recorder has subscribed to your node's publisher (its type checked), ``bag_player`` plays the
``inputs`` (it waits for your node's subscriptions); after the play and ``linger_s``, your node
gets SIGINT, then the recorder, which closes ``out/estimate``; then ``strapdown-sim score``
writes ``out/score.json``, and the launch ends. Your node exiting before the end of the play,
any process failing, or a type the scorer cannot read stops everything with the reason (exit
status 1). Ctrl-C stops every process.

The decisions are in :mod:`strapdown_ros.score.live_launch` (standard library only);
``launch`` / ``launch_ros`` are imported inside the functions so that this file imports (and
is tested) without them.
"""

#: The launch arguments: name → (default, description).
ARGUMENTS = {
    "bag": ("", "bag directory to play (written by strapdown-sim generate or run)"),
    "node": ("", "the command that runs your node (split like a shell command line)"),
    "topic": ("", "the estimate topic your node publishes"),
    "inputs": ("", "the bag's topics your node subscribes to (comma- or space-separated)"),
    "out": ("", "the score's directory (default: BAG/score); the recording in OUT/estimate"),
    "force": ("false", "replace an existing OUT/estimate"),
    "rate_factor": ("1.0", "play speed over real time"),
    "linger_s": ("2.0", "seconds your node keeps running after the play"),
    "scenario": ("", "the scenario BAG was generated from (exact truth between samples)"),
}


def _actions(context):
    """OpaqueFunction: the launch arguments → the first actions and the sequence's handlers."""
    import signal
    from pathlib import Path

    from launch.actions import EmitEvent, ExecuteProcess, LogInfo, RegisterEventHandler, TimerAction
    from launch.event_handlers import OnProcessExit, OnProcessIO
    from launch.events import Shutdown, matches_action
    from launch.events.process import SignalProcess
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node
    from launch_ros.substitutions import FindPackagePrefix

    from strapdown_ros.launch_logic import node_interpreter
    from strapdown_ros.score.live_launch import (
        NODE,
        PLAYER,
        RECORDER,
        SCORE,
        LiveSequence,
        plan_score_live,
    )

    def arg(name):
        return LaunchConfiguration(name).perform(context)

    python = node_interpreter(FindPackagePrefix("strapdown_ros").perform(context))
    # strapdown-sim beside the nodes' interpreter (the venv of the documented pip step).
    strapdown_sim = str(Path(python).parent / "strapdown-sim")
    plan = plan_score_live(
        arg("bag"), arg("node"), arg("topic"), arg("inputs"), arg("out"), force=arg("force"),
        rate_factor=arg("rate_factor"), linger_s=arg("linger_s"), scenario=arg("scenario"),
        strapdown_sim=strapdown_sim,
    )  # fmt: skip
    sequence = LiveSequence(plan)
    procs = {
        RECORDER: Node(package="strapdown_ros", executable="bag_recorder", name="bag_recorder",
                       output="screen", parameters=[plan.recorder]),  # fmt: skip
        NODE: ExecuteProcess(cmd=plan.node, name="node", output="screen"),
        PLAYER: Node(package="strapdown_ros", executable="bag_player", name="bag_player",
                     output="screen", parameters=[plan.player]),  # fmt: skip
        SCORE: ExecuteProcess(cmd=plan.score, name="score", output="screen"),
    }

    def to_action(step):
        if step.kind == "start":
            action = procs[step.target]
        elif step.kind == "signal":
            action = EmitEvent(event=SignalProcess(
                signal_number=getattr(signal, step.sig),
                process_matcher=matches_action(procs[step.target]),
            ))  # fmt: skip
        else:
            action = EmitEvent(event=Shutdown(reason=step.reason))
        return TimerAction(period=step.after_s, actions=[action]) if step.after_s else action

    def exit_handler(name):
        def on_exit(event, launch_context):
            steps = sequence.on_exit(name, event.returncode, launch_context.is_shutdown)
            return [to_action(s) for s in steps]

        return RegisterEventHandler(OnProcessExit(target_action=procs[name], on_exit=on_exit))

    def output_handler(name):
        def on_output(event):
            return [to_action(s) for s in sequence.on_output(name, event.text.decode(
                "utf-8", "replace"))]  # fmt: skip

        return RegisterEventHandler(OnProcessIO(target_action=procs[name], on_stdout=on_output,
                                                on_stderr=on_output))  # fmt: skip

    return [
        LogInfo(msg=f"strapdown_ros: playing {plan.player['topics']} of {plan.player['bag']} "
                f"into {' '.join(plan.node)}; recording {plan.topic} into {plan.record_to}"),
        *(exit_handler(n) for n in procs),
        output_handler(RECORDER),
        procs[RECORDER],
        procs[NODE],
    ]  # fmt: skip


def generate_launch_description():
    """Return the launch description of the live score."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction

    args = [DeclareLaunchArgument(name, default_value=default, description=text)
            for name, (default, text) in ARGUMENTS.items()]  # fmt: skip
    return LaunchDescription([*args, OpaqueFunction(function=_actions)])
