"""Benchmark: bulk CDR serialization vs per-message rosbags ``serialize_cdr``, and the bag floor.

One synthetic stream of M cycles gives M Imu + (M+1) Odometry + (M+1) NavSatFix messages
(:mod:`strapdown_ros.messages`). In the same process:

* ``fields``: the three field containers from the stream, by separate calls and by
  :func:`strapdown_ros.messages.stream_fields` (shared E0 → ECEF and geodetic conversion);
* ``bulk``: :func:`strapdown_ros.bag.cdr.serialize` of the three field containers to
  ``list[bytes]``;
* ``rosbags``: ``Typestore.serialize_cdr`` called once per message on pre-built message objects
  (building the objects is timed separately, it is not counted in the speedup);
* ``floor``: :class:`strapdown_ros.bag.writer.BagWriter` writing the pre-serialized payloads,
  time-merged, to mcap (and sqlite3) — what writing a bag costs with serialization free.

The payloads of both serializers are checked byte-identical before the times count.

Usage: python bench/bench_serialize.py [--cycles 120000] [--repeats 3]
Last line: ``speedup_vs_rosbags: X x``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from rosbags.typesys import Stores, get_typestore

from strapdown_ros import messages as msg
from strapdown_ros.bag import cdr
from strapdown_ros.bag.writer import BagWriter, Batch
from strapdown_ros.core.rotations import dcm_from_rotvec
from strapdown_ros.core.stream import Stream

TS = get_typestore(Stores.ROS2_JAZZY)


def make_stream(cycles: int, seed: int = 0) -> Stream:
    rng = np.random.default_rng(seed)
    n = cycles + 1
    return Stream(
        t0_ns=1_700_000_000_000_000_000,
        period_ns=5_000_000,
        dalpha=rng.normal(size=(cycles, 3)) * 1e-3,
        dv=rng.normal(size=(cycles, 3)) * 0.05,
        c_b_e0=dcm_from_rotvec(rng.normal(size=(n, 3))),
        v_e0=rng.normal(size=(n, 3)) * 300.0,
        r_e0=np.array([4.2e6, 0.9e6, 4.7e6]) + rng.normal(size=(n, 3)) * 1e3,
    )


def rosbags_messages(f) -> list:
    """Message objects of a field container (the per-message path's input)."""
    T = TS.types
    time_t, header_t = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    vec, quat = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    sec, nsec = msg.stamps_to_sec_nanosec(f.stamps_ns)
    headers = [
        header_t(stamp=time_t(sec=int(s), nanosec=int(n)), frame_id=f.frame_id)
        for s, n in zip(sec, nsec, strict=True)
    ]
    out = []
    if isinstance(f, msg.ImuFields):
        for i, h in enumerate(headers):
            out.append(
                T[cdr.IMU](
                    header=h,
                    orientation=quat(*f.orientation[i].tolist()),
                    orientation_covariance=np.array(f.orientation_covariance[i]),
                    angular_velocity=vec(*f.angular_velocity[i].tolist()),
                    angular_velocity_covariance=np.array(f.angular_velocity_covariance[i]),
                    linear_acceleration=vec(*f.linear_acceleration[i].tolist()),
                    linear_acceleration_covariance=np.array(f.linear_acceleration_covariance[i]),
                )
            )
    elif isinstance(f, msg.OdometryFields):
        pose_t, point_t = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/Point"]
        twist_t = T["geometry_msgs/msg/Twist"]
        pwc, twc = (
            T["geometry_msgs/msg/PoseWithCovariance"],
            T["geometry_msgs/msg/TwistWithCovariance"],
        )
        for i, h in enumerate(headers):
            out.append(
                T[cdr.ODOMETRY](
                    header=h,
                    child_frame_id=f.child_frame_id,
                    pose=pwc(
                        pose=pose_t(
                            position=point_t(*f.position[i].tolist()),
                            orientation=quat(*f.orientation[i].tolist()),
                        ),
                        covariance=np.array(f.pose_covariance[i]),
                    ),
                    twist=twc(
                        twist=twist_t(
                            linear=vec(*f.twist_linear[i].tolist()),
                            angular=vec(*f.twist_angular[i].tolist()),
                        ),
                        covariance=np.array(f.twist_covariance[i]),
                    ),
                )
            )
    else:
        status_t = T["sensor_msgs/msg/NavSatStatus"]
        for i, h in enumerate(headers):
            out.append(
                T[cdr.NAVSATFIX](
                    header=h,
                    status=status_t(status=int(f.status[i]), service=int(f.service[i])),
                    latitude=float(f.latitude[i]),
                    longitude=float(f.longitude[i]),
                    altitude=float(f.altitude[i]),
                    position_covariance=np.array(f.position_covariance[i]),
                    position_covariance_type=int(f.position_covariance_type[i]),
                )
            )
    return out


def best_of(fn, repeats: int) -> tuple[float, object]:
    best, result = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    return best, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=120_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    stream = make_stream(args.cycles)

    t_fields, fields = best_of(
        lambda: (msg.imu_fields(stream), msg.odometry_fields(stream), msg.navsatfix_fields(stream)),
        args.repeats,
    )
    n_msgs = sum(len(f) for f in fields)
    print(
        f"messages: {n_msgs} ({args.cycles} Imu + {args.cycles + 1} Odometry + "
        f"{args.cycles + 1} NavSatFix)"
    )
    print(f"stream -> message fields (messages/): {t_fields:.3f} s (three separate calls)")
    t_shared, shared = best_of(lambda: msg.stream_fields(stream), args.repeats)
    trio = (shared.imu, shared.odometry, shared.navsatfix)
    assert all(a.equals(b) for a, b in zip(trio, fields, strict=True))
    print(f"  same with msg.stream_fields:          {t_shared:.3f} s (E0->E, geodetic once)")

    t_bulk, bulk = best_of(lambda: [cdr.serialize(f) for f in fields], args.repeats)
    print(
        f"bulk serialize (cdr.py):               {t_bulk:.3f} s "
        f"({t_bulk / n_msgs * 1e6:.2f} us/msg)"
    )

    t0 = time.perf_counter()
    objs = [rosbags_messages(f) for f in fields]
    t_build = time.perf_counter() - t0
    types = [cdr.msgtype_of(f) for f in fields]

    def per_message():
        return [[TS.serialize_cdr(m, t) for m in ms] for ms, t in zip(objs, types, strict=True)]

    t_ros, ros = best_of(per_message, 1)
    for mine, theirs in zip(bulk, ros, strict=True):
        assert len(mine) == len(theirs)
        assert all(a == b for a, b in zip(mine, theirs, strict=True)), "payloads differ"
    print(f"rosbags: build message objects:        {t_build:.3f} s (not counted)")
    print(
        f"rosbags: serialize_cdr per message:    {t_ros:.3f} s "
        f"({t_ros / n_msgs * 1e6:.2f} us/msg); payloads byte-identical to bulk"
    )

    batches = [
        Batch(t, cdr.msgtype_of(f), f.stamps_ns, p)
        for t, f, p in zip(
            ("/reference/imu", "/reference/odom", "/reference/fix"), fields, bulk, strict=True
        )
    ]
    with tempfile.TemporaryDirectory() as tmp:
        for storage in ("mcap", "sqlite3"):

            def write(storage=storage):
                out = Path(tmp) / f"bag_{storage}"
                with BagWriter(out, storage=storage, force=True) as w:
                    w.write_batches(batches)
                return sum(p.stat().st_size for p in out.iterdir())

            t_floor, size = best_of(write, 1)
            print(
                f"floor: BagWriter {storage:7s} pre-serialized: {t_floor:.3f} s "
                f"({t_floor / n_msgs * 1e6:.2f} us/msg, {size / 1e6:.1f} MB)"
            )
    print(f"speedup_vs_rosbags: {t_ros / t_bulk:.1f} x")


if __name__ == "__main__":
    main()
