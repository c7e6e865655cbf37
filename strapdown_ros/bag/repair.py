"""Repair a rosbag2 directory whose recording was interrupted (``strapdown-sim bag repair``).

A recorder killed without warning (SIGKILL, crash, power loss) leaves its data file without
``metadata.yaml``; an mcap file also lacks its summary section and footer, and may end in a
partial record; an SQLite database may have a hot rollback journal. :func:`repair_bag` keeps
every message that was completely written and rebuilds the rest:

* **mcap**, on the format's own library ``mcap``: the file is read with
  :class:`~strapdown_ros.bag.reader.McapScan` (``mcap``'s ``StreamReader``, up to the last
  complete record; the complete messages of a chunk cut short are salvaged when it is
  uncompressed. Done by hand there, and only because the library does not: locating the record
  the reader stopped at, salvaging that chunk — the library reads a chunk only whole — and
  checking the record lengths inside chunks) and written again with ``mcap.writer.Writer``
  into a temporary sibling, renamed over the original when everything succeeded. The writer
  rebuilds what a killed recording lacks: chunk CRCs, message indexes, the summary section
  (schemas, channels, statistics, chunk/metadata/attachment indexes, summary offsets) and the
  footer. Kept as they were: the Header's profile ``ros2`` (set if the file had another one:
  rosbag2 readers require it) and, in the library field, the original writer's name; every
  schema and channel (with its metadata: the offered QoS profiles rosbag2 stores); every
  message with its payload bytes, log time, publish time and sequence number, in file order;
  metadata and attachment records.
  The ``rosbag2`` metadata record (rosbag2 writes the bag's metadata into it, as YAML under
  ``serialized_metadata``, when it closes a file) is written anew with the repaired bag's
  metadata, its other keys kept. Chunks are written uncompressed.
* **sqlite3**: the database is opened read-write, so SQLite rolls back an unfinished
  transaction from its journal (what the recorder had not committed, i.e. not flushed), checked
  with ``PRAGMA integrity_check``, and the ``metadata`` table row is written.

Then ``metadata.yaml`` (version 9: topics with types, offered QoS profiles and type hashes,
message counts, start time, duration, file list) is written from what the data file holds.
``custom_data`` is kept from the bag's own records of it — an existing ``metadata.yaml``, the
``rosbag2`` metadata record of an mcap file, the ``metadata`` table of an SQLite file — with
``repaired_by`` added. (rosbag2 writers store these records only when they close a bag, so a
recording killed before that has none.)
The result opens with :func:`strapdown_ros.bag.reader.read_bag`, ``rosbags``' readers and
``mcap.reader.make_reader``.
"""

from __future__ import annotations

import os
import sqlite3
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import yaml
from mcap.records import Attachment, Channel, Header, Message, Metadata, Schema
from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, Writer

from strapdown_ros.bag.reader import BagReadError, McapScan, read_bag
from strapdown_ros.bag.writer import TYPESTORE

__all__ = ["BagRepairError", "RepairReport", "repair_bag"]

_VERSION = 9
_NO_MESSAGES_START = 2**63 - 1  # what rosbags writes as the start time of an empty bag
_CHUNK_SIZE = 1 << 20  # bytes of records per chunk, as rosbags writes them
_PROFILE = "ros2"  # the MCAP profile of rosbag2 files
_ROSBAG2 = "rosbag2"  # name of the metadata record in which rosbag2 stores the bag's metadata


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
    custom_data: dict[str, str] = field(default_factory=dict)  #: as written to metadata.yaml
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
    (``repaired=False``) unless ``force``, which rebuilds its data files and metadata anyway.

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
    found = _Found()
    found.merge(_metadata_yaml(path))
    if storage == "mcap":
        _repair_mcap_files(files, found, report)
    else:
        _repair_sqlite_files(files, found, report)
        info = _bag_metadata(storage, files, found)
        for f in found.sqlite_metadata:
            _store_sqlite_metadata(f, info)
    _write_metadata_yaml(path, _bag_metadata(storage, files, found), found, report)
    return report


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
    report = RepairReport(
        path=path,
        storage=storage,
        files=sorted(listed),
        repaired=False,
        custom_data=dict(contents.custom_data),
    )
    for topic, data in contents.topics.items():
        report.topics[topic] = data.msgtype
        report.counts[topic] = len(data)
        if len(data):
            lo, hi = int(data.log_time_ns.min()), int(data.log_time_ns.max())
            report.start_ns = lo if report.start_ns is None else min(report.start_ns, lo)
            report.end_ns = hi if report.end_ns is None else max(report.end_ns, hi)
    return report


# ---------------------------------------------------------------------------------------------
# What a bag's files hold


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
    """What the data files (and a previous metadata.yaml) of a bag hold."""

    topics: dict[str, _Topic] = field(default_factory=dict)
    custom_data: dict[str, str] = field(default_factory=dict)
    ros_distro: str | None = None
    #: SQLite files with a rosbag2 ``metadata`` table (filled in too)
    sqlite_metadata: list[Path] = field(default_factory=list)

    def merge(self, info: dict | None) -> None:
        """Take ``custom_data`` and ``ros_distro`` from a stored rosbag2 metadata mapping; the
        first source merged wins for a key (metadata.yaml, then the data files' records)."""
        if not isinstance(info, dict):
            return
        custom = info.get("custom_data")
        if isinstance(custom, dict):
            for key, value in custom.items():
                self.custom_data.setdefault(str(key), str(value))
        distro = info.get("ros_distro")
        if self.ros_distro is None and isinstance(distro, str) and distro:
            self.ros_distro = distro


def _metadata_yaml(path: Path) -> dict | None:
    """The ``rosbag2_bagfile_information`` of an existing metadata.yaml, if it loads."""
    try:
        doc = yaml.safe_load((path / "metadata.yaml").read_text(encoding="utf-8"))
        return doc["rosbag2_bagfile_information"]
    except (OSError, yaml.YAMLError, TypeError, KeyError):
        return None


def _serialized_metadata(text: str) -> dict | None:
    """The mapping rosbag2 serializes into its 'rosbag2' record / SQLite metadata table."""
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return None
    if isinstance(value, dict) and "rosbag2_bagfile_information" in value:
        value = value["rosbag2_bagfile_information"]
    return value if isinstance(value, dict) else None


def _type_hash(msgtype: str, stored: str = "") -> str:
    if stored:
        return stored
    try:
        return TYPESTORE.hash_rihs01(msgtype)
    except Exception:  # noqa: BLE001 - a type outside the Jazzy store: unknown hash
        return ""


# ---------------------------------------------------------------------------------------------
# MCAP, on the mcap library


@dataclass
class _McapOut:
    """One MCAP file being rewritten: the writer stays open until the bag's metadata is known
    (it goes into the file's 'rosbag2' metadata record)."""

    src: Path
    tmp: Path
    fh: BinaryIO
    writer: Writer
    rosbag2: dict[str, str] = field(default_factory=dict)  #: the original record's entries

    def finish(self, serialized_metadata: str) -> None:
        self.writer.flush()  # the last chunk first: the record follows the data, as rosbag2's
        self.writer.add_metadata(
            _ROSBAG2, {**self.rosbag2, "serialized_metadata": serialized_metadata}
        )
        self.writer.finish()
        self.fh.flush()
        os.fsync(self.fh.fileno())
        self.fh.close()

    def discard(self) -> None:
        self.fh.close()
        self.tmp.unlink(missing_ok=True)


def _repair_mcap_files(files: list[Path], found: _Found, report: RepairReport) -> None:
    outs: list[_McapOut] = []
    try:
        for f in files:
            outs.append(_rewrite_mcap(f, found, report))
        text = yaml.safe_dump(
            _bag_metadata("mcap", files, found), default_flow_style=False, sort_keys=False
        ).strip()
        for out in outs:
            out.finish(text)
        for out in outs:
            os.replace(out.tmp, out.src)
    finally:
        for out in outs:
            out.discard()


def _rewrite_mcap(f: Path, found: _Found, report: RepairReport) -> _McapOut:
    """Copy the complete records of ``f`` into an open ``mcap`` Writer on a temporary file."""
    try:
        scan = McapScan(f)
    except BagReadError as exc:
        raise BagRepairError(str(exc)) from None
    tmp = f.with_name(f".{f.name}.repair-tmp")
    fh = tmp.open("wb")
    out = _McapOut(f, tmp, fh, Writer(fh, chunk_size=_CHUNK_SIZE, compression=CompressionType.NONE))
    try:
        _copy_records(scan, out, found, report)
    except BaseException:
        out.discard()
        raise
    report.dropped_bytes += scan.dropped
    report.salvaged += scan.salvaged
    report.notes += [f"{f.name}: {n}" for n in scan.notes]
    record = _serialized_metadata(out.rosbag2.get("serialized_metadata", ""))
    found.merge(record)
    return out


def _copy_records(scan: McapScan, out: _McapOut, found: _Found, report: RepairReport) -> None:
    writer, name = out.writer, scan.path.name
    schemas: dict[int, tuple[Schema, int]] = {}  # id in the file -> (record, id in the output)
    channels: dict[int, tuple[int, _Topic | None]] = {}  # id in the file -> (output id, topic)
    orphans = 0
    started = False

    def start(library: str) -> None:
        nonlocal started
        tag = f"strapdown-sim bag repair ({LIBRARY_IDENTIFIER})"
        writer.start(_PROFILE, library if tag in library else f"{library}; {tag}".strip("; "))
        started = True

    for rec in scan.records():
        if isinstance(rec, Header):
            if rec.profile != _PROFILE:
                report.notes.append(
                    f"{name}: MCAP profile {rec.profile!r} written as {_PROFILE!r} (rosbag2's)"
                )
            start(rec.library)
            continue
        if not started:  # the file was cut inside its header
            start("")
        if isinstance(rec, Message):
            entry = channels.get(rec.channel_id)
            if entry is None:
                orphans += 1
                continue
            writer.add_message(entry[0], rec.log_time, rec.data, rec.publish_time, rec.sequence)
            if entry[1] is not None:
                entry[1].add(rec.log_time)
        elif isinstance(rec, Schema):
            if rec.id in schemas:  # repeated (e.g. in every chunk): one is enough
                if schemas[rec.id][0] != rec:
                    report.notes.append(f"{name}: schema id {rec.id} redefined; first kept")
                continue
            schemas[rec.id] = (rec, writer.register_schema(rec.name, rec.encoding, rec.data))
        elif isinstance(rec, Channel):
            if rec.id in channels:
                continue
            if rec.schema_id and rec.schema_id not in schemas:
                report.notes.append(
                    f"{name}: channel {rec.topic} refers to the unknown schema id "
                    f"{rec.schema_id}; its messages are dropped"
                )
                continue
            schema = schemas[rec.schema_id] if rec.schema_id else None
            cid = writer.register_channel(
                rec.topic, rec.message_encoding, schema[1] if schema else 0, dict(rec.metadata)
            )
            channels[rec.id] = (cid, _topic(found, rec, schema[0] if schema else None, report))
        elif isinstance(rec, Metadata):
            if rec.name == _ROSBAG2:  # written anew with the repaired metadata
                out.rosbag2 = dict(rec.metadata)
            else:
                writer.add_metadata(rec.name, dict(rec.metadata))
        elif isinstance(rec, Attachment):
            writer.add_attachment(rec.create_time, rec.log_time, rec.name, rec.media_type, rec.data)
    if not started:
        start("")
    if orphans:
        report.notes.append(f"{name}: dropped {orphans} messages of channels never defined")


def _topic(
    found: _Found, ch: Channel, schema: Schema | None, report: RepairReport
) -> _Topic | None:
    """The metadata.yaml topic a channel's messages count for (None: left out, noted)."""
    if schema is None:
        report.notes.append(
            f"channel {ch.topic} has no schema (type unknown): its messages stay in the file "
            "but the topic is left out of metadata.yaml"
        )
        return None
    topic = found.topics.get(ch.topic)
    if topic is None:
        topic = found.topics[ch.topic] = _Topic(
            ch.topic,
            schema.name,
            ch.message_encoding,
            ch.metadata.get("offered_qos_profiles", ""),
            _type_hash(schema.name, ch.metadata.get("topic_type_hash", "")),
        )
    elif topic.msgtype != schema.name:
        report.notes.append(
            f"topic {ch.topic} has channels of types {topic.msgtype} and {schema.name}; "
            f"metadata.yaml lists it as {topic.msgtype}"
        )
    return topic


# ---------------------------------------------------------------------------------------------
# SQLite


def _repair_sqlite_files(files: list[Path], found: _Found, report: RepairReport) -> None:
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
            if has_meta:  # rosbag2 stores the bag's metadata there when it closes the file
                for (text,) in con.execute("SELECT metadata FROM metadata ORDER BY id DESC"):
                    found.merge(_serialized_metadata(text or ""))
            con.commit()
        except sqlite3.Error as exc:
            con.close()
            raise BagRepairError(f"cannot read {f}: {exc}") from exc
        con.close()
        if has_meta:
            found.sqlite_metadata.append(f)


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


# ---------------------------------------------------------------------------------------------
# metadata.yaml


def _bag_metadata(storage: str, files: list[Path], found: _Found) -> dict:
    """The ``rosbag2_bagfile_information`` mapping of the repaired bag."""
    topics = found.topics
    count = sum(t.count for t in topics.values())
    start = min((t.start_ns for t in topics.values() if t.count), default=_NO_MESSAGES_START)
    end = max((t.end_ns for t in topics.values() if t.count), default=0)
    duration = end - start if count else 0
    custom = dict(found.custom_data)
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
                # per-file figures would need counting per file; totals are per bag
                "message_count": count if len(files) == 1 else 0,
            }
            for f in files
        ],
        "custom_data": custom,
        "ros_distro": found.ros_distro or "rosbags",
    }
    return info


def _write_metadata_yaml(path: Path, info: dict, found: _Found, report: RepairReport) -> None:
    text = yaml.safe_dump({"rosbag2_bagfile_information": info}, default_flow_style=False)
    tmp = path / "metadata.yaml.tmp"
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path / "metadata.yaml")
    topics = found.topics
    count = info["message_count"]
    report.topics = {t.name: t.msgtype for t in topics.values()}
    report.counts = {t.name: t.count for t in topics.values()}
    report.start_ns = info["starting_time"]["nanoseconds_since_epoch"] if count else None
    report.end_ns = report.start_ns + info["duration"]["nanoseconds"] if count else None
    report.custom_data = dict(info["custom_data"])
    if set(report.custom_data) == {"repaired_by"}:
        report.notes.append(
            "no custom_data found (rosbag2 writers store it when they close a bag; a recording "
            "killed before that has none)"
        )


def _qos_list(text: str) -> list:
    """rosbag2 stores offered QoS as YAML text in the data file and as a list in the metadata."""
    if not text:
        return []
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return []
    return value if isinstance(value, list) else []
