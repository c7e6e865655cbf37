"""The bag metadata (``custom_data``) that says how a plan's streams were made."""

from __future__ import annotations

import json

from strapdown_ros.config.imu_errors import imu_errors_key
from strapdown_ros.plan.model import Plan

__all__ = ["VARIATION_OFFSETS", "bag_custom_data"]

#: Key of a scanning variation's offsets (JSON: ``start_time_ns``, ``period_ns`` and the
#: ``variation`` section as resolved), from which ``report`` rebuilds ``C_Bvar^Bref(t)``.
VARIATION_OFFSETS = "variation.offsets"


def bag_custom_data(plan: Plan) -> dict[str, str]:
    """The bag metadata ``custom_data`` describing how a scenario's streams were made.

    ``generator``, ``scenario`` (name), ``rate_hz``, the gravitation model and, for the sections
    the scenario has, ``variation.method`` / ``variation.gravity``, ``navigator.algorithm`` /
    ``navigator.mode`` / ``navigator.imu_topic`` and ``imu_errors.preset`` /
    ``imu_errors.seed`` (``imu_errors[i].preset`` ... with several models), with a scanning
    platform :data:`VARIATION_OFFSETS`; ``strapdown-sim report`` names the variation method from
    it and removes the scan from the transfer alignment's true mounting. Written
    by ``generate`` and ``bag_recorder``.
    """
    scenario = plan.scenario
    data = {
        "generator": "strapdown_ros",
        "scenario": scenario.name,
        "rate_hz": f"{scenario.rate_hz:g}",
        "gravity_model": str(scenario.gravity_model),
    }
    if scenario.variation is not None:
        spec = scenario.variation
        data["variation.method"], data["variation.gravity"] = str(spec.method), spec.gravity
        if spec.scan is not None:  # the report removes the scan from the truths' relative attitude
            data[VARIATION_OFFSETS] = json.dumps({
                "start_time_ns": scenario.start_time_ns, "period_ns": scenario.period_ns,
                "variation": spec.model_dump(mode="json", exclude_none=True)})  # fmt: skip
    nav = plan.navigator
    if nav is not None:
        data["navigator.algorithm"], data["navigator.mode"] = nav.algorithm, str(nav.mode)
        topics = scenario.recording.topics
        data["navigator.imu_topic"] = nav.imu_topic or topics["variation_imu"]
    models = scenario.imu_errors
    for i, spec in enumerate(models):
        for key in ("preset", "seed"):  # the ones the file gives
            if key in spec.model_fields_set:
                data[f"{imu_errors_key(i, 1 if i == 0 else len(models))}.{key}"] = str(
                    getattr(spec, key))  # fmt: skip
    if scenario.aiding is not None:  # the section as resolved (presets filled in), for the report
        data["aiding"] = scenario.aiding.model_dump_json(exclude_none=True)
    return data
