"""Append-only rosbag2 writer for live recording: messages go to disk at every :meth:`flush`.

:class:`IncrementalBagWriter` writes a rosbag2 directory (mcap or sqlite3, metadata version 9,
the format of :class:`~strapdown_ros.bag.writer.BagWriter`) message by message, directly at its
destination. Unlike ``BagWriter`` it is not atomic: the point is that a recording killed
without warning (SIGKILL, power loss with ``fsync``) keeps everything written before the last
flush.

* **mcap**: messages are queued in memory and framed in bulk into chunks
  (:class:`~strapdown_ros.bag.mcap_chunks.BulkChunks`, the same file as ``rosbags``'
  per-message writer, a fraction of its CPU time); :meth:`flush` closes the chunk and writes
  it with its message indexes to the file (and ``fsync`` s it on request). A chunk is closed
  at 1 MiB too, as ``rosbags`` does. The summary section, the footer and ``metadata.yaml`` are
  written by :meth:`close`.
* **sqlite3**: messages are inserted in an open transaction; :meth:`flush` commits it (SQLite's
  journal makes the commit durable). ``metadata.yaml`` is written by :meth:`close`.

After a crash the directory has a data file without ``metadata.yaml`` (and, for mcap, without
summary and footer): ``strapdown-sim bag repair DIR`` (:mod:`strapdown_ros.bag.repair`) rebuilds
them from the flushed data. The writer relies on ``rosbags`` 0.11's storage writers
(``McapWriter.close_chunk``, ``Sqlite3Writer.conn``), the pinned version.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from rosbags.interfaces import Connection, Qos

from strapdown_ros.bag.mcap_chunks import BulkChunks
from strapdown_ros.bag.writer import (
    BagWriteError,
    BagWriterBase,
    check_destination,
    open_rosbags_writer,
)

__all__ = ["QUEUE_LIMIT", "IncrementalBagWriter"]

#: mcap: queued messages framed into the chunk at the latest after this many (memory bound).
QUEUE_LIMIT = 20_000


class IncrementalBagWriter(BagWriterBase):
    """Writes messages one by one into a rosbag2 directory, durable up to the last flush.

    Parameters
    ----------
    path : path
        Destination bag directory; it must not exist unless ``force``.
    storage : {"mcap", "sqlite3"}
        Storage plugin.
    compression : {"none", "zstd", "lz4"}
        MCAP chunk compression (mcap only); each flush compresses the chunk it closes.
    force : bool
        Replace an existing bag directory (or an empty directory) at ``path``.
    custom_data : mapping of str to str, optional
        Stored in the metadata ``custom_data``.
    qos : Qos, optional
        Offered QoS profile of a topic added without one (default
        :data:`~strapdown_ros.bag.qos.DEFAULT_QOS`).
    fsync : bool
        Also ``fsync`` the data file at every flush (survives power loss, not only a killed
        process; costs a disk sync per flush).
    bulk : bool
        mcap: queue the messages and frame them in bulk (default); False: ``rosbags``'
        per-message writer (the same file, several times the CPU time; for comparisons).

    Example
    -------
    ::

        bag = IncrementalBagWriter("out/rec").open()
        bag.add_topic("/reference/imu", "sensor_msgs/msg/Imu")
        bag.write("/reference/imu", stamp_ns, payload)
        bag.flush()        # everything so far survives a crash
        bag.close()        # summary + metadata.yaml
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        fsync: bool = False,
        bulk: bool = True,
        **settings: Any,
    ) -> None:
        super().__init__(path, **settings)
        self.fsync = fsync
        self.bulk = bulk
        self._flushed: dict[str, int] = {}
        self._bulk: BulkChunks | None = None

    # -- lifecycle -----------------------------------------------------------------------------

    def open(self) -> IncrementalBagWriter:
        """Create the bag directory and its data file; returns ``self``."""
        self._require_closed()
        p = self.path
        if check_destination(p, self.force):
            shutil.rmtree(p)
        p.parent.mkdir(parents=True, exist_ok=True)
        self._writer = open_rosbags_writer(p, self.storage, self.custom_data, self.compression)
        self._check_storage()
        if self.storage == "mcap" and self.bulk:
            self._bulk = BulkChunks(self._writer)
        self.flush()  # header (and sqlite schema) on disk before the first message
        return self

    def _check_storage(self) -> None:
        storage = self._require().storage
        need = (
            ("chunk", "bio", "chunks", "compressor", "compression", "channel_stats")
            if self.storage == "mcap" else ("conn",)
        )  # fmt: skip
        missing = [name for name in need if not hasattr(storage, name)]
        if missing:
            raise BagWriteError(
                f"the installed rosbags {self.storage} writer lacks {missing}; incremental "
                "writing needs rosbags 0.11 (requirements/constraints.txt)"
            )

    def close(self) -> Path:
        """Flush, write the index/summary and ``metadata.yaml``; returns the bag path."""
        writer = self._require()
        try:
            if self._bulk is not None:
                self._bulk.finish()
                self._bulk = None
            writer.close()
        except Exception as exc:
            raise BagWriteError(f"cannot finish bag {self.path}: {exc}") from exc
        finally:
            self._writer = None
        self._flushed = dict(self._counts)
        if self.fsync:
            _fsync_dir(self.path)
        return self.path

    @property
    def is_open(self) -> bool:
        """True between :meth:`open` and :meth:`close`."""
        return self._writer is not None

    # -- writing -------------------------------------------------------------------------------

    @property
    def flushed_counts(self) -> dict[str, int]:
        """Messages on disk as of the last flush, per topic (registration order)."""
        return {topic: self._flushed.get(topic, 0) for topic in self._counts}

    @property
    def topics(self) -> dict[str, str]:
        """Registered topic -> message type."""
        return {t: c.msgtype for t, c in self._connections.items()}

    def write(self, topic: str, stamp_ns: int, payload: bytes | memoryview) -> None:
        """Write one serialized message of a registered topic, logged at ``stamp_ns``."""
        self.write_connection(self.connection(topic), stamp_ns, payload)

    def write_connection(
        self, conn: Connection, stamp_ns: int, payload: bytes | memoryview
    ) -> None:
        """:meth:`write` with the connection looked up already (the recorder's hot path)."""
        if stamp_ns < 0:
            raise BagWriteError(f"{conn.topic}: negative log time {stamp_ns}")
        bulk = self._bulk
        if bulk is None:
            self._require().write(conn, stamp_ns, payload)
        else:
            bulk.append(conn.id, stamp_ns, payload)
            if len(bulk) >= QUEUE_LIMIT:
                bulk.materialize()
        self._counts[conn.topic] += 1

    def sink(self, conn: Connection) -> Callable[[int, bytes | memoryview], None]:
        """``write(stamp_ns, payload)`` of one registered connection: :meth:`write_connection`
        without the look-ups (the recorder calls it for every message)."""
        bulk = self._bulk
        if bulk is None:
            return lambda stamp_ns, payload: self.write_connection(conn, stamp_ns, payload)
        cid, topic = conn.id, conn.topic
        channels, times, payloads = bulk.channels.append, bulk.times.append, bulk.payloads
        push = payloads.append
        counts = self._counts

        def write(stamp_ns: int, payload: bytes | memoryview) -> None:
            if stamp_ns < 0:
                raise BagWriteError(f"{topic}: negative log time {stamp_ns}")
            channels(cid)
            times(stamp_ns)
            push(payload)
            counts[topic] += 1
            if len(payloads) >= QUEUE_LIMIT:
                bulk.materialize()

        return write

    def add_topic(
        self, topic: str, msgtype: str, qos: Qos | Sequence[Qos] | None = None
    ) -> Connection:
        """:meth:`BagWriterBase.add_topic`; the queued messages go into the chunk first
        (a new channel's records follow them there, as with the per-message writer)."""
        if self._bulk is not None and topic not in self._connections:
            self._bulk.materialize()
        return super().add_topic(topic, msgtype, qos)

    def flush(self) -> dict[str, int]:
        """Put everything written so far on disk; returns the flushed counts per topic."""
        storage = self._require().storage
        try:
            if self.storage == "mcap":
                if self._bulk is not None:
                    self._bulk.flush()
                elif storage.chunk.msgs:  # type: ignore[union-attr]
                    storage.close_chunk()  # type: ignore[union-attr]
                storage.bio.flush()  # type: ignore[union-attr]
                if self.fsync:
                    os.fsync(storage.bio.fileno())  # type: ignore[union-attr]
            else:
                storage.conn.commit()  # type: ignore[union-attr]
        except Exception as exc:
            raise BagWriteError(f"cannot flush bag {self.path}: {exc}") from exc
        self._flushed = dict(self._counts)
        return dict(self._flushed)

    def abort(self) -> None:
        """Stop writing without a summary or metadata (what a crash leaves; repairable)."""
        self._abort_writer()


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
