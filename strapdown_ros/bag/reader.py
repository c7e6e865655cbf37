"""Read a rosbag2 directory (mcap or sqlite3) back into message field containers.

``rosbags.rosbag2.Reader`` supplies the raw payloads; the bulk codec
(:func:`strapdown_ros.bag.cdr.deserialize`) turns each topic's payloads into one field container
(:mod:`strapdown_ros.messages`). Topics of types without a bulk codec are returned raw.

Failures are reported as :class:`BagReadError` with the path and what is wrong: missing
directory, missing ``metadata.yaml``, unsupported storage, missing or truncated data file.

The reader also describes bags (:func:`bag_info`, ``strapdown-sim bag info``), including those
it cannot read (interrupted, truncated, foreign): their MCAP files are read with the format's
own library, ``mcap`` (:class:`McapScan`, which ``strapdown-sim bag repair`` uses too).
"""

from __future__ import annotations

import datetime
import io
import os
import sqlite3
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import (
    Channel,
    Chunk,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Message,
    Schema,
)
from mcap.stream_reader import StreamReader, get_chunk_data_stream
from numpy.typing import NDArray
from rosbags.rosbag2 import Reader

from strapdown_ros.bag import cdr

__all__ = [
    "BagContents",
    "BagReadError",
    "McapScan",
    "TopicData",
    "bag_info",
    "check_bag",
    "read_bag",
]

_MCAP_MAGIC = b"\x89MCAP0\r\n"
_SQLITE_MAGIC = b"SQLite format 3\x00"
_STORAGES = ("mcap", "sqlite3")


class BagReadError(RuntimeError):
    """A bag cannot be read; the message names the path and the problem."""


@dataclass
class TopicData:
    """All messages of one topic.

    ``fields`` is the field container (e.g. :class:`~strapdown_ros.messages.ImuFields`) when the
    type has a bulk codec, else None and ``payloads`` holds the raw CDR payloads.
    """

    topic: str
    msgtype: str
    log_time_ns: NDArray[np.int64]
    fields: object | None = None
    payloads: list[bytes] | None = None

    def __len__(self) -> int:
        return int(self.log_time_ns.shape[0])


@dataclass
class BagContents:
    """A bag read into memory: metadata and per-topic data."""

    path: Path
    storage: str
    version: int
    message_count: int
    custom_data: dict[str, str]
    topics: dict[str, TopicData] = field(default_factory=dict)

    def __getitem__(self, topic: str) -> object:
        """Field container of ``topic`` (raises KeyError naming the available topics)."""
        try:
            data = self.topics[topic]
        except KeyError:
            raise KeyError(
                f"topic {topic!r} not in bag {self.path} (topics: {sorted(self.topics)})"
            ) from None
        if data.fields is None:
            raise KeyError(
                f"topic {topic!r} has type {data.msgtype} without a bulk decoder; "
                "use .topics[topic].payloads"
            )
        return data.fields


def _load_metadata(path: Path) -> dict:
    if not path.exists():
        raise BagReadError(f"bag directory {path} does not exist")
    if not path.is_dir():
        raise BagReadError(
            f"{path} is not a directory; pass the bag directory that holds "
            "metadata.yaml and the data files"
        )
    meta_path = path / "metadata.yaml"
    if not meta_path.is_file():
        raise BagReadError(
            f"{path} has no metadata.yaml: not a rosbag2 directory, or its recording was "
            f"interrupted (`strapdown-sim bag repair {path}` rebuilds the metadata)"
        )
    try:
        doc = yaml.safe_load(meta_path.read_text(encoding="utf-8"))
        info = doc["rosbag2_bagfile_information"]
        info["storage_identifier"], info["relative_file_paths"]  # noqa: B018 - key check
    except (OSError, yaml.YAMLError, TypeError, KeyError) as exc:
        raise BagReadError(f"{meta_path} is not valid rosbag2 metadata: {exc!r}") from None
    storage = info["storage_identifier"]
    if storage not in _STORAGES:
        raise BagReadError(
            f"bag {path} uses storage {storage!r}; only {', '.join(_STORAGES)} can be read"
        )
    return info


def _check_files(path: Path, info: dict) -> list[Path]:
    files = [path / Path(p).name for p in info["relative_file_paths"]]
    for f in files:
        if not f.is_file():
            raise BagReadError(f"bag {path}: data file {f.name} listed in metadata.yaml is missing")
        compressed = (info.get("compression_mode") or "").lower() == "file"
        if compressed:
            continue
        size = f.stat().st_size
        if info["storage_identifier"] == "mcap":
            with f.open("rb") as fh:
                head = fh.read(len(_MCAP_MAGIC))
                fh.seek(max(0, size - len(_MCAP_MAGIC)))
                tail = fh.read(len(_MCAP_MAGIC))
            if head != _MCAP_MAGIC:
                raise BagReadError(f"bag {path}: {f.name} is not an MCAP file")
            if size < 2 * len(_MCAP_MAGIC) or tail != _MCAP_MAGIC:
                raise BagReadError(
                    f"bag {path}: {f.name} is truncated ({size} bytes, no MCAP end magic); the "
                    f"recording was probably interrupted (`strapdown-sim bag repair {path}`)"
                )
        else:
            with f.open("rb") as fh:
                head = fh.read(100)
            if head[:16] != _SQLITE_MAGIC:
                raise BagReadError(f"bag {path}: {f.name} is not an SQLite database")
            if f.with_name(f.name + "-journal").exists():
                raise BagReadError(
                    f"bag {path}: {f.name} has a rollback journal ({f.name}-journal): its "
                    f"recording was interrupted (`strapdown-sim bag repair {path}`)"
                )
            page = int.from_bytes(head[16:18], "big")
            page = 65536 if page == 1 else page
            pages = int.from_bytes(head[28:32], "big")
            if page and pages and size < page * pages:
                raise BagReadError(
                    f"bag {path}: {f.name} is truncated ({size} bytes, header says {page * pages})"
                )
    return files


def check_bag(path: str | os.PathLike[str]) -> tuple[dict, list[Path]]:
    """Check a bag directory as :func:`read_bag` does, without reading messages.

    Returns the ``rosbag2_bagfile_information`` mapping of ``metadata.yaml`` and the data
    files; raises :class:`BagReadError` (missing directory or metadata, unsupported storage,
    missing, truncated or interrupted data file).
    """
    path = Path(path)
    info = _load_metadata(path)
    return info, _check_files(path, info)


def read_bag(
    path: str | os.PathLike[str],
    topics: Iterable[str] | None = None,
    *,
    raw: bool = False,
) -> BagContents:
    """Read a bag directory into per-topic field containers.

    Parameters
    ----------
    path : path
        rosbag2 directory (``metadata.yaml`` + ``*.mcap`` or ``*.db3``).
    topics : iterable of str, optional
        Only these topics (all when None). Unknown names raise :class:`BagReadError`.
    raw : bool
        Also keep the raw payloads of decoded topics (``TopicData.payloads``).

    Returns
    -------
    BagContents
        ``contents["/reference/imu"]`` is the topic's field container; ``contents.topics`` has
        the log times, types and raw payloads.
    """
    path = Path(path)
    info = _load_metadata(path)
    files = _check_files(path, info)
    wanted = None if topics is None else set(topics)
    try:
        with Reader(path) as reader:
            conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
            if wanted is not None:
                missing = wanted - {c.topic for c in conns}
                if missing:
                    raise BagReadError(
                        f"bag {path} has no topic(s) {sorted(missing)} "
                        f"(topics: {sorted({c.topic for c in reader.connections})})"
                    )
            types = {c.topic: c.msgtype for c in conns}
            stamps: dict[str, list[int]] = {t: [] for t in types}
            payloads: dict[str, list[bytes]] = {t: [] for t in types}
            if conns:
                for conn, t, data in reader.messages(connections=conns):
                    stamps[conn.topic].append(t)
                    payloads[conn.topic].append(data)
    except BagReadError:
        raise
    except Exception as exc:  # rosbags ReaderError, apsw errors, struct errors on bad data
        names = ", ".join(f.name for f in files)
        raise BagReadError(
            f"cannot read bag {path} ({names}): {type(exc).__name__}: {exc} — the data file is "
            "truncated or corrupt"
        ) from exc
    out = BagContents(
        path=path,
        storage=str(info["storage_identifier"]),
        version=int(info.get("version", 0)),
        message_count=int(info.get("message_count", 0)),
        custom_data={str(k): str(v) for k, v in (info.get("custom_data") or {}).items()},
    )
    for topic, msgtype in types.items():
        log_t = np.asarray(stamps[topic], dtype=np.int64)
        data = TopicData(topic, msgtype, log_t)
        if msgtype in cdr.MSGTYPES:
            try:
                data.fields = cdr.deserialize(msgtype, payloads[topic])
            except cdr.CdrError as exc:
                if msgtype != cdr.TF_MESSAGE:
                    raise BagReadError(f"bag {path}, topic {topic}: {exc}") from exc
                # /tf mixes transforms of several frame pairs: kept as payloads (messages.md)
                data.payloads = payloads[topic]
            if raw:
                data.payloads = payloads[topic]
        else:
            data.payloads = payloads[topic]
        out.topics[topic] = data
    return out


# ---------------------------------------------------------------------------------------------
# MCAP files read with the format's library, also when cut short


#: What the ``mcap`` library raises on data it cannot read: its own errors (``EndOfFile``,
#: ``InvalidMagic``, ``RecordLengthLimitExceeded``, unsupported compression), and, on a record cut
#: inside a fixed-size field, the bare ``struct.error`` of its unpacking; ``ValueError`` covers
#: chunk CRC mismatches (``CRCValidationError``) and undecodable strings.
MCAP_READ_ERRORS = (McapError, struct.error, ValueError)


class McapScan:
    """The records of one MCAP file in file order, read with the ``mcap`` library.

    :meth:`records` yields the Header, the Schema, Channel and Message records (those inside
    chunks too: each chunk is decompressed and its CRC checked by
    ``mcap.stream_reader.get_chunk_data_stream``, its records read by a ``StreamReader`` over
    them), Metadata and Attachment records, up to the end of the data section. Index and summary
    records are not yielded (a writer rebuilds them).

    A file cut short (a killed recorder) is read up to its last complete record. The library's
    ``StreamReader`` does not stop there by itself: it raises (``EndOfFile``, or a bare
    ``struct.error`` when the cut falls in a length field) and never yields a record it could
    not read completely — so everything yielded before that is whole. What no library does is
    done here by hand, and only that:

    * find the offset of the record the reader stopped at (``StreamReader`` does not expose its
      position): the 9-byte opcode/length prefixes are walked from the end of the last record
      it yielded;
    * salvage a **chunk cut short**: the library reads a chunk only whole (its padding read
      raises first); the chunk's header fields are parsed with ``mcap.records.Chunk.read``, and
      its records, if uncompressed (the recorder's are), with a second ``StreamReader`` over the
      bytes that are there — which again yields only complete records. A compressed chunk cut
      short cannot be decompressed: its messages are lost (noted);
    * check that each record inside a chunk spans exactly the length its prefix declares: the
      library's ``Message.read`` accepts a corrupt length below its 22-byte header and then
      reads on to the end of the chunk, and ``breakup_chunk`` reads a length beyond the chunk
      as whatever bytes are left — both without an error.

    After :meth:`records` is exhausted: ``complete`` (the data section end was reached),
    ``end`` (offset just after the last complete record, or of the data section end),
    ``salvaged`` (messages taken from a chunk cut short), ``notes``.
    """

    MAGIC = b"\x89MCAP0\r\n"

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.size = self.path.stat().st_size
        self.complete = False
        self.cut = False  #: the file ends inside a record
        self.end = 0
        self.salvaged = 0
        self.notes: list[str] = []
        with self.path.open("rb") as fh:
            head = fh.read(len(self.MAGIC))
        if head != self.MAGIC[: len(head)]:
            raise BagReadError(f"{self.path.name} is not an MCAP file (no MCAP magic at its start)")

    @property
    def dropped(self) -> int:
        """Bytes after the last complete record (0 for a file with a complete data section)."""
        return 0 if self.complete else self.size - self.end

    def records(self) -> Iterator[McapRecord]:
        """Yield the records (see the class documentation); fills in the attributes."""
        with self.path.open("rb") as fh:
            if self.size < len(self.MAGIC):  # cut inside the magic: nothing in it
                self.cut, self.end = True, 0
                return
            reader = StreamReader(fh, emit_chunks=True, record_size_limit=self.size)
            self.end = len(self.MAGIC)
            try:
                for rec in reader.records:
                    start, self.end = self.end, fh.tell()  # the reader stops at a record's end
                    if isinstance(rec, Chunk):
                        try:
                            stream, size = get_chunk_data_stream(rec, validate_crc=True)
                            data = stream.read(size)
                        except MCAP_READ_ERRORS as exc:
                            self.notes.append(
                                f"chunk at byte {start} is corrupt ({exc}); its messages are "
                                "skipped"
                            )
                            continue
                        yield from self._chunk_records(data, start, partial=False)
                    elif isinstance(rec, (DataEnd, Footer)):
                        self.complete = True
                        return
                    else:
                        yield rec
            except MCAP_READ_ERRORS as exc:
                error = exc
            else:  # pragma: no cover - StreamReader stops only at a footer or by raising
                return
            yield from self._after_stop(fh, error)

    def _after_stop(self, fh: io.BufferedReader, error: Exception) -> Iterator[McapRecord]:
        """By hand: where the reader stopped, and the complete records of a chunk cut short."""
        pos = self.end
        known = {int(op) for op in Opcode}
        while True:
            fh.seek(pos)
            prefix = fh.read(9)
            if len(prefix) < 9:  # cut inside an opcode/length prefix (or at a record boundary)
                self.cut = pos < self.size
                break
            op, length = struct.unpack("<BQ", prefix)
            if pos + 9 + length > self.size:  # the record the file was cut in
                self.cut = True
                if op == Opcode.CHUNK:
                    yield from self._salvage_chunk(fh, pos)
                break
            if op in known:  # a whole record the library could not read: corrupt
                self.notes.append(
                    f"unreadable record (opcode 0x{op:02x}) at byte {pos}: "
                    f"{type(error).__name__}: {error}; the {self.size - pos} bytes from there "
                    "on are dropped"
                )
                break
            pos += 9 + length  # a record of an unknown opcode the library skipped
        self.end = pos

    def _salvage_chunk(self, fh: io.BufferedReader, pos: int) -> Iterator[McapRecord]:
        fh.seek(pos + 9)
        try:
            chunk = Chunk.read(ReadDataStream(io.BytesIO(fh.read())))
        except MCAP_READ_ERRORS:
            return  # cut inside the chunk's header fields: no record in it
        if chunk.compression:
            self.notes.append(
                f"the chunk at byte {pos} is cut short and {chunk.compression}-compressed: its "
                "messages cannot be recovered"
            )
            return
        yield from self._chunk_records(chunk.data, pos, partial=True)

    def _chunk_records(self, data: bytes, pos: int, partial: bool) -> Iterator[McapRecord]:
        """The Schema, Channel and Message records of a chunk's (uncompressed) records."""
        buf, done = io.BytesIO(data), 0
        try:
            for rec in StreamReader(buf, skip_magic=True, record_size_limit=len(data)).records:
                (length,) = struct.unpack_from("<Q", data, done + 1)  # by hand: see the class
                if buf.tell() - done != 9 + length:
                    raise ValueError(f"a record of {length} bytes read as {buf.tell() - done - 9}")
                done = buf.tell()
                if isinstance(rec, (Schema, Channel, Message)):
                    self.salvaged += partial and isinstance(rec, Message)
                    yield rec
        except MCAP_READ_ERRORS as exc:
            if done < len(data) and not partial:  # (partial: the record the chunk was cut in)
                self.notes.append(
                    f"chunk at byte {pos}: corrupt record at offset {done} of its records "
                    f"({exc}); the rest of the chunk is dropped"
                )


# ---------------------------------------------------------------------------------------------
# bag info


def bag_info(path: str | os.PathLike[str]) -> str:
    """Describe the bag at ``path`` (``strapdown-sim bag info``).

    A bag that reads: storage, files, start, duration, message count, ``custom_data`` and the
    topics with counts, types and offered reliability, from ``metadata.yaml``. Any other
    directory is described from what it holds — ``metadata.yaml`` if it loads, and each data
    file as its own format reads it (MCAP with the ``mcap`` library, also when cut short; SQLite
    read-only) — and the ``status:`` line says why it does not read and what to do (e.g. run
    ``strapdown-sim bag repair``): an interrupted recording, a truncated data file, a foreign
    MCAP file without ``metadata.yaml``, an empty directory.

    Raises :class:`BagReadError` only when ``path`` is not a directory.
    """
    path = Path(path)
    if not path.is_dir():
        what = "does not exist" if not path.exists() else "is not a directory"
        raise BagReadError(f"bag directory {path} {what}")
    try:
        info, files = check_bag(path)
    except BagReadError as exc:
        return "\n".join(_describe_unreadable(path, str(exc)))
    try:
        status = "status:    complete: metadata.yaml and data files check out"
        lines = [f"bag:       {path}", status]
        return "\n".join(lines + _metadata_lines(info, files))
    except (KeyError, TypeError, ValueError, AttributeError, OSError) as exc:
        return "\n".join(_describe_unreadable(path, f"metadata.yaml is malformed: {exc!r}"))


def _utc(ns: int) -> str:
    sec, frac = divmod(int(ns), 1_000_000_000)
    stamp = datetime.datetime.fromtimestamp(sec, tz=datetime.UTC).strftime("%Y-%m-%dT%H:%M:%S")
    return f"{stamp}.{frac:09d}Z"


def _metadata_lines(info: dict, files: list[Path]) -> list[str]:
    count = int(info.get("message_count", 0))
    start = int((info.get("starting_time") or {}).get("nanoseconds_since_epoch", 0))
    duration = int((info.get("duration") or {}).get("nanoseconds", 0))
    size = sum(f.stat().st_size for f in files if f.is_file())
    lines = [
        f"storage:   {info['storage_identifier']} (metadata version {info.get('version')}), "
        f"{', '.join(f.name for f in files)}, {size / 2**20:.1f} MiB",
        f"start:     {_utc(start) if count else '-'}",
        f"duration:  {duration * 1e-9:.3f} s",
        f"messages:  {count}",
    ]
    custom = info.get("custom_data") or {}
    if custom:
        lines.append("custom:    " + ", ".join(f"{k}={v}" for k, v in custom.items()))
    topics = info.get("topics_with_message_count") or []
    width = max((len(t["topic_metadata"]["name"]) for t in topics), default=0)
    lines.append(f"topics:    {len(topics)}")
    for t in topics:
        meta = t["topic_metadata"]
        qos = meta.get("offered_qos_profiles") or []
        rel = ",".join(sorted({str(q.get("reliability", "?")) for q in qos if isinstance(q, dict)}))
        lines.append(
            f"  {meta['name']:<{width}} {t['message_count']:>9}  {meta['type']}"
            + (f"  [{rel}]" if rel else "")
        )
    return lines


@dataclass
class _FileContents:
    """Topics, counts and times found in one data file (for :func:`bag_info`)."""

    what: str
    topics: dict[str, str] = field(default_factory=dict)  #: topic -> type
    counts: dict[str, int] = field(default_factory=dict)
    start: int | None = None
    end: int | None = None

    def add(self, topic: str, n: int, lo: int | None, hi: int | None) -> None:
        self.counts[topic] = self.counts.get(topic, 0) + n
        if n and lo is not None and hi is not None:
            self.start = lo if self.start is None else min(self.start, lo)
            self.end = hi if self.end is None else max(self.end, hi)


def _describe_unreadable(path: Path, problem: str) -> list[str]:
    data_files = sorted(p for p in path.iterdir() if p.suffix in {".mcap", ".db3"} and p.is_file())
    has_meta = (path / "metadata.yaml").is_file()
    lines = [f"bag:       {path}"]
    if not data_files and not has_meta:
        empty = "an empty directory" if not any(path.iterdir()) else "a directory"
        lines.append(
            f"status:    not a bag: {empty} without metadata.yaml and without a .mcap or .db3 "
            "data file"
        )
        return lines
    lines.append(f"status:    does not read as it is: {problem}")
    if has_meta:
        try:
            info = _load_metadata(path)
            listed = [path / Path(p).name for p in info["relative_file_paths"]]
            lines += ["metadata.yaml says:"] + ["  " + ln for ln in _metadata_lines(info, listed)]
        except (BagReadError, KeyError, TypeError, ValueError, AttributeError) as exc:
            lines.append(f"metadata.yaml: cannot be used ({exc})")
    else:
        lines.append("metadata.yaml: none")
    found = _FileContents("")
    read = 0
    for f in data_files:
        try:
            got = _mcap_contents(f) if f.suffix == ".mcap" else _sqlite_contents(f)
        except (BagReadError, OSError, sqlite3.Error) as exc:
            lines.append(f"file:      {f.name}: {exc}")
            continue
        read += 1
        lines.append(f"file:      {f.name}, {f.stat().st_size / 2**20:.1f} MiB: {got.what}")
        for topic, msgtype in got.topics.items():
            found.topics.setdefault(topic, msgtype)
            found.add(topic, got.counts.get(topic, 0), got.start, got.end)
    if not read:
        return lines
    total = sum(found.counts.values())
    lines += [
        "the data files hold:" if read == len(data_files) else "the data files read hold:",
        f"  start:     {_utc(found.start) if found.start is not None else '-'}",
        f"  duration:  {((found.end or 0) - (found.start or 0)) * 1e-9:.3f} s",
        f"  messages:  {total}",
        f"  topics:    {len(found.topics)}",
    ]
    width = max((len(t) for t in found.topics), default=0)
    lines += [
        f"    {t:<{width}} {found.counts.get(t, 0):>9}  {msgtype}"
        for t, msgtype in found.topics.items()
    ]
    return lines


def _mcap_contents(f: Path) -> _FileContents:
    """Topics and counts of an MCAP file: from its summary, else by reading it through."""
    out = _FileContents("")
    scan = McapScan(f)  # raises BagReadError when it is not an MCAP file
    with f.open("rb") as fh:
        fh.seek(max(0, scan.size - len(McapScan.MAGIC)))
        ends_with_magic = fh.read() == McapScan.MAGIC and scan.size >= 2 * len(McapScan.MAGIC)
    if ends_with_magic:  # make_reader needs the footer: a file cut short has none
        try:
            with f.open("rb") as fh:
                reader = make_reader(fh)
                header = reader.get_header()
                summary = reader.get_summary()
        except MCAP_READ_ERRORS:
            summary = None
        if summary is not None and summary.statistics is not None:
            stats = summary.statistics
            for cid, ch in summary.channels.items():
                schema = summary.schemas.get(ch.schema_id)
                out.topics.setdefault(ch.topic, schema.name if schema else "(no schema)")
                n = stats.channel_message_counts.get(cid, 0)
                out.add(ch.topic, n, stats.message_start_time, stats.message_end_time)
            out.what = (
                f"MCAP (profile {header.profile!r}, written by {header.library!r}), complete, "
                "with summary"
            )
            return out
    schemas: dict[int, str] = {}
    channels: dict[int, str] = {}
    profile = library = "?"
    for rec in scan.records():
        if isinstance(rec, Message):
            topic = channels.get(rec.channel_id)
            if topic is not None:
                out.add(topic, 1, rec.log_time, rec.log_time)
        elif isinstance(rec, Schema):
            schemas[rec.id] = rec.name
        elif isinstance(rec, Channel):
            channels[rec.id] = rec.topic
            out.topics.setdefault(rec.topic, schemas.get(rec.schema_id, "(no schema)"))
        elif isinstance(rec, Header):
            profile, library = repr(rec.profile), repr(rec.library)
    if scan.complete:
        state = "complete data section, no summary"
    elif scan.dropped:
        state = f"cut short: an incomplete record in its last {scan.dropped} bytes"
    else:
        state = "ends after a complete record, without data end, summary and footer"
    if scan.salvaged:
        state += f" ({scan.salvaged} complete messages in a chunk cut short)"

    notes = "".join(f"; {n}" for n in scan.notes)
    out.what = f"MCAP (profile {profile}, written by {library}), {state}{notes}"
    return out


def _sqlite_contents(f: Path) -> _FileContents:
    """Topics and counts of a rosbag2 SQLite file, read-only (a hot journal is not rolled back)."""
    with f.open("rb") as fh:
        if fh.read(16) != _SQLITE_MAGIC:
            raise BagReadError("not an SQLite database")
    if f.with_name(f.name + "-journal").exists():  # opening it would roll the journal back
        raise BagReadError(
            "SQLite with a rollback journal (an unfinished transaction, which `strapdown-sim "
            "bag repair` rolls back); not opened here"
        )
    out = _FileContents("SQLite")
    con = sqlite3.connect(f"file:{f}?mode=ro", uri=True)
    try:
        rows = con.execute(
            "SELECT name, type, count(messages.id), min(messages.timestamp), "
            "max(messages.timestamp) FROM topics LEFT JOIN messages ON "
            "topics.id == messages.topic_id GROUP BY topics.id ORDER BY topics.id"
        ).fetchall()
    finally:
        con.close()
    for name, msgtype, n, lo, hi in rows:
        out.topics.setdefault(name, msgtype)
        out.add(name, n, lo, hi)
    return out
