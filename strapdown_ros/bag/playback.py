"""Playback of a rosbag2 directory without ROS: message source, read-ahead, pacing statistics.

:class:`BagSource` checks a bag (:func:`~strapdown_ros.bag.reader.check_bag`: missing
directory or metadata, unsupported storage, truncated or interrupted data file are refused with
the reason), selects and remaps its topics and yields the serialized messages in log-time order
from a start time on. :class:`ReaderProcess` reads them in a separate process and hands them
over in small batches, so that the publishing loop never waits for a chunk to be parsed.
:func:`pacing_stats` summarizes publish-time errors. The ``bag_player`` node
(:mod:`strapdown_ros.nodes.bag_player`) publishes on top of this.
"""

from __future__ import annotations

import collections
import os
import struct
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike
from rosbags.interfaces import Qos, QosDurability, QosReliability
from rosbags.rosbag2 import Reader

from strapdown_ros.bag.reader import BagReadError, check_bag

__all__ = [
    "BagSource",
    "ClockTicks",
    "PASS_END",
    "PacingWatch",
    "PacingStats",
    "PlayTopic",
    "ReaderProcess",
    "clock_payload",
    "pacing_stats",
]

CLOCK_MSGTYPE = "rosgraph_msgs/msg/Clock"
_CLOCK = struct.Struct("<4siI")
_CDR_LE = b"\x00\x01\x00\x00"


@dataclass
class PlayTopic:
    """A topic of the bag that is played."""

    index: int  #: position in :attr:`BagSource.topics`
    topic: str  #: name in the bag
    out_topic: str  #: name it is published on (after remapping)
    msgtype: str
    offered_qos: list[Qos]
    count: int  #: messages in the bag (metadata)

    @property
    def reliable(self) -> bool:
        """Publish RELIABLE unless a recorded publisher was BEST_EFFORT."""
        return all(q.reliability != QosReliability.BEST_EFFORT for q in self.offered_qos)

    @property
    def transient_local(self) -> bool:
        """Publish TRANSIENT_LOCAL when every recorded publisher was."""
        return bool(self.offered_qos) and all(
            q.durability == QosDurability.TRANSIENT_LOCAL for q in self.offered_qos
        )


class BagSource:
    """The selected topics of a bag, read in log-time order.

    Parameters
    ----------
    path : path
        rosbag2 directory.
    topics : iterable of str, optional
        Topics to play (names in the bag); all when None or empty. An unknown name raises
        :class:`~strapdown_ros.bag.reader.BagReadError`.
    remap : mapping of str to str, optional
        Bag topic name -> published name.

    Raises
    ------
    BagReadError
        The bag cannot be read; the message names the path and the problem.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        topics: Iterable[str] | None = None,
        remap: Mapping[str, str] | None = None,
    ) -> None:
        self.path = Path(path)
        self.info, self.files = check_bag(self.path)
        remap = dict(remap or {})
        try:
            self._reader = Reader(self.path)
            self._reader.open()
        except Exception as exc:  # rosbags ReaderError, apsw errors, struct errors
            raise BagReadError(
                f"cannot open bag {self.path}: {type(exc).__name__}: {exc} — the data file is "
                "truncated or corrupt"
            ) from exc
        conns = list(self._reader.connections)
        available = {c.topic for c in conns}
        wanted = set(topics or ())
        if wanted - available:
            self.close()
            raise BagReadError(
                f"bag {self.path} has no topic(s) {sorted(wanted - available)} "
                f"(topics: {sorted(available)})"
            )
        unknown = set(remap) - available
        if unknown:
            self.close()
            raise BagReadError(
                f"cannot remap {sorted(unknown)}: not in bag {self.path} "
                f"(topics: {sorted(available)})"
            )
        self.topics: list[PlayTopic] = []
        self._conns = []
        for c in conns:
            if wanted and c.topic not in wanted:
                continue
            self.topics.append(
                PlayTopic(
                    len(self.topics),
                    c.topic,
                    remap.get(c.topic, c.topic),
                    c.msgtype,
                    list(getattr(c.ext, "offered_qos_profiles", []) or []),
                    int(c.msgcount),
                )
            )
            self._conns.append(c)
        self._index = {id(c): i for i, c in enumerate(self._conns)}
        meta = self._reader
        self.message_count = sum(t.count for t in self.topics)
        self.start_ns = int(meta.start_time) if meta.message_count else 0
        self.end_ns = int(meta.end_time) - 1 if meta.message_count else 0

    def messages(
        self, start_ns: int | None = None, stop_ns: int | None = None
    ) -> Iterator[tuple[int, int, bytes]]:
        """``(topic index, log time ns, payload)`` of the selected topics with log times in
        ``[start_ns, stop_ns)`` (None: from the first, to the last).

        Raises :class:`BagReadError` when the data turns out unreadable on the way.
        """
        if not self._conns:
            return
        index = self._index
        messages = self._reader.messages(connections=self._conns, start=start_ns, stop=stop_ns)
        try:
            for conn, t, data in messages:
                yield index[id(conn)], t, data
        except BagReadError:
            raise
        except Exception as exc:
            raise BagReadError(
                f"bag {self.path} became unreadable while playing: {type(exc).__name__}: {exc}"
            ) from exc

    def close(self) -> None:
        """Close the data files."""
        reader, self._reader = getattr(self, "_reader", None), None
        if reader is not None:
            try:
                reader.close()
            except Exception:  # noqa: BLE001 - closing a reader that failed to open
                pass


#: :meth:`ReaderProcess.get` returns this at the end of a pass over the bag (``loop``).
PASS_END = "pass-end"
_FRAME = struct.Struct("<I")
#: Pipe buffer asked for (Linux ``F_SETPIPE_SZ``; the default 64 KiB works too).
_PIPE_SIZE = 1 << 20
#: Bytes read from the pipe per :meth:`ReaderProcess.refill`.
_READ_BYTES = 1 << 16


def _reader_main(argv: list[str]) -> int:
    """Reader process: write length-prefixed pickled batches of the bag's messages to stdout.

    ``argv``: ``PATH TOPICS_JSON START_NS STOP_NS LOOP BATCH`` (``STOP_NS`` empty: to the
    end). A batch is a list of
    ``(index, t, payload)`` items (:data:`PASS_END` after each pass); an empty frame ends the
    stream; a pickled ``{"error": text}`` reports a failure.
    """
    import json
    import pickle
    import signal
    import sys

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the player decides when to stop
    path, topics, start, stop, loop, batch = argv
    out = sys.stdout.buffer

    def send(obj: object) -> None:
        data = pickle.dumps(obj, protocol=5) if obj is not None else b""
        out.write(_FRAME.pack(len(data)) + data)
        out.flush()

    try:
        source = BagSource(path, json.loads(topics))
        try:
            while True:
                items: list[object] = []
                for item in source.messages(int(start), int(stop) if stop else None):
                    items.append(item)
                    if len(items) >= int(batch):
                        send(items)
                        items = []
                items.append(PASS_END)
                send(items)
                if loop != "1":
                    break
        finally:
            source.close()
        send(None)
    except (BrokenPipeError, OSError):
        return 0  # the player went away
    except BaseException as exc:  # reported by the player
        try:
            send({"error": str(exc)})
        except OSError:
            pass
        return 1
    return 0


class ReaderProcess:
    """Reads a bag in a separate process and hands its messages over in small batches.

    The bag's chunks are parsed by another process (on another core), so the publishing thread
    never waits for a parse and never competes with a reader thread for Python's GIL. It reads
    the pipe without blocking in :meth:`refill` (whatever has arrived) and unpickles complete
    batches; only :meth:`get` with an empty buffer waits.

    Parameters
    ----------
    source : BagSource
        The bag and topic selection (the process opens the bag again with the same topics).
    start_ns : int, optional
        First log time to read.
    stop_ns : int, optional
        Log time to stop before (None: to the end of the bag); with ``loop``, each pass is
        the window ``[start_ns, stop_ns)``.
    loop : bool
        Read the bag over and over (:data:`PASS_END` after each pass) until :meth:`close`.
    batch : int
        Messages per batch.
    high_water : int
        :meth:`refill` stops unpickling while this many messages are buffered.
    """

    def __init__(
        self,
        source: BagSource,
        start_ns: int | None = None,
        stop_ns: int | None = None,
        *,
        loop: bool = False,
        batch: int = 64,
        high_water: int = 20_000,
    ) -> None:
        import json
        import subprocess
        import sys

        args = [
            str(source.path),
            json.dumps([t.topic for t in source.topics]),
            str(source.start_ns if start_ns is None else start_ns),
            "" if stop_ns is None else str(stop_ns),
            "1" if loop else "0",
            str(batch),
        ]
        # the child imports this package from where the parent found it
        root = str(Path(__file__).resolve().parents[2])
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
        self._proc = subprocess.Popen(
            [sys.executable, "-m", "strapdown_ros.bag.playback", *args],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            env=env,
        )
        self._fd = self._proc.stdout.fileno()  # type: ignore[union-attr]
        try:
            import fcntl

            fcntl.fcntl(self._fd, getattr(fcntl, "F_SETPIPE_SZ", 1031), _PIPE_SIZE)
        except OSError:
            pass  # keep the default pipe size
        os.set_blocking(self._fd, False)
        self._raw = bytearray()
        self._buffer: collections.deque[object] = collections.deque()
        self._high_water = high_water
        self._eof = False  # the pipe is closed
        self._done = False  # the end marker (None) is in the buffer

    def _read(self, block: bool, limit: int = _READ_BYTES) -> None:
        """Read up to ``limit`` bytes the pipe holds (waiting for some first when ``block``)."""
        import select

        if self._eof:
            return
        if block:
            select.select([self._fd], [], [])
        try:
            data = os.read(self._fd, limit)
        except BlockingIOError:
            return
        if data:
            self._raw += data
        else:
            self._eof = True

    def _unpack(self, batches: int) -> None:
        """Unpickle at most ``batches`` complete batches from the raw bytes."""
        import pickle

        raw = self._raw
        for _ in range(batches):
            if self._done:
                return
            n = _FRAME.unpack_from(raw, 0)[0] if len(raw) >= 4 else -1
            if n < 0 or len(raw) < 4 + n:  # no complete frame
                if self._eof:
                    self._done = True
                    self._buffer.append(None)
                    if raw:
                        raise BagReadError("the bag reader process ended in the middle of a batch")
                return
            data = bytes(raw[4 : 4 + n])
            del raw[: 4 + n]
            if not n:  # end of the stream
                self._done = True
                self._buffer.append(None)
                return
            items = pickle.loads(data)
            if isinstance(items, dict):
                self._done = True
                self._buffer.append(None)
                raise BagReadError(items["error"])
            self._buffer.extend(items)

    def refill(self) -> None:
        """Take a little of what has arrived from the reader process, without waiting.

        At most one batch is unpickled and :data:`_READ_BYTES` read per call (tens of µs), so
        that a call between two publications never delays the next one.
        """
        if self._done or len(self._buffer) >= self._high_water:
            return
        if len(self._raw) < _READ_BYTES:
            self._read(block=False)
        self._unpack(1)

    def wait_ready(self) -> None:
        """Block until a batch (or the end) is here; the process takes a moment to start."""
        while not self._buffer:
            self._unpack(1)
            if self._buffer:
                return
            self._read(block=True)

    def get(self) -> tuple[int, int, bytes] | str | None:
        """Next ``(topic index, log time, payload)``, :data:`PASS_END`, or None at the end.

        Waits while the reader is behind; raises :class:`BagReadError` if it failed.
        """
        if not self._buffer:
            self.wait_ready()
            if not self._buffer:
                return None
        item = self._buffer[0]
        if item is not None:
            self._buffer.popleft()
        return item  # type: ignore[return-value]

    def close(self) -> None:
        """Stop the reader process."""
        proc = self._proc
        if proc.poll() is None:
            proc.terminate()
        try:
            proc.wait(timeout=5.0)
        except Exception:  # noqa: BLE001 - subprocess.TimeoutExpired
            proc.kill()
            proc.wait(timeout=5.0)
        if proc.stdout is not None:
            proc.stdout.close()


class ClockTicks:
    """When the player publishes ``/clock``: before a message whose log time starts a new
    ``period_ns`` interval of bag time counted from ``begin_ns`` (``period_ns`` 0: before
    each new log time). The clock carries that message's log time, so a subscriber on
    simulated time never sees a message stamped after its clock by more than one period."""

    def __init__(self, period_ns: int, begin_ns: int) -> None:
        self.period_ns = int(period_ns)
        self.begin_ns = int(begin_ns)
        self._last: int | None = None

    def due(self, t_ns: int) -> bool:
        """Whether ``/clock`` goes out before the message logged at ``t_ns`` (non-decreasing
        within a pass; :meth:`restart` between loop passes)."""
        key = t_ns if self.period_ns <= 0 else (t_ns - self.begin_ns) // self.period_ns
        if key == self._last:
            return False
        self._last = key
        return True

    def restart(self, begin_ns: int) -> None:
        """A new pass whose first log time is ``begin_ns``."""
        self.begin_ns = int(begin_ns)
        self._last = None


class PacingWatch:
    """Warnings while playing: publications later than ``threshold_s`` (publish time minus
    scheduled time), at most one text per ``interval_s`` of wall time summing up that
    interval (``threshold_s`` <= 0: never)."""

    def __init__(self, threshold_s: float, interval_s: float = 1.0) -> None:
        self.threshold_s = float(threshold_s)
        self.interval_s = float(interval_s)
        self._since: float | None = None  # wall time of the first late message not yet told
        self._late = 0
        self._worst = 0.0
        self.warnings = 0  #: texts returned so far

    def observe(self, error_s: float, now_s: float) -> str | None:
        """Take one publication's pacing error (s) at wall time ``now_s`` (s); returns the
        warning to log, if one is due."""
        if self.threshold_s <= 0:
            return None
        if error_s > self.threshold_s:
            if self._since is None:
                self._since = now_s
            self._late += 1
            self._worst = max(self._worst, error_s)
            if self.warnings == 0 or now_s - self._since >= self.interval_s:
                return self._tell()
        elif self._since is not None and now_s - self._since >= self.interval_s:
            return self._tell()
        return None

    def _tell(self) -> str:
        text = (
            f"pacing: {self._late} message(s) published more than "
            f"{self.threshold_s * 1e3:g} ms late (worst {self._worst * 1e3:.1f} ms); the "
            "machine is loaded (docs/recording.md: realtime_priority)"
        )
        self._since, self._late, self._worst = None, 0, 0.0
        self.warnings += 1
        return text


def clock_payload(stamp_ns: int) -> bytes:
    """Serialized ``rosgraph_msgs/Clock`` (CDR little endian) for ``stamp_ns``."""
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    return _CLOCK.pack(_CDR_LE, sec, nanosec)


@dataclass(frozen=True)
class PacingStats:
    """Publish time minus scheduled time (seconds) over the paced messages."""

    count: int
    p50: float
    p99: float
    max: float
    mean: float

    def format(self) -> str:
        """``p50 … ms, p99 … ms, max … ms`` (what the player logs)."""
        if not self.count:
            return "no paced messages"
        return (
            f"pacing error over {self.count} messages: p50 {self.p50 * 1e3:.3f} ms, "
            f"p99 {self.p99 * 1e3:.3f} ms, max {self.max * 1e3:.3f} ms "
            f"(mean {self.mean * 1e3:.3f} ms)"
        )


def pacing_stats(errors_s: ArrayLike) -> PacingStats:
    """p50, p99, max and mean of pacing errors (seconds; late is positive)."""
    e = np.asarray(errors_s, dtype=np.float64)
    if e.size == 0:
        return PacingStats(0, 0.0, 0.0, 0.0, 0.0)
    p50, p99 = np.percentile(e, [50.0, 99.0])
    return PacingStats(int(e.size), float(p50), float(p99), float(e.max()), float(e.mean()))


if __name__ == "__main__":
    import sys

    sys.exit(_reader_main(sys.argv[1:]))
