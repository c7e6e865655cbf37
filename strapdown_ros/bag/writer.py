"""rosbag2 writer for pre-serialized payloads (mcap or sqlite3), atomic on disk.

:class:`BagWriter` wraps ``rosbags.rosbag2.Writer`` (metadata version 9, the version ROS 2
Jazzy's rosbag2 0.26 writes; QoS profiles serialized with enum names). The bag is written into a
hidden temporary sibling directory and renamed into place only when everything succeeded, so an
error (or Ctrl-C) never leaves a half-written bag at the destination.

Batches of payloads (one topic each) are merged by stamp and written in time order; the log
time of every message is its header stamp (docs/interface.md §2). At equal stamps, messages keep the
order of
the batches as given.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from strapdown_ros.bag.batches import Batch, batch, clock_batch, merge_order, stream_batches
from strapdown_ros.bag.qos import DEFAULT_QOS
from strapdown_ros.core.stream import Stream

__all__ = [
    "BAG_VERSION",
    "COMPRESSIONS",
    "DEFAULT_QOS",
    "STORAGES",
    "TYPESTORE",
    "Batch",
    "BagWriter",
    "BagWriterBase",
    "BagWriteError",
    "batch",
    "check_compression",
    "check_destination",
    "clock_batch",
    "looks_like_bag",
    "open_rosbags_writer",
    "stream_batches",
    "write_stream_topics",
]

#: rosbag2 metadata version (Jazzy writes 9).
BAG_VERSION = 9
#: Storage identifiers accepted by :class:`BagWriter` (``mcap`` is Jazzy's default).
STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
#: MCAP chunk compressions (``none``, rosbag2's ``zstd_fast``/``zstd_small`` presets' zstd,
#: and lz4); a bag's ``metadata.yaml`` says ``compression_mode: ''`` either way, as rosbag2's.
COMPRESSIONS = ("none", "zstd", "lz4")

_TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
#: The ROS 2 Jazzy type store of ``rosbags`` (message definitions, type hashes).
TYPESTORE = _TYPESTORE


class BagWriteError(RuntimeError):
    """The bag cannot be written (destination exists, bad batch, ...)."""


def looks_like_bag(path: Path) -> bool:
    """True when the directory ``path`` has a ``metadata.yaml`` or a ``.mcap``/``.db3`` file."""
    if (path / "metadata.yaml").is_file():
        return True
    return any(p.suffix in {".mcap", ".db3"} for p in path.iterdir())


def check_destination(path: Path, force: bool) -> bool:
    """May a bag be written at ``path``? True if something is there that ``force`` replaces.

    Only a bag directory (:func:`looks_like_bag`) or an empty directory is replaced, and only
    with ``force``; anything else raises :class:`BagWriteError` saying why.
    """
    if not path.exists() and not path.is_symlink():
        return False
    if not force:
        raise BagWriteError(f"{path} exists already; not overwriting (use force=True / --force)")
    if not path.is_dir() or path.is_symlink():
        raise BagWriteError(f"{path} exists and is not a bag directory; refusing to replace it")
    if any(path.iterdir()) and not looks_like_bag(path):
        raise BagWriteError(
            f"{path} is a non-empty directory that is not a rosbag2 bag; refusing to replace it"
        )
    return True


def check_compression(storage: str, compression: str) -> None:
    """:class:`BagWriteError` unless ``compression`` is one of :data:`COMPRESSIONS` that
    ``storage`` can do (chunk compression is MCAP's: sqlite3 takes ``none`` only)."""
    if compression not in COMPRESSIONS:
        raise BagWriteError(
            f"unknown compression {compression!r}; choose one of {', '.join(COMPRESSIONS)}"
        )
    if compression != "none" and storage != "mcap":
        raise BagWriteError(f"{compression} chunk compression needs storage mcap, not {storage}")


def _lz4_chunks(writer: Writer) -> None:
    """Make the open ``rosbags`` MCAP storage compress its chunks with LZ4 (frame format, as
    the MCAP specification and rosbag2 write it); ``rosbags`` 0.11 writes zstd or nothing."""
    import lz4.frame

    storage = writer.storage
    if not (hasattr(storage, "compression") and hasattr(storage, "compressor")):
        raise BagWriteError(
            "the installed rosbags mcap writer has no chunk compressor to set; lz4 needs "
            "rosbags 0.11 (requirements/constraints.txt)"
        )
    storage.compression = "lz4"  # type: ignore[union-attr]
    storage.compressor = lz4.frame.compress  # type: ignore[union-attr]


def open_rosbags_writer(
    path: Path, storage: str, custom_data: Mapping[str, str], compression: str = "none"
) -> Writer:
    """An open ``rosbags`` writer of a new bag at ``path`` with ``custom_data`` in its metadata
    and its MCAP chunks compressed with ``compression`` (:data:`COMPRESSIONS`).

    Raises :class:`BagWriteError` when the bag cannot be created.
    """
    check_compression(storage, compression)
    writer = Writer(path, version=BAG_VERSION, storage_plugin=STORAGES[storage])
    if compression == "zstd":  # chunk compression of the storage plugin (metadata: none)
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    for key, value in custom_data.items():
        writer.set_custom_data(key, value)
    try:
        writer.open()
    except Exception as exc:  # rosbags WriterError, OSError
        raise BagWriteError(f"cannot create bag {path}: {exc}") from exc
    if compression == "lz4":
        try:
            _lz4_chunks(writer)
        except BaseException:
            writer.abort()
            raise
    return writer


class BagWriterBase:
    """What both writers do alike: the settings, the open ``rosbags`` writer and the topics.

    :class:`BagWriter` (atomic) and
    :class:`~strapdown_ros.bag.incremental.IncrementalBagWriter` (durable up to the last flush)
    differ in where they write and when the data reach the disk; registering topics, counting
    messages and aborting are the same.
    """

    #: Said when a method needs the open writer.
    _NOT_OPEN = "bag is not open"

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        storage: str = "mcap",
        compression: str = "none",
        force: bool = False,
        custom_data: Mapping[str, str] | None = None,
        qos: Qos = DEFAULT_QOS,
    ) -> None:
        if storage not in STORAGES:
            raise BagWriteError(f"unknown storage {storage!r}; choose one of {sorted(STORAGES)}")
        check_compression(storage, compression)
        self.path = Path(path).absolute()
        self.storage = storage
        self.compression = compression
        self.force = force
        self.custom_data = dict(custom_data or {"generator": "strapdown_ros"})
        self.qos = qos
        self._writer: Writer | None = None
        self._connections: dict[str, Connection] = {}
        self._counts: dict[str, int] = {}

    def _require(self) -> Writer:
        if self._writer is None:
            raise BagWriteError(self._NOT_OPEN)
        return self._writer

    def _require_closed(self) -> None:
        if self._writer is not None:
            raise BagWriteError("bag already open")

    @property
    def message_counts(self) -> dict[str, int]:
        """Messages written so far, per topic (registration order)."""
        return dict(self._counts)

    def add_topic(
        self, topic: str, msgtype: str, qos: Qos | Sequence[Qos] | None = None
    ) -> Connection:
        """Register ``topic`` with type ``msgtype`` (``pkg/msg/Name``) and its offered QoS
        profile(s) (default: the writer's ``qos``); idempotent."""
        writer = self._require()
        conn = self._connections.get(topic)
        if conn is not None:
            if conn.msgtype != msgtype:
                raise BagWriteError(
                    f"topic {topic} already has type {conn.msgtype}, cannot add {msgtype}"
                )
            return conn
        if msgtype not in _TYPESTORE.types:
            raise BagWriteError(f"unknown message type {msgtype!r}")
        profiles = [self.qos] if qos is None else [qos] if isinstance(qos, Qos) else list(qos)
        conn = writer.add_connection(
            topic, msgtype, typestore=_TYPESTORE, offered_qos_profiles=profiles
        )
        self._connections[topic] = conn
        self._counts[topic] = 0
        return conn

    def connection(self, topic: str) -> Connection:
        """The connection of a registered topic."""
        try:
            return self._connections[topic]
        except KeyError:
            raise BagWriteError(f"topic {topic} not registered (add_topic first)") from None

    def _abort_writer(self) -> None:
        """Stop the ``rosbags`` writer without a summary or metadata (best effort)."""
        writer, self._writer = self._writer, None
        if writer is not None:
            try:
                writer.abort()
            except Exception:  # noqa: BLE001 - best effort
                pass


class BagWriter(BagWriterBase):
    """Context manager writing a rosbag2 directory atomically.

    Parameters
    ----------
    path : path
        Destination bag directory.
    storage : {"mcap", "sqlite3"}
        Storage plugin (``mcap`` is Jazzy's default).
    compression : {"none", "zstd", "lz4"}
        MCAP chunk compression (mcap storage only).
    force : bool
        Replace an existing destination. Only a bag directory (``metadata.yaml``, ``*.mcap`` or
        ``*.db3`` inside) or an empty directory is replaced; anything else is refused. The old
        bag is removed only after the new one has been written completely.
    custom_data : mapping of str to str, optional
        Stored in the metadata ``custom_data`` (e.g. scenario name, generator version).
    qos : Qos, optional
        Offered QoS profile stored for every topic (default :data:`DEFAULT_QOS`).

    Example
    -------
    ::

        with BagWriter("out/run1") as bag:
            bag.write_batches([batch("/reference/imu", imu), batch("/reference/odom", odom)])
    """

    _NOT_OPEN = "bag is not open (use BagWriter as a context manager)"

    def __init__(self, path: str | os.PathLike[str], **settings: Any) -> None:
        super().__init__(path, **settings)
        self._tmpdir: Path | None = None
        self._check_destination()

    # -- destination ---------------------------------------------------------------------------

    def _check_destination(self) -> None:
        check_destination(self.path, self.force)

    # -- context management --------------------------------------------------------------------

    def open(self) -> BagWriter:
        """Create the temporary bag (called by ``__enter__``)."""
        self._require_closed()
        self._check_destination()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmpdir = Path(
            tempfile.mkdtemp(prefix=f".{self.path.name}.tmp-", dir=self.path.parent)
        )
        try:
            writer = open_rosbags_writer(
                self._tmpdir / self.path.name, self.storage, self.custom_data, self.compression
            )
        except BaseException:
            self._cleanup()
            raise
        self._writer = writer
        return self

    def close(self) -> Path:
        """Finish the bag and move it to its destination; returns the destination path."""
        writer = self._require()
        try:
            writer.close()
            self._writer = None
            src = self._tmpdir / self.path.name  # type: ignore[operator]
            if self.path.exists() or self.path.is_symlink():
                self._check_destination()
                shutil.rmtree(self.path)
            os.replace(src, self.path)
        except BaseException:
            self.abort()
            raise
        self._cleanup()
        return self.path

    def abort(self) -> None:
        """Discard everything written so far (destination untouched)."""
        self._abort_writer()
        self._cleanup()

    def _cleanup(self) -> None:
        tmp, self._tmpdir = self._tmpdir, None
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)

    def __enter__(self) -> BagWriter:
        return self.open()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    # -- writing -------------------------------------------------------------------------------

    def write(self, topic: str, stamp_ns: int, payload: bytes | memoryview) -> None:
        """Write one pre-serialized message of a registered topic, logged at ``stamp_ns``."""
        writer = self._require()
        conn = self.connection(topic)
        writer.write(conn, int(stamp_ns), payload)
        self._counts[topic] += 1

    def write_batches(
        self, batches: Iterable[Batch], progress: Callable[[int, int], None] | None = None
    ) -> int:
        """Write several topics' batches merged in stamp order; returns the number of messages.

        The sort is stable: at equal stamps the order of ``batches`` (then of the payloads within
        a batch) is kept. Stamps must be non-negative (rosbag2 log times are unsigned).
        ``progress(done, total)`` is called every 50 000 messages and at the end.
        """
        writer = self._require()
        batches = list(batches)
        conns: list[Connection] = []
        stamps: list[NDArray[np.int64]] = []
        for b in batches:
            conns.append(self.add_topic(b.topic, b.msgtype))
            t = np.asarray(b.stamps_ns, dtype=np.int64)
            if t.shape != (len(b.payloads),):
                raise BagWriteError(f"{b.topic}: {t.shape} stamps for {len(b.payloads)} payloads")
            stamps.append(t)
        if not batches:
            return 0
        all_t = np.concatenate(stamps)
        if all_t.size and all_t.min() < 0:
            raise BagWriteError("negative stamps cannot be bag log times")
        write = writer.write
        payloads = [b.payloads for b in batches]
        total = int(all_t.size)
        for n, (k, i, t) in enumerate(merge_order(batches), 1):
            write(conns[k], t, payloads[k][i])
            if progress is not None and (n % 50_000 == 0 or n == total):
                progress(n, total)
        for b in batches:
            self._counts[b.topic] += len(b.payloads)
        return int(all_t.size)


def write_stream_topics(writer: BagWriter, stream: Stream, **kwargs: object) -> int:
    """Write the Imu/Odometry/NavSatFix topics of one stream in time order (see
    :func:`stream_batches` for the keyword arguments); returns the number of messages.

    To interleave several streams in one time order, pass all their batches to one
    :meth:`BagWriter.write_batches` call instead.
    """
    return writer.write_batches(stream_batches(stream, **kwargs))  # type: ignore[arg-type]
