"""The producer of ``generate``: computes the next pieces while the caller writes the previous.

On Linux the producer is a forked process (parallelism on the second core; the already-built
trajectory is inherited). A piece's batches hold hundreds of thousands of small ``bytes``
payloads, too many to pickle through the queue's pipe cheaply, so the worker spools each
piece's payloads into one file in a private directory on ``/dev/shm`` (a RAM file system; the
system temporary directory where there is none) and sends only the stamps and the layout; the
writing process reads the file back in one call and splits it into the very same ``bytes``
objects. Elsewhere (no ``fork``), or with ``STRAPDOWN_PRODUCER=thread`` in the environment (what
the mutation runs set, so that the test process sees the code the producer runs), the producer
is a thread and nothing is copied. The forked
worker dies with its parent whatever ends the parent, SIGKILL included (``PR_SET_PDEATHSIG``),
and removes the spool as it goes. Pure standard library and numpy; no ROS. Measurements:
docs/benchmarks.md.
"""

from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import pickle
import queue
import shutil
import signal
import tempfile
import threading
import traceback
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.bag.batches import Batch
from strapdown_ros.bag.cdr import split_rows

__all__ = ["Piece", "Producer"]

_END = "end"


class Piece(NamedTuple):
    """One piece of ``generate``'s output: cycles done, residuals, batches, navigator errors."""

    cycles: int
    residuals: dict[str, object]
    batches: list[Batch]
    nav_errors: dict[str, float]


class _Packed(NamedTuple):
    """A batch's payloads joined into one buffer: ``size`` bytes each (or ``lengths``)."""

    data: bytes
    size: int  # every payload's length, or -1: see lengths
    lengths: NDArray[np.int64] | None


class _SpoolFile(NamedTuple):
    """What crosses the pipe for a piece: the file that holds it."""

    path: Path


def portable(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling with the same type and message (it is re-raised in the
    parent as it is), else a RuntimeError with its type, message and the worker's traceback."""
    try:
        back = pickle.loads(pickle.dumps(exc))  # noqa: S301 - our own object, this process
        if type(back) is type(exc) and str(back) == str(exc):
            return exc
    except Exception:  # noqa: S110 - not picklable: described below
        pass
    tb = "".join(traceback.format_exception(exc))
    return RuntimeError(f"{type(exc).__name__}: {exc} (in the generator worker)\n{tb}")


def _pack(payloads: Sequence[bytes | memoryview]) -> _Packed:
    lengths = np.fromiter(map(len, payloads), dtype=np.int64, count=len(payloads))
    data = b"".join(payloads)
    if lengths.size and bool((lengths == lengths[0]).all()):
        return _Packed(data, int(lengths[0]), None)
    return _Packed(data, -1, lengths)


def _unpack(packed: _Packed) -> list[bytes]:
    if packed.lengths is None:
        return split_rows(np.frombuffer(packed.data, dtype=np.uint8).reshape(-1, packed.size))
    ends = np.cumsum(packed.lengths).tolist()
    starts = [0, *ends[:-1]] if ends else []
    data = packed.data
    return [data[a:z] for a, z in zip(starts, ends, strict=True)]


def _spool_piece(piece: Piece, path: Path) -> _SpoolFile:
    """Write ``piece`` to ``path``, each batch's payloads as one buffer."""
    batches = [b._replace(payloads=_pack(b.payloads)) for b in piece.batches]
    with open(path, "wb") as f:
        pickle.dump(piece._replace(batches=batches), f, protocol=pickle.HIGHEST_PROTOCOL)
    return _SpoolFile(path)


def _unspool_piece(spooled: _SpoolFile) -> Piece:
    """Inverse of :func:`_spool_piece` (the same ``bytes`` payloads); removes the file."""
    with open(spooled.path, "rb") as f:
        piece: Piece = pickle.load(f)  # noqa: S301 - written by our own worker just now
    spooled.path.unlink()
    return piece._replace(batches=[b._replace(payloads=_unpack(b.payloads)) for b in piece.batches])


#: Free space /dev/shm must have to hold the spool (two pieces in flight, ~115 MB each for the
#: default flight); containers often mount a 64 MB /dev/shm, and then the temporary directory
#: (page cache, usually on disk) is used.
SHM_MIN_FREE = 1 << 30


def _spool_root(shm: str = "/dev/shm") -> str | None:  # noqa: S108 - private mkdtemp inside
    """``shm`` if it is a writable directory with :data:`SHM_MIN_FREE` bytes free, else None
    (the system temporary directory)."""
    if not (os.path.isdir(shm) and os.access(shm, os.W_OK | os.X_OK)):
        return None
    st = os.statvfs(shm)
    return shm if st.f_bavail * st.f_frsize >= SHM_MIN_FREE else None


_SPOOL_PREFIX = "strapdown-generate-"


def _remove_stale_spools(root: Path) -> None:
    """Remove spool directories of ``generate`` processes that no longer run (killed with
    SIGKILL, which skips :meth:`Producer.close`): RAM on /dev/shm is not freed otherwise."""
    for d in root.glob(f"{_SPOOL_PREFIX}*-*"):
        pid = d.name[len(_SPOOL_PREFIX) :].split("-", 1)[0]
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            shutil.rmtree(d, ignore_errors=True)
        except PermissionError:  # another user's running process
            continue


class _PipeChannel:
    """A forked worker's channel: items pickled into a pipe synchronously (no feeder thread,
    which the worker's long compiled calls would starve), at most ``depth`` pieces in flight."""

    def __init__(self, ctx: mp.context.BaseContext, depth: int) -> None:
        self.reader, self.writer = ctx.Pipe(duplex=False)
        self.slots = ctx.BoundedSemaphore(depth)

    def put(self, item: object) -> None:
        if isinstance(item, _SpoolFile):
            self.slots.acquire()  # released by the reader once the piece is taken
        self.writer.send(item)

    def get(self, timeout: float) -> object:
        if not self.reader.poll(timeout):
            raise queue.Empty
        item = self.reader.recv()
        if isinstance(item, _SpoolFile):
            self.slots.release()
        return item

    def close(self) -> None:
        self.reader.close()
        self.writer.close()


#: ``prctl`` option: the signal the kernel sends this process when its parent dies.
_PR_SET_PDEATHSIG = 1


def _die_with_parent(parent: int, spool: Path) -> None:
    """In the forked worker: the signals that stop it, and its death with the parent.

    SIGINT and SIGHUP are ignored (Ctrl-C and a closed terminal reach the parent, in the same
    process group, which stops the worker); SIGTERM (from :meth:`Producer.close`, or from the
    kernel when the parent dies: ``PR_SET_PDEATHSIG``, Linux) removes the spool and exits at
    once, without a traceback. A parent that died before the request was made is caught by
    comparing the parent's pid.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)

    def stop(signum: int, frame: object) -> None:
        shutil.rmtree(spool, ignore_errors=True)
        os._exit(128 + signum)

    signal.signal(signal.SIGTERM, stop)
    # SIGTERM was blocked across the fork (Producer.__init__): one sent before this point
    # (close() right after start) is delivered now, to this handler, not to the parent's
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGTERM})
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: close() still stops the worker
        return
    if os.getppid() != parent:  # the parent died between the fork and the request
        stop(signal.SIGTERM, None)


def _produce(items: Iterator[Piece], out: object, spool: Path | None = None,
             parent: int | None = None) -> None:  # fmt: skip
    """Producer body (thread or forked process): put every item, then _END or the exception.

    A forked worker (``spool`` and ``parent`` given) takes its signals first
    (:func:`_die_with_parent`); it must not print a traceback of its own.
    """
    if spool is not None and parent is not None:
        _die_with_parent(parent, spool)
    try:
        k = 0
        for item in items:
            if spool is not None and isinstance(item, Piece):
                item, k = _spool_piece(item, spool / f"piece{k}.bin"), k + 1
            out.put(item)  # type: ignore[attr-defined]
        out.put(_END)  # type: ignore[attr-defined]
    except BaseException as exc:  # re-raised by the consumer
        out.put(portable(exc) if spool is not None else exc)  # type: ignore[attr-defined]


#: Environment variable: ``thread`` makes the producer a thread where it would fork.
THREAD_ENV = "STRAPDOWN_PRODUCER"


class Producer:
    """Iterate over ``items`` computed ahead in a worker; at most ``depth`` pieces wait.

    The worker is a forked process where ``fork`` exists (pieces cross through a spool
    directory, removed by :meth:`close`), else a thread. Items that are not :class:`Piece`
    are passed on as they are. An exception in the worker is raised by the iteration.
    """

    def __init__(self, items: Iterator[Piece], depth: int = 2) -> None:
        self._spool: Path | None = None
        self._queue: _PipeChannel | queue.Queue[object]
        if "fork" in mp.get_all_start_methods() and os.environ.get(THREAD_ENV) != "thread":
            ctx = mp.get_context("fork")
            root = _spool_root()
            _remove_stale_spools(Path(root or tempfile.gettempdir()))
            prefix = f"{_SPOOL_PREFIX}{os.getpid()}-"
            self._spool = Path(tempfile.mkdtemp(prefix=prefix, dir=root))
            self._queue = _PipeChannel(ctx, depth)
            self._worker: threading.Thread | mp.process.BaseProcess = ctx.Process(
                target=_produce, args=(items, self._queue, self._spool, os.getpid()),
                daemon=True,
            )
            # the child starts with the parent's handlers (a CLI's raises Stopped): SIGTERM is
            # held until the worker has its own (_die_with_parent), so no traceback is printed
            held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})
            try:
                self._worker.start()
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, held)
        else:
            self._queue = queue.Queue(maxsize=depth)
            self._worker = threading.Thread(target=_produce, args=(items, self._queue), daemon=True)
            self._worker.start()

    def __iter__(self) -> Iterator[Piece]:
        while True:
            try:
                item = self._queue.get(timeout=1.0)
            except queue.Empty:
                if not self._worker.is_alive():
                    raise RuntimeError("the generator worker died without a result") from None
                continue
            if isinstance(item, str) and item == _END:
                return
            if isinstance(item, BaseException):
                raise item
            if isinstance(item, _SpoolFile):
                item = _unspool_piece(item)
            yield item  # type: ignore[misc]

    def close(self) -> None:
        """Stop the worker (if still running), release the channel, remove the spool."""
        if isinstance(self._worker, threading.Thread):
            return  # a daemon thread; it ends with the iterator or the process
        if self._worker.is_alive():
            self._worker.terminate()
        self._worker.join(timeout=5)
        if self._worker.is_alive():  # inside a long compiled call: its handler waits for it
            self._worker.kill()
            self._worker.join()
        self._queue.close()  # type: ignore[union-attr]
        if self._spool is not None:
            shutil.rmtree(self._spool, ignore_errors=True)
