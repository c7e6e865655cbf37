"""The ``variation`` section: a second IMU at a lever arm / on a scanning platform.

:class:`VariationSpec` holds every key with its default and limits; :meth:`VariationSpec.
offset_model` builds the ROS-free :class:`~strapdown_ros.core.offsets.OffsetModel` from it.
Keys, units and theory: docs/theory/offsets.md, docs/variation.md.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from strapdown_ros.config.base import (
    Finite,
    NonNegative,
    NullIsDefault,
    Positive,
    ScenarioError,
    StrictBool,
    StrictInt,
    Vector3,
    shorten,
)

if TYPE_CHECKING:  # the core models are imported where they are built (scipy.signal)
    from strapdown_ros.core.offsets import OffsetModel, RasterScan, SegmentsScan, SweepScan
    from strapdown_ros.core.scan_filter import LinearFilter

__all__ = [
    "DEFAULT_RANDOM_COMPONENTS",
    "DEFAULT_WINDOW",
    "Bending",
    "GeneralFilter",
    "NoFilter",
    "RandomBendingSpec",
    "RasterScanSpec",
    "ScanSegment",
    "SegmentsScanSpec",
    "Sinusoid",
    "SweepScanSpec",
    "VariationSpec",
    "WalkingWindow",
    "check_variation",
]

#: Default walking-window length (cycles); odd, so lag compensation is a whole-cycle shift.
DEFAULT_WINDOW = 21

#: Default number of sinusoids of the random bending model.
DEFAULT_RANDOM_COMPONENTS = 64


# -- bending -----------------------------------------------------------------------------------


class Sinusoid(NullIsDefault):
    """``A sin(2π f t + p)`` per axis added to the lever arm (m, Hz, deg)."""

    amplitude_m: Vector3
    frequency_hz: Positive
    phase_deg: Finite = 0.0


class RandomBendingSpec(NullIsDefault):
    """Band-limited random bending: ``components`` sinusoids per axis (docs/theory/offsets.md)."""

    sigma_m: Vector3
    bandwidth_hz: Positive
    seed: Annotated[StrictInt, Field(ge=0)] = 0
    components: Annotated[StrictInt, Field(ge=1)] = DEFAULT_RANDOM_COMPONENTS

    @field_validator("sigma_m")
    @classmethod
    def _nonnegative(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        if any(x < 0 for x in value):
            raise ValueError(f"must be >= 0, got {shorten(list(value))}")
        return value


class Bending(NullIsDefault):
    """Time-varying part of the lever arm (m, Bref FRD): sinusoids, then the random ones."""

    sinusoids: list[Sinusoid] = Field(default_factory=list)
    random: RandomBendingSpec | None = None


# -- scan --------------------------------------------------------------------------------------


class ScanSegment(NullIsDefault):
    """Constant rate (deg/s, Bvar axes) for ``duration_s`` > 0 s."""

    duration_s: Positive
    rate_dps: Vector3


class SegmentsScanSpec(NullIsDefault):
    """Constant-rate segments from t = 0, held after the last one."""

    kind: Literal["segments"]
    segments: list[ScanSegment]

    @field_validator("segments")
    @classmethod
    def _nonempty(cls, value: list[ScanSegment]) -> list[ScanSegment]:
        if not value:
            raise ValueError("must be a non-empty list")
        return value

    def max_rate_dps(self) -> float:
        """Largest angular rate (deg/s) of the scan."""
        return max(float(np.linalg.norm(s.rate_dps)) for s in self.segments)


class SweepScanSpec(NullIsDefault):
    """Triangular sweep 0 → +A → −A → +A … about ``axis`` at ``rate_dps`` from ``start_s``."""

    kind: Literal["sweep"]
    axis: Vector3 = (0.0, 0.0, 1.0)
    amplitude_deg: Positive
    rate_dps: Positive
    start_s: NonNegative = 0.0

    @field_validator("axis")
    @classmethod
    def _nonzero(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        if not any(value):
            raise ValueError(f"must not be zero, got {shorten(list(value))}")
        return value

    def max_rate_dps(self) -> float:
        """Largest angular rate (deg/s) of the scan."""
        return self.rate_dps


class RasterScanSpec(NullIsDefault):
    """Azimuth sweeps (about z) with elevation steps (about y) at each end (docs)."""

    kind: Literal["raster"]
    amplitude_deg: Positive
    rate_dps: Positive
    elevation_step_deg: Finite
    rows: Annotated[StrictInt, Field(ge=1)]
    elevation_rate_dps: Positive | None = None  # default: rate_dps
    start_s: NonNegative = 0.0

    def max_rate_dps(self) -> float:
        """Largest angular rate (deg/s) of the scan."""
        el = self.rate_dps if self.elevation_rate_dps is None else self.elevation_rate_dps
        return max(self.rate_dps, el)


ScanSpec = Annotated[SegmentsScanSpec | SweepScanSpec | RasterScanSpec, Field(discriminator="kind")]


# -- filter ------------------------------------------------------------------------------------


class WalkingWindow(NullIsDefault):
    """Walking-window average of ``window`` cycles (Appendix D, eq. (D-8))."""

    kind: Literal["walking_window"]
    window: Annotated[StrictInt, Field(ge=1)] = DEFAULT_WINDOW


class GeneralFilter(NullIsDefault):
    """Eq. (D-4) with ``a_0..`` and ``b_1..``; must satisfy (D-3) and be stable."""

    kind: Literal["general"]
    a: Annotated[list[Finite], Field(min_length=1)]
    b: list[Finite] = Field(default_factory=list)

    @model_validator(mode="after")
    def _exact_and_stable(self) -> GeneralFilter:
        from strapdown_ros.core.scan_filter import LinearFilter

        try:
            LinearFilter(self.a, self.b)
        except ValueError as exc:
            msg = str(exc)
            if msg.startswith(("a: ", "b: ")):
                raise ScenarioError(msg[0], msg[3:]) from None
            raise
        return self


class NoFilter(NullIsDefault):
    """No smoothing of the scan."""

    kind: Literal["none"]


FilterSpec = Annotated[WalkingWindow | GeneralFilter | NoFilter, Field(discriminator="kind")]


# -- the section -------------------------------------------------------------------------------


class VariationSpec(NullIsDefault):
    """The ``variation`` section (all keys optional). Body vectors FRD, metres, degrees.

    ``lever_arm_m`` (Bref axes) plus ``bending`` is ``l^Bref``; ``displacement_m`` (Bvar axes)
    is ``s^Bvar``; ``C_Bvar^Bref = C_mount(mounting_rph_deg) · C_scan(t)`` smoothed by
    ``filter`` (with ``lag_compensation``); ``method`` 1 or 2 and ``gravity`` select the
    solution (docs/variation.md). ``topics`` is accepted and not interpreted.
    """

    lever_arm_m: Vector3 = (0.0, 0.0, 0.0)
    bending: Bending | None = None
    displacement_m: Vector3 = (0.0, 0.0, 0.0)
    mounting_rph_deg: Vector3 = (0.0, 0.0, 0.0)
    scan: ScanSpec | None = None
    filter: FilterSpec = WalkingWindow(kind="walking_window")
    lag_compensation: StrictBool = False
    method: Literal[1, 2] = 2
    gravity: Literal["full", "first_order"] = "full"
    topics: dict[str, Any] | None = None

    @field_validator("filter", mode="before")
    @classmethod
    def _default_kind(cls, value: Any) -> Any:
        if isinstance(value, dict) and "kind" not in value:
            return {"kind": "walking_window", **value}  # the kind defaults to walking_window
        return value

    @field_validator("method", mode="before")
    @classmethod
    def _integer_method(cls, value: Any) -> Any:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"must be 1 or 2, got {shorten(value)}")
        if value not in (1, 2):
            raise ValueError(f"must be 1 or 2, got {shorten(value)}")
        return value

    # -- build the core model ------------------------------------------------------------------

    def offset_model(self) -> OffsetModel:
        """The offsets as functions of time (:class:`~strapdown_ros.core.offsets.OffsetModel`)."""
        from strapdown_ros.core.offsets import OffsetModel, RandomBending, bending_sinusoids

        bending = self.bending or Bending()
        random = None
        if bending.random is not None:
            r = bending.random
            random = RandomBending(
                np.asarray(r.sigma_m, dtype=np.float64), r.bandwidth_hz, r.seed, r.components
            )
        sinusoids = [
            (np.asarray(s.amplitude_m, dtype=np.float64), s.frequency_hz, math.radians(s.phase_deg))
            for s in bending.sinusoids
        ]
        return OffsetModel(
            lever_arm=np.asarray(self.lever_arm_m, dtype=np.float64),
            bending=bending_sinusoids(sinusoids, random),
            displacement=np.asarray(self.displacement_m, dtype=np.float64),
            mounting_rph=np.radians(np.asarray(self.mounting_rph_deg, dtype=np.float64)),
            scan=self._scan(),
            filter=self._filter(),
            lag_compensation=self.lag_compensation,
        )

    def _scan(self) -> SegmentsScan | SweepScan | RasterScan | None:
        from strapdown_ros.core.offsets import RasterScan, SegmentsScan, SweepScan

        s = self.scan
        if s is None:
            return None
        if isinstance(s, SegmentsScanSpec):
            return SegmentsScan(
                np.asarray([g.duration_s for g in s.segments], dtype=np.float64),
                np.asarray(
                    [np.radians(np.asarray(g.rate_dps, dtype=np.float64)) for g in s.segments]
                ),  # fmt: skip
            )
        amplitude, rate = math.radians(s.amplitude_deg), math.radians(s.rate_dps)
        if isinstance(s, SweepScanSpec):
            return SweepScan(np.asarray(s.axis, dtype=np.float64), amplitude, rate, s.start_s)
        # the default elevation rate is the azimuth rate (through degrees, as always computed)
        el_dps = math.degrees(rate) if s.elevation_rate_dps is None else s.elevation_rate_dps
        return RasterScan(
            amplitude,
            rate,
            math.radians(s.elevation_step_deg),
            s.rows,
            math.radians(el_dps),
            s.start_s,
        )

    def _filter(self) -> LinearFilter | None:
        from strapdown_ros.core.scan_filter import LinearFilter

        f = self.filter
        if isinstance(f, NoFilter):
            return None
        if isinstance(f, WalkingWindow):
            return LinearFilter.walking_window(f.window)
        return LinearFilter(f.a, f.b)


def check_variation(spec: VariationSpec | None, rate_hz: float) -> None:
    """Rules of the ``variation`` section that need the scenario's output rate ``rate_hz``.

    The scan may turn less than 180° per output cycle: the increments of the attitude offset
    (eq. (D-2)) and of the variation's attitude are extracted as rotations below π, so a faster
    scan would alias.

    Raises
    ------
    ScenarioError
        Naming the key (``variation.scan.rate_dps: ...``).
    """
    if spec is None or spec.scan is None:
        return
    limit = 180.0 * rate_hz  # deg/s: half a turn per cycle
    rate = spec.scan.max_rate_dps()
    if rate >= limit:
        key = {"segments": "segments", "sweep": "rate_dps", "raster": "rate_dps"}[spec.scan.kind]
        if isinstance(spec.scan, RasterScanSpec) and spec.scan.elevation_rate_dps == rate:
            key = "elevation_rate_dps"
        raise ScenarioError(
            f"variation.scan.{key}",
            f"the scan turns {rate:g} deg/s, at least 180 deg per cycle at rate_hz "
            f"{rate_hz:g} (limit < {limit:g} deg/s)",
        )
