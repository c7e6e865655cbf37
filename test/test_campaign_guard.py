"""The campaign's resume guard and its cluster's exposure.

A resumed campaign must be computed from the same inputs as the runs it keeps (the digest of
the resolved scenario, overrides, varied keys and seed in ``campaign.json``): an edited
scenario is refused with a message, never mixed into one table. The embedded cluster binds
loopback only, and its workers ignore the terminal's SIGINT (docs/campaigns.md).
"""

from __future__ import annotations

import json
import shutil
import signal
from pathlib import Path

import pytest

from strapdown_ros.campaign import CampaignMismatchError, run_campaign
from strapdown_ros.campaign.results import finished_runs, read_run_errors
from strapdown_ros.campaign.runs import Campaign
from strapdown_ros.campaign.vary import parse_vary
from strapdown_ros.logs import quiet

REPO = Path(__file__).resolve().parents[1]
DEFAULT = REPO / "config" / "scenarios" / "default.yaml"


def _copy(tmp_path: Path, name: str = "scenario.yaml") -> Path:
    path = tmp_path / name
    shutil.copy(DEFAULT, path)
    return path


# -- the digest (no cluster) -------------------------------------------------------------------


def test_digest_follows_what_the_runs_depend_on(tmp_path):
    """Same inputs, same digest (another path, comments changed); any input that changes a
    run's numbers changes it: the file's content, --set, --duration, --vary, the seed."""
    path = _copy(tmp_path)
    base = Campaign(path, [], 3.0).inputs_digest()
    moved = _copy(tmp_path, "moved.yaml")
    moved.write_text("# a comment only\n" + moved.read_text())
    assert Campaign(moved, [], 3.0).inputs_digest() == base
    edited = _copy(tmp_path, "edited.yaml")
    edited.write_text(edited.read_text().replace("preset: tactical", "preset: industrial"))
    assert "industrial" in edited.read_text()
    others = [
        Campaign(edited, [], 3.0),
        Campaign(path, ["imu_errors.0.preset=industrial"], 3.0),
        Campaign(path, [], 4.0),
        Campaign(path, [], 3.0, seed=1),
        Campaign(path, [], 3.0, [parse_vary("imu_errors.0.gyro_arw_dpsh=uniform(0.01, 0.02)")]),
    ]
    digests = [c.inputs_digest() for c in others]
    assert base not in digests and len(set(digests)) == len(digests)


def test_digest_covers_the_sample_file(tmp_path):
    """A ``kind: samples`` trajectory: the CSV's content (beside the scenario) is part of the
    inputs. The scenario model is replaced by one naming the file (the fit is not needed)."""
    from types import SimpleNamespace

    csv = tmp_path / "samples.csv"
    csv.write_text("t,lat\n0,1\n")
    c = Campaign(_copy(tmp_path), [], 3.0)
    c.base = SimpleNamespace(
        trajectory=SimpleNamespace(kind="samples", file="samples.csv"),
        model_dump=lambda mode: {"trajectory": "samples.csv"},
    )
    assert c._input_files() == [csv]
    before = c.inputs_digest()
    csv.write_text("t,lat\n0,2\n")
    assert c.inputs_digest() != before


# -- the guard (an embedded cluster) -----------------------------------------------------------


@pytest.mark.slow
def test_resume_refuses_an_edited_scenario(tmp_path):
    """Why: 2 runs with one IMU preset, the file edited to another, then --runs 3 on the same
    --out: "2 already finished (skipped)" and one table of two scenarios. Now refused, and the
    unedited scenario (even moved, or with a comment added) still resumes."""
    path = _copy(tmp_path)
    out = tmp_path / "campaign"
    first = run_campaign(path, out, 2, duration_s=3.0, workers=1, log=quiet)
    assert first.ran == [0, 1]
    digest = json.loads((out / "campaign.json").read_text())["inputs_sha256"]
    assert len(digest) == 64
    kept = read_run_errors(out, 0)[1].tobytes()
    text = path.read_text()
    path.write_text(text.replace("preset: tactical", "preset: industrial"))
    with pytest.raises(CampaignMismatchError) as refused:
        run_campaign(path, out, 3, duration_s=3.0, workers=1, log=quiet)
    message = str(refused.value)
    assert str(out) in message and "2 finished run(s)" in message, message
    assert f"the content of {path} changed" in message and "another --out" in message, message
    assert finished_runs(out) == {0, 1}  # nothing run, nothing removed
    assert json.loads((out / "campaign.json").read_text())["inputs_sha256"] == digest
    # an override that changes the inputs is named
    path.write_text(text)
    with pytest.raises(CampaignMismatchError, match="common"):
        run_campaign(path, out, 3, overrides=["imu_errors.0.preset=industrial"], duration_s=3.0,
                     workers=1, log=quiet)  # fmt: skip
    # the same inputs from another path resume
    moved = _copy(tmp_path, "moved.yaml")
    moved.write_text("# moved\n" + text)
    again = run_campaign(moved, out, 3, duration_s=3.0, workers=1, log=quiet)
    assert again.skipped == [0, 1] and again.ran == [2]
    assert read_run_errors(out, 0)[1].tobytes() == kept


@pytest.mark.slow
def test_resume_refuses_a_directory_without_a_digest(tmp_path):
    """Finished runs under a ``campaign.json`` written before digests were stored cannot be
    checked: refused with the reason."""
    out = tmp_path / "campaign"
    run_campaign(DEFAULT, out, 1, duration_s=3.0, workers=1, log=quiet)
    info = json.loads((out / "campaign.json").read_text())
    del info["inputs_sha256"]
    (out / "campaign.json").write_text(json.dumps(info))
    with pytest.raises(CampaignMismatchError, match="did not record what its runs"):
        run_campaign(DEFAULT, out, 2, duration_s=3.0, workers=1, log=quiet)


# -- the embedded cluster ----------------------------------------------------------------------


def _listening(server) -> list[str]:
    return [s.getsockname()[0] for s in getattr(server, "_sockets", {}).values()]


@pytest.mark.slow
def test_embedded_cluster_on_loopback_and_workers_ignore_sigint():
    """Why: the dashboard was asked for on every interface (``:0``). Now the scheduler, its
    HTTP server (the dashboard where bokeh is installed) and the workers bind 127.0.0.1, and
    each worker process ignores SIGINT (the terminal's Ctrl-C; the client stops them)."""
    from strapdown_ros.campaign.engine import dask_client

    with dask_client(None, 1) as client:
        scheduler = client.cluster.scheduler
        assert scheduler.address.startswith("tcp://127.0.0.1:"), scheduler.address
        hosts = _listening(scheduler.http_server)
        assert hosts and set(hosts) == {"127.0.0.1"}, hosts
        workers = list(client.scheduler_info()["workers"])
        assert workers and all(w.startswith("tcp://127.0.0.1:") for w in workers), workers
        ignored = client.run(lambda: signal.getsignal(signal.SIGINT) == signal.SIG_IGN)
        assert ignored and all(ignored.values()), ignored
    with dask_client(None, 1, dashboard="0.0.0.0:0") as client:  # noqa: S104 - asked for
        assert set(_listening(client.cluster.scheduler.http_server)) == {"0.0.0.0"}  # noqa: S104
