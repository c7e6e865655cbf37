"""Read a rosbag2 directory (mcap or sqlite3) back into message field containers.

``rosbags.rosbag2.Reader`` supplies the raw payloads; the bulk codec
(:func:`strapdown_ros.bag.cdr.deserialize`) turns each topic's payloads into one field container
(:mod:`strapdown_ros.messages`). Topics of types without a bulk codec are returned raw.

Failures are reported as :class:`BagReadError` with the path and what is wrong: missing
directory, missing ``metadata.yaml``, unsupported storage, missing or truncated data file.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray
from rosbags.rosbag2 import Reader

from strapdown_ros.bag import cdr

__all__ = ["BagContents", "BagReadError", "TopicData", "check_bag", "read_bag"]

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
                raise BagReadError(f"bag {path}, topic {topic}: {exc}") from exc
            if raw:
                data.payloads = payloads[topic]
        else:
            data.payloads = payloads[topic]
        out.topics[topic] = data
    return out
