"""The transfer-alignment campaign gives every run its own seeds, with one IMU error model or a
list of them (a list was left with the file's seeds: every run drew the same IMU errors)."""

from __future__ import annotations

from strapdown_ros.stages.transfer_montecarlo import _seeded

MODEL = {"preset": "tactical", "seed": 1, "input_topic": "/variation/imu",
         "output_topic": "/variation/imu_measured"}  # fmt: skip


def _seeds(overrides: list[str], prefix: str) -> dict[str, int]:
    return {k: int(v) for k, v in (o.split("=") for o in overrides) if k.startswith(prefix)}


def test_one_model_keeps_its_seed_key_and_values_per_run() -> None:
    a, b = _seeded({"imu_errors": MODEL}, 0, 0), _seeded({"imu_errors": MODEL}, 1, 0)
    assert set(_seeds(a, "imu_errors")) == {"imu_errors.seed"}
    assert a != b  # each run its own draws
    assert a == _seeded({"imu_errors": MODEL}, 0, 0)  # reproducible


def test_a_list_gives_each_model_and_each_run_its_own_seed() -> None:
    doc = {"imu_errors": [MODEL, {**MODEL, "seed": 2, "input_topic": "/reference/imu",
                                  "output_topic": "/reference/imu_measured"}]}  # fmt: skip
    runs = [_seeds(_seeded(doc, k, 0), "imu_errors") for k in range(4)]
    assert all(set(r) == {"imu_errors.0.seed", "imu_errors.1.seed"} for r in runs)
    values = [v for r in runs for v in r.values()]
    assert len(set(values)) == len(values)  # 8 different seeds
    assert _seeds(_seeded(doc, 2, 7), "imu_errors") != runs[2]  # the base seed counts
    # the master's and the filter's seeds are the single-model case's
    assert _seeds(_seeded(doc, 3, 0), "transfer") == _seeds(_seeded({"imu_errors": MODEL}, 3, 0),
                                                             "transfer")  # fmt: skip
