"""Bulk MCAP chunk writing for the recorder: messages queued per call, chunks built with numpy.

``rosbags``' MCAP writer frames every message in Python as it arrives (a ``BytesIO`` per
record, its chunk's per-channel index lists; ~20 µs a message). :class:`BulkChunks` takes over
the message part of an open ``rosbags`` 0.11 ``McapWriter`` (``storage``): :meth:`append`
only queues ``(channel id, log time, payload)``; :meth:`materialize` frames the queued
messages at once (the 31-byte Message record headers as one numpy structured array, joined
with the payloads in one ``bytes.join``), closes chunks where ``rosbags`` would (the first
message that takes the chunk past 1 MiB) and writes each chunk with its Message Index records
and Chunk Index entry exactly as ``McapWriter.close_chunk`` does. The file is byte-for-byte the
one the per-message writer produces (test/test_bag_recorder.py compares them); schemas,
channels, the summary, the footer and ``metadata.yaml`` stay ``rosbags``'.

MCAP records (https://mcap.dev/spec): Message ``0x05`` = opcode u8, record length u64,
channel id u16, sequence u32, log time u64, publish time u64, data; all little-endian.
"""

from __future__ import annotations

from collections import defaultdict
from io import BytesIO
from typing import Any

import numpy as np

__all__ = ["CHUNK_LIMIT", "BulkChunks"]

#: ``rosbags`` closes a chunk after the message that takes its uncompressed size past this.
CHUNK_LIMIT = 1 << 20

#: An MCAP Message record's header (opcode, length, channel, sequence, log and publish times).
_MESSAGE = np.dtype(
    [("op", "u1"), ("len", "<u8"), ("channel", "<u2"), ("seq", "<u4"), ("log", "<u8"),
     ("pub", "<u8")]
)  # fmt: skip
_HEADER = _MESSAGE.itemsize  # 31
#: Message record length minus the payload: channel, sequence, log time, publish time.
_FIXED = 2 + 4 + 8 + 8


def _u64(x: int) -> bytes:
    return x.to_bytes(8, "little")


def _u32(x: int) -> bytes:
    return x.to_bytes(4, "little")


def _u16(x: int) -> bytes:
    return x.to_bytes(2, "little")


def _string(s: str) -> bytes:
    data = s.encode()
    return _u32(len(data)) + data


def _record(op: int, body: bytes) -> bytes:
    return bytes((op,)) + _u64(len(body)) + body


class BulkChunks:
    """Queues messages of an open ``rosbags`` ``McapWriter`` and writes them chunk by chunk.

    ``writer`` is the ``rosbags`` ``Writer`` (its counts and time range feed
    ``metadata.yaml``), ``writer.storage`` its ``McapWriter``. Call :meth:`materialize`
    before anything else goes into the current chunk (a new connection's records) and before
    the storage closes a chunk or the file.
    """

    def __init__(self, writer: Any) -> None:
        self.writer = writer
        self.storage = writer.storage
        self.channels: list[int] = []
        self.times: list[int] = []
        self.payloads: list[bytes | memoryview] = []
        #: messages already in the current (open) chunk: channel ids, log times, offsets
        self._open: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def __len__(self) -> int:
        return len(self.payloads)

    def append(self, channel: int, log_time: int, payload: bytes | memoryview) -> None:
        """Queue one message (the hot path; :meth:`materialize` frames it)."""
        self.channels.append(channel)
        self.times.append(log_time)
        self.payloads.append(payload)

    # -- framing -------------------------------------------------------------------------------

    def materialize(self) -> None:
        """Frame the queued messages into the storage's chunk, closing full chunks."""
        n = len(self.payloads)
        if not n:
            return
        channels = np.array(self.channels, dtype=np.uint16)
        times = np.array(self.times, dtype=np.uint64)
        payloads = self.payloads[:]
        # cleared in place: :meth:`IncrementalBagWriter.sink` holds their append methods
        self.channels.clear()
        self.times.clear()
        self.payloads.clear()
        sizes = np.fromiter(map(len, payloads), dtype=np.int64, count=n) + _HEADER
        self._account(channels, times)
        start = 0
        while start < n:
            base = self.storage.chunk.bio.tell()
            ends = base + np.cumsum(sizes[start:])
            # rosbags closes after the first message that leaves the chunk above the limit
            over = np.flatnonzero(ends > CHUNK_LIMIT)
            stop = start + int(over[0]) + 1 if over.size else n
            self._frame(channels[start:stop], times[start:stop], payloads[start:stop],
                        sizes[start:stop], base)  # fmt: skip
            if over.size:
                self.close_chunk()
            start = stop

    def _account(self, channels: np.ndarray, times: np.ndarray) -> None:
        """What ``rosbags`` updates per message: counts and time ranges (file and bag)."""
        storage, writer = self.storage, self.writer
        lo, hi = int(times.min()), int(times.max())
        storage.message_start_time = min(lo, storage.message_start_time)
        storage.message_end_time = max(hi, storage.message_end_time)
        writer.min_timestamp = min(lo, writer.min_timestamp)
        writer.max_timestamp = max(hi, writer.max_timestamp)
        ids, counts = np.unique(channels, return_counts=True)
        for cid, count in zip(ids.tolist(), counts.tolist(), strict=True):
            storage.channel_stats[cid] += count
            writer.counts[cid] += count

    def _frame(
        self, channels: np.ndarray, times: np.ndarray, payloads: list, sizes: np.ndarray,
        base: int,
    ) -> None:  # fmt: skip
        chunk = self.storage.chunk
        m = len(payloads)
        head = np.empty(m, dtype=_MESSAGE)
        head["op"] = 0x05
        head["len"] = sizes - (_HEADER - _FIXED)
        head["channel"] = channels
        head["seq"] = 0
        head["log"] = times
        head["pub"] = times
        raw = head.tobytes()
        parts: list[bytes | memoryview] = [b""] * (2 * m)
        parts[0::2] = [raw[k : k + _HEADER] for k in range(0, m * _HEADER, _HEADER)]
        parts[1::2] = payloads
        chunk.bio.write(b"".join(parts))
        offsets = base + np.concatenate(([0], np.cumsum(sizes[:-1])))
        self._open.append((channels, times, offsets.astype(np.uint64)))
        chunk.message_start_time = min(int(times.min()), chunk.message_start_time)
        chunk.message_end_time = max(int(times.max()), chunk.message_end_time)

    # -- chunks --------------------------------------------------------------------------------

    def close_chunk(self) -> None:
        """Write the open chunk, its Message Index records and its Chunk Index entry, as
        ``McapWriter.close_chunk`` does (the per-channel indexes built with numpy)."""
        storage = self.storage
        chunk = storage.chunk
        if self._open:
            channels = np.concatenate([c for c, _, _ in self._open])
            times = np.concatenate([t for _, t, _ in self._open])
            offsets = np.concatenate([o for _, _, o in self._open])
        else:
            channels = np.empty(0, np.uint16)
            times = offsets = np.empty(0, np.uint64)
        self._open = []
        data = chunk.bio.getvalue()
        compressed = storage.compressor(data)
        body = (
            _u64(chunk.message_start_time) + _u64(chunk.message_end_time) + _u64(len(data))
            + _u32(0) + _string(storage.compression) + _u64(len(compressed))
        )  # fmt: skip
        bio = storage.bio
        chunk_start = bio.tell()
        bio.write(b"\x06" + _u64(len(body) + len(compressed)) + body)
        bio.write(compressed)
        chunk_end = bio.tell()
        index: list[tuple[int, int]] = []
        if channels.size:
            # channels in the order of their first message in the chunk (rosbags' dict order)
            ids, first = np.unique(channels, return_index=True)
            records = []
            pos = chunk_end
            for cid in ids[np.argsort(first)].tolist():
                sel = channels == cid
                pairs = np.empty((int(sel.sum()), 2), dtype="<u8")
                pairs[:, 0] = times[sel]
                pairs[:, 1] = offsets[sel]
                rec = _record(0x07, _u16(cid) + _u32(pairs.nbytes) + pairs.tobytes())
                index.append((cid, pos))
                pos += len(rec)
                records.append(rec)
            bio.write(b"".join(records))
        entry = (
            _u64(chunk.message_start_time) + _u64(chunk.message_end_time) + _u64(chunk_start)
            + _u64(chunk_end - chunk_start) + _u32(len(index) * 10)
            + b"".join(_u16(cid) + _u64(off) for cid, off in index)
            + _u64(bio.tell() - chunk_end) + _string(storage.compression)
            + _u64(len(compressed)) + _u64(len(data))
        )  # fmt: skip
        rec = BytesIO()  # rosbags writes its Chunk Index records from each buffer's position
        rec.write(entry)
        storage.chunks.append(rec)
        storage.chunk = type(chunk)(2**63 - 1, 0, BytesIO(), defaultdict(list))

    def flush(self) -> None:
        """Frame what is queued and close the open chunk if it holds messages (a chunk with
        only schema or channel records stays open, as ``rosbags`` keeps it)."""
        self.materialize()
        if self._open:
            self.close_chunk()

    def finish(self) -> None:
        """Frame what is queued and close the open chunk if it holds anything (before the
        storage writes its summary)."""
        self.materialize()
        if self.storage.chunk.bio.tell():
            self.close_chunk()
