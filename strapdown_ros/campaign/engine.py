"""Running a campaign's runs on Dask distributed: local cluster or an existing scheduler.

The client process computes the shared streams once, scatters them to every worker
(``broadcast``), submits one task per run that is not finished yet and writes each result as it
arrives (:mod:`strapdown_ros.campaign.results`). A run's result is complete only when its
``summary.json`` exists (written last, atomically), so an interrupted campaign (Ctrl-C, a killed
worker or client) loses nothing finished: the next invocation with the same ``--out`` runs only
the missing runs. A run that raises is reported with its index and error; the others finish.

Nothing listens beyond loopback unless asked: the embedded cluster's scheduler, workers and
dashboard bind 127.0.0.1 (``dashboard`` to expose the dashboard). An existing scheduler is
reached with Dask's TLS security when certificates are given (:func:`tls_security`) or set in
Dask's configuration (``distributed.comm.tls``).
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

__all__ = ["DASHBOARD", "EngineResult", "TlsFiles", "dask_client", "run_tasks", "tls_security"]

#: Default dashboard address of the embedded cluster: loopback, a free port.
DASHBOARD = "127.0.0.1:0"
#: Imported by every worker of the embedded cluster: it ignores the terminal's SIGINT.
WORKER_PRELOAD = "strapdown_ros.campaign.worker_setup"


@dataclass(frozen=True)
class TlsFiles:
    """PEM files of Dask's TLS security: the CA that signed the scheduler's and the workers'
    certificates, and this client's certificate and key (``key`` None: inside ``cert``)."""

    ca: str
    cert: str
    key: str | None = None


def tls_security(tls: TlsFiles | None, scheduler: str) -> Any:
    """The ``distributed.Security`` to reach ``scheduler``: from ``tls`` (encryption
    required), else Dask's configuration (``distributed.comm.tls.*``; None: plain TCP)."""
    from distributed.security import Security

    if tls is None:
        security = Security()
        if scheduler.startswith("tls://") and not security.tls_ca_file:
            raise ValueError(
                f"--scheduler {scheduler}: a tls:// scheduler needs certificates: "
                "--tls-ca-file, --tls-cert (and --tls-key), or distributed.comm.tls.ca-file, "
                "...client.cert, ...client.key in Dask's configuration"
            )
        return security
    if not scheduler.startswith("tls://"):
        raise ValueError(
            f"--scheduler {scheduler}: TLS certificates are given, the address must be tls://"
        )
    for what, path in (("--tls-ca-file", tls.ca), ("--tls-cert", tls.cert), ("--tls-key", tls.key)):
        if path is not None and not os.path.isfile(path):
            raise ValueError(f"{what} {path}: no such file")
    return Security(tls_ca_file=tls.ca, tls_client_cert=tls.cert, tls_client_key=tls.key,
                    require_encryption=True)  # fmt: skip


@dataclass
class EngineResult:
    """What :func:`run_tasks` did."""

    done: list[int] = field(default_factory=list)
    failed: dict[int, str] = field(default_factory=dict)
    workers: int = 0
    dashboard: str | None = None
    elapsed_s: float = 0.0


@contextlib.contextmanager
def dask_client(
    scheduler: str | None,
    workers: int | None,
    *,
    dashboard: str = DASHBOARD,
    tls: TlsFiles | None = None,
) -> Iterator[Any]:
    """A ``distributed.Client``: on ``scheduler`` (``tcp://host:port``, ``tls://`` with
    :func:`tls_security`) or on an embedded ``LocalCluster`` on loopback with ``workers``
    single-threaded worker processes (default: one per core) and its dashboard at
    ``dashboard`` (``host:port``; served only where bokeh is installed).
    """
    import dask
    from distributed import Client, LocalCluster

    # Quiet, deterministic workers: no work stealing of finished keys, no spill to disk. Only
    # critical log lines: a run's error reaches the user through its future (run_tasks), and
    # workers stopped with the cluster (Ctrl-C) would log the lost scheduler as errors.
    settings = {"distributed.worker.daemon": False, "logging.distributed": "critical"}
    if not scheduler:
        preload = list(dask.config.get("distributed.worker.preload", []) or [])
        settings["distributed.worker.preload"] = [*preload, WORKER_PRELOAD]
    with dask.config.set(settings):
        if scheduler:
            client = Client(scheduler, timeout="30s", security=tls_security(tls, scheduler))
            cluster = None
        else:
            n = workers or os.cpu_count() or 1
            cluster = LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                dashboard_address=dashboard,
                silence_logs=50,
            )
            client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
            if cluster is not None:
                cluster.close()


def _dashboard(client: Any) -> str | None:
    try:
        import bokeh  # noqa: F401  (the dashboard needs it)
    except ImportError:
        return None
    return getattr(client, "dashboard_link", None)


class _Progress:
    """A one-line progress bar on stderr when it is a terminal."""

    def __init__(self, total: int) -> None:
        self.total, self.done, self.failed = total, 0, 0
        self.enabled = sys.stderr.isatty()
        self.start = time.monotonic()

    def step(self, ok: bool) -> None:
        self.done += ok
        self.failed += not ok
        if not self.enabled:
            return
        n = self.done + self.failed
        frac = n / self.total if self.total else 1.0
        rate = n / max(time.monotonic() - self.start, 1e-9)
        bar = "#" * int(30 * frac)
        sys.stderr.write(
            f"\rcampaign  [{bar:<30}] {n}/{self.total} runs ({self.failed} failed, "
            f"{rate:.2f} runs/s)" + ("\n" if n == self.total else "")
        )
        sys.stderr.flush()


def run_tasks(
    client: Any,
    indices: list[int],
    task: Callable[..., Any],
    shared: Any,
    args: tuple[Any, ...],
    on_result: Callable[[int, Any], None],
    log: Callable[[str], None] = print,
) -> EngineResult:
    """Run ``task(shared, index, *args)`` for every index on ``client``'s workers.

    ``on_result(index, result)`` is called in this process as each run finishes (in completion
    order). ``shared`` is scattered to every worker once. A run that raises is recorded in
    ``failed`` with its message; a worker that dies has its runs retried by the scheduler.
    """
    from distributed import as_completed

    result = EngineResult()
    start = time.monotonic()
    result.workers = len(client.scheduler_info().get("workers", {}))
    result.dashboard = _dashboard(client)
    if not indices:
        return result
    shared_future = client.scatter(shared, broadcast=True, hash=False)
    futures = {
        client.submit(task, shared_future, k, *args, key=f"run-{k:04d}-{id(args)}", pure=False): k
        for k in indices
    }
    progress = _Progress(len(futures))
    try:
        for future in as_completed(futures):
            k = futures[future]
            try:
                value = future.result()
            except Exception as exc:  # the run's own error, reported with its index
                result.failed[k] = f"{type(exc).__name__}: {exc}"
                progress.step(False)
                log(f"run {k:04d} failed: {result.failed[k]}")
                continue
            on_result(k, value)
            result.done.append(k)
            progress.step(True)
    finally:
        for future in futures:
            future.cancel()
        result.elapsed_s = time.monotonic() - start
    return result
