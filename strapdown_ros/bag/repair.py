"""Repair a rosbag2 directory whose recording was interrupted (``strapdown-sim bag repair``).

A recorder killed without warning (SIGKILL, crash, power loss) leaves its data file without
``metadata.yaml``; an mcap file also lacks its summary section and footer, and may end in a
partial record; an SQLite database may have a hot rollback journal. :func:`repair_bag` keeps
every message that was completely written and rebuilds the rest:

* **mcap**: the file is scanned record by record. Every complete chunk (and its schema and
  channel records) is kept; a chunk cut short keeps its complete message records when it is
  uncompressed (salvaged); anything after the last complete record is dropped. The file is
  rewritten (into a temporary sibling, then renamed over the original) with uncompressed chunks,
  fresh message indexes, a summary section (schemas, channels, chunk indexes, statistics) and
  the footer; message payloads and log times are copied byte for byte.
* **sqlite3**: the database is opened read-write, so SQLite rolls back an unfinished
  transaction from its journal (what the recorder had not committed, i.e. not flushed), checked
  with ``PRAGMA integrity_check``, and the metadata table row is written.

Then ``metadata.yaml`` (version 9: topics with types, offered QoS profiles and type hashes,
message counts, start time, duration, file list) is written from what the data file holds.
The result opens with :func:`strapdown_ros.bag.reader.read_bag` and ``rosbags``' readers.
"""

from __future__ import annotations

import os
import sqlite3
import struct
import zlib
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from strapdown_ros.bag.reader import BagReadError, check_bag, read_bag
from strapdown_ros.bag.writer import TYPESTORE

__all__ = ["BagRepairError", "RepairReport", "bag_info", "repair_bag"]

MAGIC = b"\x89MCAP0\r\n"
_VERSION = 9
_NO_MESSAGES_START = 2**63 - 1  # what rosbags writes as the start time of an empty bag

# MCAP opcodes
_HEADER, _FOOTER, _SCHEMA, _CHANNEL, _MESSAGE, _CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
_MESSAGE_INDEX, _CHUNK_INDEX, _STATISTICS, _METADATA = 0x07, 0x08, 0x0B, 0x0C
_SUMMARY_OFFSET, _DATA_END = 0x0E, 0x0F

_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")


class BagRepairError(RuntimeError):
    """The directory cannot be repaired; the message names the path and the problem."""


@dataclass
class RepairReport:
    """What :func:`repair_bag` found and did."""

    path: Path
    storage: str
    files: list[str]
    topics: dict[str, str] = field(default_factory=dict)  #: topic -> type
    counts: dict[str, int] = field(default_factory=dict)  #: topic -> messages kept
    start_ns: int | None = None
    end_ns: int | None = None
    repaired: bool = True  #: False: the bag was complete and was left as it was
    dropped_bytes: int = 0  #: bytes after the last complete record (mcap)
    salvaged: int = 0  #: messages kept from a chunk cut short (mcap)
    notes: list[str] = field(default_factory=list)

    @property
    def message_count(self) -> int:
        """Messages in the bag after repair."""
        return sum(self.counts.values())

    def format(self) -> str:
        """Human-readable summary (what ``strapdown-sim bag repair`` prints)."""
        verb = "repaired" if self.repaired else "complete, nothing to repair:"
        span = (
            f", {(self.end_ns - self.start_ns) * 1e-9:.3f} s"
            if self.start_ns is not None and self.end_ns is not None
            else ""
        )
        lines = [
            f"{self.path}: {verb} {self.storage} bag, {self.message_count} messages on "
            f"{len(self.topics)} topics{span}"
        ]
        if self.dropped_bytes:
            lines.append(f"  dropped {self.dropped_bytes} bytes of incomplete data at the end")
        if self.salvaged:
            lines.append(f"  salvaged {self.salvaged} messages from a chunk cut short")
        lines += [f"  note: {n}" for n in self.notes]
        width = max((len(t) for t in self.topics), default=0)
        lines += [
            f"  {t:<{width}}  {self.counts.get(t, 0):>9}  {self.topics[t]}" for t in self.topics
        ]
        return "\n".join(lines)


def repair_bag(path: str | os.PathLike[str], *, force: bool = False) -> RepairReport:
    """Make an interrupted recording at ``path`` a complete, readable bag again.

    A bag that :func:`~strapdown_ros.bag.reader.read_bag` opens already is left untouched
    (``repaired=False``) unless ``force``, which rebuilds its metadata anyway.

    Raises
    ------
    BagRepairError
        ``path`` is not a directory, holds no ``.mcap``/``.db3`` file, or the data file is not
        an MCAP/SQLite file.
    """
    path = Path(path)
    if not path.is_dir():
        what = "does not exist" if not path.exists() else "is not a directory"
        raise BagRepairError(f"bag directory {path} {what}")
    files = sorted(p for p in path.iterdir() if p.suffix in {".mcap", ".db3"} and p.is_file())
    if not files:
        raise BagRepairError(f"{path} holds no .mcap or .db3 data file: nothing to repair")
    storages = {p.suffix for p in files}
    if len(storages) > 1:
        raise BagRepairError(f"{path} mixes .mcap and .db3 files: {[p.name for p in files]}")
    storage = "mcap" if ".mcap" in storages else "sqlite3"
    if not force:
        complete = _complete_report(path, storage, files)
        if complete is not None:
            return complete
    report = RepairReport(path=path, storage=storage, files=[p.name for p in files])
    if storage == "mcap":
        found = _repair_mcap_files(files, report)
    else:
        found = _repair_sqlite_files(files, report)
    _write_metadata(path, storage, files, found, report)
    return report


def bag_info(path: str | os.PathLike[str]) -> str:
    """Summary of a bag from its metadata: storage, files, start, duration, topics and counts.

    Raises :class:`~strapdown_ros.bag.reader.BagReadError` when the bag is not readable (an
    interrupted recording: the message says to run ``strapdown-sim bag repair``).
    """
    import datetime as _dt

    info, files = check_bag(path)
    count = int(info.get("message_count", 0))
    start = int(info.get("starting_time", {}).get("nanoseconds_since_epoch", 0))
    duration = int(info.get("duration", {}).get("nanoseconds", 0))
    size = sum(f.stat().st_size for f in files)
    when = "-"
    if count:
        sec, ns = divmod(start, 1_000_000_000)
        stamp = _dt.datetime.fromtimestamp(sec, tz=_dt.UTC).strftime("%Y-%m-%dT%H:%M:%S")
        when = f"{stamp}.{ns:09d}Z"
    lines = [
        f"bag:       {Path(path)}",
        f"storage:   {info['storage_identifier']} (metadata version {info.get('version')}), "
        f"{', '.join(f.name for f in files)}, {size / 2**20:.1f} MiB",
        f"start:     {when}",
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
    return "\n".join(lines)


def _complete_report(path: Path, storage: str, files: list[Path]) -> RepairReport | None:
    """Report of a bag that reads fine as it is (None when it needs repair)."""
    meta = path / "metadata.yaml"
    if not meta.is_file():
        return None
    try:
        contents = read_bag(path)
    except BagReadError:
        return None
    listed = {f.name for f in files}
    info = yaml.safe_load(meta.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
    if {Path(p).name for p in info["relative_file_paths"]} != listed:
        return None  # a data file is not listed in the metadata
    report = RepairReport(path=path, storage=storage, files=sorted(listed), repaired=False)
    for topic, data in contents.topics.items():
        report.topics[topic] = data.msgtype
        report.counts[topic] = len(data)
        if len(data):
            lo, hi = int(data.log_time_ns.min()), int(data.log_time_ns.max())
            report.start_ns = lo if report.start_ns is None else min(report.start_ns, lo)
            report.end_ns = hi if report.end_ns is None else max(report.end_ns, hi)
    return report


# ---------------------------------------------------------------------------------------------
# Topics found in a data file


@dataclass
class _Topic:
    """A topic (connection) as the data file describes it."""

    name: str
    msgtype: str
    serialization_format: str
    offered_qos_profiles: str  #: YAML text, as stored by rosbag2
    type_description_hash: str
    count: int = 0
    start_ns: int = _NO_MESSAGES_START
    end_ns: int = 0

    def add(self, log_time: int) -> None:
        self.count += 1
        self.start_ns = min(self.start_ns, log_time)
        self.end_ns = max(self.end_ns, log_time)


@dataclass
class _Found:
    """What the data files of a bag hold."""

    topics: dict[str, _Topic] = field(default_factory=dict)
    custom_data: dict[str, str] | None = None
    #: SQLite files with a rosbag2 ``metadata`` table (filled in too)
    sqlite_metadata: list[Path] = field(default_factory=list)


def _type_hash(msgtype: str, stored: str = "") -> str:
    if stored:
        return stored
    try:
        return TYPESTORE.hash_rihs01(msgtype)
    except Exception:  # noqa: BLE001 - a type outside the Jazzy store: unknown hash
        return ""


# ---------------------------------------------------------------------------------------------
# MCAP


def _string(buf: bytes | memoryview, pos: int) -> tuple[str, int]:
    (n,) = _U32.unpack_from(buf, pos)
    end = pos + 4 + n
    if end > len(buf):
        raise ValueError("string beyond its record")
    return bytes(buf[pos + 4 : end]).decode("utf-8"), end


def _put_string(text: str) -> bytes:
    data = text.encode("utf-8")
    return _U32.pack(len(data)) + data


def _record(op: int, content: bytes) -> bytes:
    return bytes([op]) + _U64.pack(len(content)) + content


@dataclass
class _Schema:
    id: int
    name: str
    encoding: str
    data: bytes


@dataclass
class _Channel:
    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict[str, str]


def _parse_schema(rec: memoryview) -> _Schema:
    (sid,) = _U16.unpack_from(rec, 0)
    name, pos = _string(rec, 2)
    encoding, pos = _string(rec, pos)
    (n,) = _U32.unpack_from(rec, pos)
    return _Schema(sid, name, encoding, bytes(rec[pos + 4 : pos + 4 + n]))


def _parse_channel(rec: memoryview) -> _Channel:
    cid, sid = struct.unpack_from("<HH", rec, 0)
    topic, pos = _string(rec, 4)
    encoding, pos = _string(rec, pos)
    (n,) = _U32.unpack_from(rec, pos)
    pos += 4
    end = pos + n
    meta: dict[str, str] = {}
    while pos < end:
        key, pos = _string(rec, pos)
        value, pos = _string(rec, pos)
        meta[key] = value
    return _Channel(cid, sid, topic, encoding, meta)


@dataclass
class _Chunk:
    """Uncompressed records of one output chunk and the messages in it."""

    records: bytearray = field(default_factory=bytearray)
    #: (channel id, log time, offset of the record in ``records``)
    messages: list[tuple[int, int, int]] = field(default_factory=list)


class _McapScan:
    """Everything kept from one MCAP file, in file order."""

    def __init__(self) -> None:
        self.header: bytes = _record(_HEADER, _put_string("ros2") + _put_string("strapdown_ros"))
        self.schemas: dict[int, _Schema] = {}
        self.channels: dict[int, _Channel] = {}
        #: ("raw", record bytes) for top-level schema/channel records, ("chunk", _Chunk)
        self.items: list[tuple[str, object]] = []
        self.good_end = len(MAGIC)
        self.salvaged = 0
        self.notes: list[str] = []
        self.custom_data: dict[str, str] | None = None

    def inner(self, records: memoryview, chunk: _Chunk, partial: bool) -> None:
        """Keep the schema/channel/message records of a chunk's (uncompressed) records."""
        pos, size = 0, len(records)
        while pos + 9 <= size:
            op = records[pos]
            (length,) = _U64.unpack_from(records, pos + 1)
            end = pos + 9 + length
            if end > size:
                break
            rec = records[pos + 9 : end]
            if op == _MESSAGE:
                if length < 22:
                    raise ValueError(f"message record of {length} bytes")
                cid, _, log_time = struct.unpack_from("<HIQ", rec, 0)
                chunk.messages.append((cid, log_time, len(chunk.records)))
                chunk.records += records[pos:end]
                self.salvaged += partial
            elif op in (_SCHEMA, _CHANNEL):
                self.top_level(op, rec)
                chunk.records += records[pos:end]
            pos = end

    def top_level(self, op: int, rec: memoryview) -> None:
        if op == _SCHEMA:
            s = _parse_schema(rec)
            self.schemas[s.id] = s
        else:
            c = _parse_channel(rec)
            self.channels[c.id] = c


def _decompress(data: memoryview, compression: str, size: int) -> bytes:
    if compression == "":
        return bytes(data)
    if compression == "zstd":
        try:
            from compression import zstd  # type: ignore[import-not-found]
        except ImportError:
            from backports import zstd  # type: ignore[no-redef]
        return zstd.decompress(bytes(data))
    if compression == "lz4":
        from lz4.frame import decompress  # type: ignore[import-untyped]

        return decompress(bytes(data))
    raise ValueError(f"unsupported chunk compression {compression!r}")


def _scan_mcap(data: memoryview, name: str) -> _McapScan:
    """Parse an MCAP file up to its last complete record (or its data end)."""
    scan = _McapScan()
    if bytes(data[: len(MAGIC)]) != MAGIC:
        raise BagRepairError(f"{name} is not an MCAP file (no MCAP magic at its start)")
    pos, size = len(MAGIC), len(data)
    n_chunk = 0
    while pos + 9 <= size:
        op = data[pos]
        (length,) = _U64.unpack_from(data, pos + 1)
        end = pos + 9 + length
        rec = data[pos + 9 : min(end, size)]
        if end > size:  # cut short: salvage an uncompressed chunk's complete messages
            if op == _CHUNK:
                _salvage_chunk(scan, rec, n_chunk)
            break
        try:
            if op == _HEADER:
                profile, _ = _string(rec, 0)
                if profile != "ros2":
                    scan.notes.append(f"MCAP profile {profile!r} (rosbag2 writes 'ros2')")
                scan.header = bytes(data[pos:end])
            elif op in (_SCHEMA, _CHANNEL):
                scan.top_level(op, rec)
                scan.items.append(("raw", bytes(data[pos:end])))
            elif op == _MESSAGE:
                cid, _, log_time = struct.unpack_from("<HIQ", rec, 0)
                chunk = _Chunk()
                chunk.messages.append((cid, log_time, 0))
                chunk.records += data[pos:end]
                scan.items.append(("chunk", chunk))
            elif op == _CHUNK:
                n_chunk += 1
                _, _, usize, crc = struct.unpack_from("<QQQI", rec, 0)
                compression, p = _string(rec, 28)
                (csize,) = _U64.unpack_from(rec, p)
                if p + 8 + csize > len(rec):
                    raise ValueError("chunk data beyond its record")
                raw = _decompress(rec[p + 8 : p + 8 + csize], compression, usize)
                if len(raw) != usize or (crc and zlib.crc32(raw) != crc):
                    raise ValueError("chunk size or CRC mismatch")
                chunk = _Chunk()
                scan.inner(memoryview(raw), chunk, partial=False)
                scan.items.append(("chunk", chunk))
            elif op == _METADATA:
                scan.custom_data = _rosbag2_custom_data(rec) or scan.custom_data
            elif op in (_DATA_END, _FOOTER):  # a complete file: its summary is rebuilt
                scan.good_end = size
                return scan
            # message indexes, chunk indexes, statistics, attachments: rebuilt or dropped
        except (ValueError, struct.error, UnicodeDecodeError) as exc:
            scan.notes.append(f"skipped a corrupt record (opcode 0x{op:02x}) at byte {pos}: {exc}")
        pos = end
        scan.good_end = pos
    return scan


def _salvage_chunk(scan: _McapScan, rec: memoryview, n_chunk: int) -> None:
    """Keep the complete records of a chunk cut short (uncompressed chunks only)."""
    try:
        compression, p = _string(rec, 28)
    except (ValueError, struct.error, UnicodeDecodeError):
        return
    if compression != "" or p + 8 > len(rec):
        scan.notes.append(f"chunk {n_chunk + 1} is cut short and compressed: its messages are lost")
        return
    chunk = _Chunk()
    scan.inner(rec[p + 8 :], chunk, partial=True)
    if chunk.records:
        scan.items.append(("chunk", chunk))


def _rosbag2_custom_data(rec: memoryview) -> dict[str, str] | None:
    """custom_data of the 'rosbag2' metadata record that rosbags writes when it closes a bag."""
    try:
        name, pos = _string(rec, 0)
        if name != "rosbag2":
            return None
        pos += 4
        key, pos = _string(rec, pos)
        value, _ = _string(rec, pos)
        if key != "serialized_metadata":
            return None
        data = yaml.safe_load(value) or {}
        custom = data.get("custom_data") or None
        return {str(k): str(v) for k, v in custom.items()} if custom else None
    except Exception:  # noqa: BLE001 - optional information
        return None


def _write_mcap(scan: _McapScan, out) -> tuple[dict[int, int], int, int]:
    """Write the kept records as a complete MCAP file; returns counts per channel, start, end."""
    pos = 0

    def put(b: bytes) -> None:
        nonlocal pos
        out.write(b)
        pos += len(b)

    put(MAGIC)
    put(scan.header)
    chunk_indexes: list[bytes] = []
    counts: dict[int, int] = defaultdict(int)
    start, end = _NO_MESSAGES_START, 0
    for kind, item in scan.items:
        if kind == "raw":
            put(item)  # type: ignore[arg-type]
            continue
        chunk: _Chunk = item  # type: ignore[assignment]
        times = [t for _, t, _ in chunk.messages]
        c_start, c_end = (min(times), max(times)) if times else (0, 0)
        records = bytes(chunk.records)
        content = (
            struct.pack("<QQQI", c_start, c_end, len(records), zlib.crc32(records))
            + _put_string("")
            + _U64.pack(len(records))
            + records
        )
        chunk_start = pos
        put(_record(_CHUNK, content))
        chunk_length = pos - chunk_start
        by_channel: dict[int, list[tuple[int, int]]] = defaultdict(list)
        for cid, t, offset in chunk.messages:
            by_channel[cid].append((t, offset))
            counts[cid] += 1
        index_offsets = []
        index_start = pos
        for cid, entries in by_channel.items():
            index_offsets.append((cid, pos))
            body = b"".join(struct.pack("<QQ", t, o) for t, o in entries)
            put(_record(_MESSAGE_INDEX, struct.pack("<HI", cid, len(body)) + body))
        if times:
            start, end = min(start, c_start), max(end, c_end)
        offsets = b"".join(struct.pack("<HQ", cid, o) for cid, o in index_offsets)
        chunk_indexes.append(
            struct.pack("<QQQQ", c_start, c_end, chunk_start, chunk_length)
            + _U32.pack(len(offsets))
            + offsets
            + _U64.pack(pos - index_start)
            + _put_string("")
            + struct.pack("<QQ", len(records), len(records))
        )
    put(_record(_DATA_END, _U32.pack(0)))

    summary_start = pos
    groups: list[tuple[int, int, int]] = []

    def group(op: int, records: list[bytes]) -> None:
        if not records:
            return
        begin = pos
        for r in records:
            put(_record(op, r))
        groups.append((op, begin, pos - begin))

    group(_SCHEMA, [_schema_record(s) for s in scan.schemas.values()])
    group(_CHANNEL, [_channel_record(c) for c in scan.channels.values()])
    group(_CHUNK_INDEX, chunk_indexes)
    stats = b"".join(struct.pack("<HQ", cid, n) for cid, n in sorted(counts.items()))
    total = sum(counts.values())
    group(
        _STATISTICS,
        [
            struct.pack(
                "<QHIIIIQQ",
                total,
                len(scan.schemas),
                len(scan.channels),
                0,
                0,
                len(chunk_indexes),
                start if total else 0,
                end,
            )
            + _U32.pack(len(stats))
            + stats
        ],
    )
    offsets_start = pos
    for op, begin, length in groups:
        put(_record(_SUMMARY_OFFSET, struct.pack("<BQQ", op, begin, length)))
    put(_record(_FOOTER, struct.pack("<QQI", summary_start, offsets_start, 0)))
    put(MAGIC)
    return dict(counts), start, end


def _schema_record(s: _Schema) -> bytes:
    return (
        _U16.pack(s.id) + _put_string(s.name) + _put_string(s.encoding)
        + _U32.pack(len(s.data)) + s.data
    )  # fmt: skip


def _channel_record(c: _Channel) -> bytes:
    meta = b"".join(_put_string(k) + _put_string(v) for k, v in c.metadata.items())
    return (
        struct.pack("<HH", c.id, c.schema_id) + _put_string(c.topic)
        + _put_string(c.message_encoding) + _U32.pack(len(meta)) + meta
    )  # fmt: skip


def _repair_mcap_files(files: list[Path], report: RepairReport) -> _Found:
    found = _Found()
    topics = found.topics
    for f in files:
        data = f.read_bytes()
        scan = _scan_mcap(memoryview(data), f.name)
        report.dropped_bytes += len(data) - scan.good_end if scan.good_end < len(data) else 0
        report.salvaged += scan.salvaged
        report.notes += [f"{f.name}: {n}" for n in scan.notes]
        tmp = f.with_name(f".{f.name}.repair-tmp")
        try:
            with tmp.open("wb") as out:
                counts, _, _ = _write_mcap(scan, out)
                out.flush()
                os.fsync(out.fileno())
            os.replace(tmp, f)
        finally:
            tmp.unlink(missing_ok=True)
        # per-topic counts and times, in channel id order
        times: dict[int, list[int]] = defaultdict(list)
        for kind, item in scan.items:
            if kind == "chunk":
                for cid, t, _ in item.messages:  # type: ignore[attr-defined]
                    times[cid].append(t)
        for cid in sorted(scan.channels):
            ch = scan.channels[cid]
            schema = scan.schemas.get(ch.schema_id)
            if schema is None:
                report.notes.append(f"{f.name}: channel {ch.topic} has no schema; skipped")
                continue
            topic = topics.get(ch.topic)
            if topic is None:
                topic = topics[ch.topic] = _Topic(
                    ch.topic,
                    schema.name,
                    ch.message_encoding,
                    ch.metadata.get("offered_qos_profiles", ""),
                    _type_hash(schema.name, ch.metadata.get("topic_type_hash", "")),
                )
            for t in times.get(cid, []):
                topic.add(t)
        unknown = set(counts) - set(scan.channels)
        if unknown:
            report.notes.append(f"{f.name}: messages of unknown channel ids {sorted(unknown)}")
        found.custom_data = scan.custom_data or found.custom_data
    return found


# ---------------------------------------------------------------------------------------------
# SQLite


def _repair_sqlite_files(files: list[Path], report: RepairReport) -> _Found:
    found = _Found()
    topics = found.topics
    for f in files:
        with f.open("rb") as fh:
            if fh.read(16) != b"SQLite format 3\x00":
                raise BagRepairError(f"{f} is not an SQLite database")
        journal = f.with_name(f.name + "-journal")
        if journal.exists():
            report.notes.append(
                f"{f.name}: rolled back the unfinished transaction in {journal.name}"
            )
        try:
            con = sqlite3.connect(f"file:{f}", uri=True)
        except sqlite3.Error as exc:
            raise BagRepairError(f"cannot open {f}: {exc}") from exc
        try:
            (check,) = con.execute("PRAGMA integrity_check").fetchone()
            if check != "ok":
                raise BagRepairError(f"{f} is corrupt (integrity_check: {check})")
            rows = con.execute(
                "SELECT topics.id, name, type, serialization_format, offered_qos_profiles, "
                "type_description_hash, count(messages.id), min(messages.timestamp), "
                "max(messages.timestamp) FROM topics LEFT JOIN messages ON "
                "topics.id == messages.topic_id GROUP BY topics.id ORDER BY topics.id"
            ).fetchall()
            for _, name, msgtype, fmt, qos, digest, count, lo, hi in rows:
                topic = topics.get(name)
                if topic is None:
                    topic = topics[name] = _Topic(
                        name, msgtype, fmt, qos, _type_hash(msgtype, digest)
                    )
                topic.count += count
                if count:
                    topic.start_ns = min(topic.start_ns, lo)
                    topic.end_ns = max(topic.end_ns, hi)
            has_meta = con.execute(
                "SELECT count(*) FROM sqlite_master WHERE type='table' AND name='metadata'"
            ).fetchone()[0]
            con.commit()
        except sqlite3.Error as exc:
            con.close()
            raise BagRepairError(f"cannot read {f}: {exc}") from exc
        con.close()
        if has_meta:
            found.sqlite_metadata.append(f)
    return found


# ---------------------------------------------------------------------------------------------
# metadata.yaml


def _write_metadata(
    path: Path, storage: str, files: list[Path], found: _Found, report: RepairReport
) -> None:
    topics = found.topics
    count = sum(t.count for t in topics.values())
    start = min((t.start_ns for t in topics.values() if t.count), default=_NO_MESSAGES_START)
    end = max((t.end_ns for t in topics.values() if t.count), default=0)
    duration = end - start if count else 0
    custom = dict(found.custom_data or {"generator": "strapdown_ros"})
    custom["repaired_by"] = "strapdown-sim bag repair"
    info = {
        "version": _VERSION,
        "storage_identifier": storage,
        "relative_file_paths": [f.name for f in files],
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": count,
        "topics_with_message_count": [
            {
                "topic_metadata": {
                    "name": t.name,
                    "type": t.msgtype,
                    "serialization_format": t.serialization_format,
                    "offered_qos_profiles": _qos_list(t.offered_qos_profiles),
                    "type_description_hash": t.type_description_hash,
                },
                "message_count": t.count,
            }
            for t in topics.values()
        ],
        "compression_format": "",
        "compression_mode": "",
        "files": [
            {
                "path": f.name,
                "starting_time": {"nanoseconds_since_epoch": start},
                "duration": {"nanoseconds": duration},
                "message_count": count,
            }
            for f in files
        ],
        "custom_data": custom,
        "ros_distro": "rosbags",
    }
    if len(files) > 1:  # per-file figures would need a scan per file; totals are per bag
        for entry in info["files"]:  # type: ignore[union-attr]
            entry["message_count"] = 0
    for f in found.sqlite_metadata:
        _store_sqlite_metadata(f, info)
    text = yaml.safe_dump({"rosbag2_bagfile_information": info}, default_flow_style=False)
    tmp = path / "metadata.yaml.tmp"
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path / "metadata.yaml")
    report.topics = {t.name: t.msgtype for t in topics.values()}
    report.counts = {t.name: t.count for t in topics.values()}
    report.start_ns = start if count else None
    report.end_ns = end if count else None


def _qos_list(text: str) -> list:
    """rosbag2 stores offered QoS as YAML text in the data file and as a list in the metadata."""
    if not text:
        return []
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return []
    return value if isinstance(value, list) else []


def _store_sqlite_metadata(f: Path, info: dict) -> None:
    con = sqlite3.connect(f"file:{f}", uri=True)
    try:
        text = yaml.safe_dump(info, default_flow_style=False)
        con.execute("DELETE FROM metadata")
        con.execute(
            "INSERT INTO metadata(metadata_version, metadata) VALUES(?, ?)", (_VERSION, text)
        )
        con.commit()
    finally:
        con.close()
