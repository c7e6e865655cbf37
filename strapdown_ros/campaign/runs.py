"""What each run of a campaign is: the scenario with its own seeds and drawn values.

Run k of a campaign is the base scenario (file + ``--set`` + ``--duration``) with

* every ``seed`` key of the scenario (``imu_errors.seed``, ``variation.bending.random.seed``,
  the aiding sensors' seeds …) replaced by a seed drawn for run k, and
* every ``--vary`` key set to a value drawn for run k,

all from ``numpy.random.SeedSequence(campaign_seed, spawn_key=(k, ·))``: a run depends only on
(scenario, campaign seed, k), never on the number of runs, workers or the order they ran in.
Its overrides are plain ``--set`` strings, so ``strapdown-sim generate SCENARIO --set …`` with a
run's overrides computes the very same streams (docs/campaigns.md).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from strapdown_ros.campaign.vary import Vary
from strapdown_ros.config import Scenario, ScenarioError
from strapdown_ros.config.scenario import apply_overrides, parse_scenario, read_document

__all__ = ["Campaign", "RunSpec"]

#: Top-level sections whose variation between runs leaves the reference stream unchanged.
PER_RUN_SECTIONS = ("imu_errors", "navigator", "aiding")


@dataclass(frozen=True)
class RunSpec:
    """Run ``index``: its seeds and drawn values, as ``--set`` overrides."""

    index: int
    seeds: dict[str, int]
    draws: dict[str, Any]
    overrides: tuple[str, ...]


def _seed_keys(node: Any, path: str = "") -> list[str]:
    """Dotted keys of every ``seed`` in a scenario document (sorted)."""
    keys: list[str] = []
    if isinstance(node, dict):
        for k, v in node.items():
            full = f"{path}.{k}" if path else str(k)
            if k == "seed" and not isinstance(v, dict | list):
                keys.append(full)
            else:
                keys += _seed_keys(v, full)
    elif isinstance(node, list):
        for i, v in enumerate(node):
            keys += _seed_keys(v, f"{path}.{i}")
    return sorted(keys)


@dataclass
class Campaign:
    """A campaign: the base scenario, the varied keys and the run specification of each run.

    Parameters
    ----------
    scenario_path : Path
        The scenario file.
    overrides : list of str
        ``--set`` overrides applied to every run.
    duration_s : float, optional
        ``--duration``.
    varies : list of Vary
        ``--vary`` keys.
    seed : int
        The campaign seed (>= 0).
    """

    scenario_path: Path
    overrides: list[str] = field(default_factory=list)
    duration_s: float | None = None
    varies: list[Vary] = field(default_factory=list)
    seed: int = 0

    def __post_init__(self) -> None:
        self.scenario_path = Path(self.scenario_path).resolve()
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ScenarioError("--seed", f"must be an integer >= 0, got {self.seed!r}")
        document = read_document(self.scenario_path)
        self.common = list(self.overrides)
        if self.duration_s is not None:
            self.common.append(f"duration_s={self.duration_s!r}")
        base = apply_overrides(document, self.common)
        scenario = parse_scenario(base, self.scenario_path)
        if not scenario.imu_errors and not self.varies:
            raise ScenarioError(
                "imu_errors",
                "a campaign varies the IMU error realizations: the scenario needs an imu_errors "
                "section (or --vary keys)",
            )
        # The navigator runs on a measured IMU (what a user's filter would get): the one it
        # names if it names one, else the first model's output.
        outputs = [out for _, out in scenario.measured_imu_topics()]
        nav = base.get("navigator") or {}
        if outputs and nav.get("imu_topic") not in outputs:
            measured = outputs[0]
            self.common.append(f"navigator.imu_topic={measured}")
            base = apply_overrides(document, self.common)
        self.base_document = base
        self.base = parse_scenario(base, self.scenario_path)
        if self.base.navigator is None:
            raise ScenarioError("navigator", "a campaign needs a navigator section")
        self.seed_keys = _seed_keys(base)
        for vary in self.varies:  # the key exists and its central value is valid
            self._validate([*self.common, vary.override(vary.center())], f"--vary {vary.text}")

    # -- what is shared ------------------------------------------------------------------------

    @property
    def shared_level(self) -> str:
        """``variation``: reference and variation are shared by all runs; ``reference``: only
        the reference is (the variation has seeds or varied keys); ``none``: nothing is."""
        keys = [v.key for v in self.varies] + self.seed_keys
        sections = {k.split(".", 1)[0] for k in keys}
        if sections <= set(PER_RUN_SECTIONS):
            return "variation"
        if sections <= {*PER_RUN_SECTIONS, "variation"}:
            return "reference"
        return "none"

    # -- what the runs are computed from -------------------------------------------------------

    def inputs_digest(self) -> str:
        """SHA-256 (hex) of everything a run's numbers depend on: the resolved scenario (the
        validated model, defaults filled in, after ``--set`` and ``--duration``), the
        campaign seed, the seeded keys, the ``--vary`` specifications and the content of the
        trajectory's sample file or bag. Two invocations with the same digest compute the
        same run k; a resumed campaign must have its digest (:func:`run_campaign`)."""
        content = {
            "scenario": self.base.model_dump(mode="json"),
            "common": self.common,
            "seed": self.seed,
            "seed_keys": self.seed_keys,
            "vary": [v.text for v in self.varies],
        }
        h = hashlib.sha256(json.dumps(content, sort_keys=True, default=str).encode())
        for path in self._input_files():
            h.update(path.name.encode())
            with open(path, "rb") as f:
                for block in iter(lambda: f.read(1 << 20), b""):
                    h.update(block)
        return h.hexdigest()

    def _input_files(self) -> list[Path]:
        """Files the trajectory is fitted to (``kind: samples``), in a fixed order."""
        spec = self.base.trajectory
        name = getattr(spec, "file", None) or getattr(spec, "bag", None)
        if getattr(spec, "kind", None) != "samples" or not name:
            return []
        path = Path(name)
        if not path.is_absolute():
            path = self.scenario_path.parent / path
        if path.is_dir():
            return sorted(p for p in path.rglob("*") if p.is_file())
        return [path] if path.is_file() else []

    # -- runs ----------------------------------------------------------------------------------

    def run(self, index: int) -> RunSpec:
        """The specification of run ``index`` (deterministic)."""
        if index < 0:
            raise ValueError(f"run index must be >= 0, got {index}")
        seq = np.random.SeedSequence(self.seed, spawn_key=(index, 0))
        states = seq.generate_state(max(len(self.seed_keys), 1), dtype=np.uint32)
        seeds = {k: int(s) for k, s in zip(self.seed_keys, states, strict=False)}
        rng = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(index, 1)))
        draws = {v.key: v.draw(rng) for v in self.varies}
        overrides = [*self.common, *(f"{k}={s}" for k, s in seeds.items())]
        overrides += [v.override(draws[v.key]) for v in self.varies]
        return RunSpec(index, seeds, draws, tuple(overrides))

    def scenario(self, run: RunSpec) -> Scenario:
        """Run ``run``'s validated scenario."""
        return self._validate(list(run.overrides), f"run {run.index}")

    def _validate(self, overrides: list[str], what: str) -> Scenario:
        document = apply_overrides(read_document(self.scenario_path), overrides)
        try:
            return parse_scenario(document, self.scenario_path)
        except ScenarioError as exc:
            raise ScenarioError(exc.key, f"{exc.problem} ({what})") from None
