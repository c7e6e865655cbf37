"""What the commands can and cannot do with a bag strapdown_ros did not write.

Any rosbag2 bag reads (``strapdown_ros.bag.reader``); what the commands make of it depends on
its topics. A robot's bag (``/imu`` sensor_msgs/Imu at 100 Hz, ``/odom`` nav_msgs/Odometry at
50 Hz in an ``odom`` frame, no strapdown metadata) gets a statement per command instead of a
verdict it cannot support (docs/interface.md §6, "Bags from other tools").
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["capability_lines", "is_foreign"]

IMU = "sensor_msgs/msg/Imu"
ODOMETRY = "nav_msgs/msg/Odometry"
NAVSATFIX = "sensor_msgs/msg/NavSatFix"


def is_foreign(custom_data: Mapping[str, str]) -> bool:
    """Whether the bag's metadata does not name strapdown_ros as its generator."""
    return str(custom_data.get("generator", "")).strip() != "strapdown_ros"


def _list(topics: list[str]) -> str:
    return ", ".join(f"`{t}`" for t in topics) if topics else "none"


def capability_lines(custom_data: Mapping[str, str], types: Mapping[str, str]) -> list[str]:
    """What ``check``, ``report`` and ``replay`` do with a bag of these topics (name → type).

    Names and types only (the metadata); whether a named pair has the stream layout (stamps,
    ECEF) is for ``check`` to say.
    """
    imus = [t for t, ty in types.items() if ty == IMU]
    odoms = [t for t, ty in types.items() if ty == ODOMETRY]
    fixes = [t for t, ty in types.items() if ty == NAVSATFIX]
    pairs = [
        f"{t} + {t[: -len('imu')]}odom"
        for t in imus
        if t.endswith("/imu") and t[: -len("imu")] + "odom" in odoms
    ]
    origin = (
        "written by strapdown_ros"
        if not is_foreign(custom_data)
        else "not written by strapdown_ros (its metadata has no `generator: strapdown_ros`, "
        "so no gravity model or scenario settings are recorded)"
    )
    return [
        f"this bag was {origin}; Imu topics: {_list(imus)}; Odometry: {_list(odoms)}; "
        f"NavSatFix: {_list(fixes)}",
        "check:  verifies docs/interface.md §3 on `P/imu` + `P/odom` pairs with the stream "
        f"layout (ECEF Odometry, Imu m stamped like Odometry m); named pairs here: "
        f"{_list(pairs)}",
        "report: plots every Imu topic (rates and specific force, in the message's frame), "
        "Odometry and NavSatFix in ECEF as trajectories, navigator errors and aiding topics; "
        "Odometry in a local frame (`odom`, `map`) and other types are listed, not plotted",
        "replay: plays a navigator's Imu stream and its ECEF truth (a generated bag's "
        "`P/imu` + `P/odom`, as `check` verifies them) into navigator_node; "
        + ("the named pairs above are candidates (`--set navigator.imu_topic=...`)"
           if pairs else "this bag has no such pair"),
    ]
