"""``strapdown-sim campaign``: Monte Carlo realizations of a scenario on Dask distributed.

:func:`run_campaign` plans the runs (:mod:`~strapdown_ros.campaign.runs`), computes what all
runs share once (:mod:`~strapdown_ros.campaign.compute`), runs the missing runs on a Dask
cluster (:mod:`~strapdown_ros.campaign.engine`), and writes the per-run results, the ensemble
tables (:mod:`~strapdown_ros.campaign.results`) and the report
(:mod:`~strapdown_ros.campaign.report`). Usage and examples: docs/campaigns.md.
"""

from __future__ import annotations

import json
import platform
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

from strapdown_ros.campaign.engine import TlsFiles
from strapdown_ros.campaign.runs import Campaign
from strapdown_ros.campaign.vary import parse_vary

__all__ = ["CampaignMismatchError", "CampaignResult", "run_campaign"]


@dataclass
class CampaignResult:
    """What :func:`run_campaign` did."""

    out: Path
    runs: int
    ran: list[int] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)
    failed: dict[int, str] = field(default_factory=dict)
    shared: str = ""
    shared_s: float = 0.0
    elapsed_s: float = 0.0
    workers: int = 0
    dashboard: str | None = None
    report: Path | None = None

    def format(self) -> str:
        """Human-readable summary."""
        lines = [
            f"campaign:  {self.out} ({self.runs} runs)",
            f"workers:   {self.workers}" + (f", dashboard {self.dashboard}" if self.dashboard
                                            else ""),
            f"shared:    {self.shared} (computed once in {self.shared_s:.2f} s)",
            f"ran:       {len(self.ran)} runs in {self.elapsed_s:.2f} s"
            + (f"; {len(self.skipped)} already finished (skipped)" if self.skipped else ""),
        ]  # fmt: skip
        if self.failed:
            lines.append(f"failed:    {len(self.failed)} runs")
            lines += [f"  run {k:04d}: {why}" for k, why in sorted(self.failed.items())]
        if self.report is not None:
            lines.append(f"report:    {self.report}")
        return "\n".join(lines)


def _versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for dist in ("numpy", "scipy", "numba", "dask", "distributed", "pyarrow"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            pass
    return out


class CampaignMismatchError(FileExistsError):
    """The campaign directory holds runs computed from other inputs than this invocation's."""


def _write_info(campaign: Campaign, out: Path, runs: int, vary: list[str]) -> None:
    """Write ``campaign.json``; refuse (:class:`CampaignMismatchError`) when ``out`` already holds
    finished runs computed from other inputs (:meth:`Campaign.inputs_digest`)."""
    from strapdown_ros.campaign.results import finished_runs

    info = {
        "scenario": str(campaign.scenario_path),
        "scenario_name": campaign.base.name,
        "inputs_sha256": campaign.inputs_digest(),
        "runs": runs,
        "seed": campaign.seed,
        "common": campaign.common,
        "seed_keys": campaign.seed_keys,
        "vary": vary,
        "shared": campaign.shared_level,
        "versions": _versions(),
    }
    path = out / "campaign.json"
    done = finished_runs(out)
    if path.exists() and done:
        old = json.loads(path.read_text())
        if old.get("inputs_sha256") != info["inputs_sha256"]:
            raise CampaignMismatchError(_mismatch(out, old, info, len(done)))
    path.write_text(json.dumps(info, indent=1))


def _mismatch(out: Path, old: dict, new: dict, finished: int) -> str:
    """Why ``out`` cannot be resumed with ``new``: what differs from ``old`` (campaign.json)."""
    if "inputs_sha256" not in old:
        why = "it was made by a version that did not record what its runs were computed from"
    else:
        changed = [k for k in ("scenario", "seed", "common", "vary") if old.get(k) != new[k]]
        why = (
            "its runs were computed from other inputs ("
            + (", ".join(f"{k}: {old.get(k)!r} -> {new[k]!r}" for k in changed)
            if changed else f"the content of {new['scenario']} changed since")
            + ")"
        )  # fmt: skip
    return (
        f"{out} holds {finished} finished run(s) that this invocation would mix with its own: "
        f"{why}; results of different scenarios in one table are wrong. Use another --out, or "
        "restore the scenario, --set, --vary and --seed the directory was made with"
    )


def run_campaign(
    scenario: str | Path,
    out: str | Path,
    runs: int,
    *,
    overrides: list[str] | None = None,
    duration_s: float | None = None,
    vary: list[str] | None = None,
    seed: int = 0,
    bags: bool = False,
    scheduler: str | None = None,
    workers: int | None = None,
    dashboard: str | None = None,
    tls: TlsFiles | None = None,
    log=print,
) -> CampaignResult:
    """Run (or complete) a campaign of ``runs`` realizations into ``out``.

    Finished runs in ``out`` (from an interrupted invocation computed from the same inputs: the
    same resolved scenario, overrides, varied keys and seed, :meth:`Campaign.inputs_digest`)
    are kept and not run again; runs computed from other inputs are refused
    (:class:`CampaignMismatchError`), never mixed. ``dashboard``: the embedded cluster's
    dashboard address (default loopback); ``tls``: certificates for a ``tls://`` scheduler
    (default: Dask's configuration).
    """
    from strapdown_ros.campaign.compute import run_one, shared_inputs
    from strapdown_ros.campaign.engine import dask_client, run_tasks
    from strapdown_ros.campaign.report import write_campaign_report
    from strapdown_ros.campaign.results import collect, finished_runs, write_run
    from strapdown_ros.requirements_check import require_extra

    require_extra("campaign")  # dask, distributed, pyarrow: say so before any work
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise ValueError(f"--runs must be an integer >= 1, got {runs!r}")
    varies = [parse_vary(v) for v in vary or []]
    campaign = Campaign(Path(scenario), list(overrides or []), duration_s, varies, seed)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    _write_info(campaign, out, runs, [v.text for v in varies])
    result = CampaignResult(out=out, runs=runs, shared=campaign.shared_level)
    done = finished_runs(out)
    result.skipped = sorted(k for k in done if k < runs)
    missing = [k for k in range(runs) if k not in done]
    start = time.monotonic()
    if missing:
        t = time.perf_counter()
        shared = shared_inputs(campaign)
        result.shared_s = time.perf_counter() - t
        where = {"dashboard": dashboard} if dashboard else {}
        with dask_client(scheduler, workers, tls=tls, **where) as client:

            def store(k: int, value: object) -> None:
                write_run(out, value)  # type: ignore[arg-type]

            engine = run_tasks(
                client, missing, run_one, shared, (campaign, str(out) if bags else None), store, log
            )
        result.ran, result.failed = sorted(engine.done), engine.failed
        result.workers, result.dashboard = engine.workers, engine.dashboard
    result.elapsed_s = time.monotonic() - start
    summaries, _, _ = collect(out, runs)
    result.report = write_campaign_report(out, runs, summaries, result.failed)
    return result
