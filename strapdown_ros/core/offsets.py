"""Offset history of a variation trajectory on the cycle grid (Savage 2020 eq. (7) inputs).

Built from the scenario's ``variation`` section (body vectors in FRD, metres; angles in
degrees where the key says so). All offsets are functions of time only, so the whole history
can be computed before (or while) the reference streams in. Keys:

* ``lever_arm_m: [x, y, z]`` — constant part of ``l^Bref`` (default 0);
* ``bending`` — added to the lever arm ("fixed plus bending oscillations", Savage 2020 after
  eq. (7)):

  - ``sinusoids: [{amplitude_m: [3], frequency_hz: f, phase_deg: p}, ...]``;
  - ``random: {sigma_m: [3], bandwidth_hz: B, seed: int, components: K (default 64)}`` —
    band-limited random motion: a sum of K sinusoids with frequencies uniform in (0, B] and
    uniform phases, amplitudes ``σ sqrt(2/K)`` per axis, so the standard deviation is σ;
    smooth (C∞), bit-reproducible from the seed;
* ``displacement_m: [3]`` — constant ``s^Bvar`` (default 0);
* ``mounting_rph_deg: [roll, pitch, yaw]`` — fixed mounting rotation ``C_mount``
  (``dcm_from_euler`` convention, Bvar relative to Bref);
* ``scan`` — a scanning platform, ``C_Bvar^Bref = C_mount C_scan(t)``:

  - ``{kind: segments, segments: [{duration_s, rate_dps: [3]}, ...]}``: constant rates about
    Bvar axes, held after the last segment;
  - ``{kind: sweep, axis: [3] (default [0, 0, 1]), amplitude_deg: A, rate_dps: R}``:
    triangular sweep 0 → +A → −A → 0 … at R deg/s;
  - ``{kind: raster, amplitude_deg: A, rate_dps: R, elevation_step_deg: E, rows: n}``: azimuth
    sweeps about z, the elevation (about y) stepping by E at each sweep end, back and forth
    over n rows;
* ``filter`` — Appendix D smoothing of ``C_Bvar^Bref`` (:mod:`strapdown_ros.core.scan_filter`):
  ``{kind: walking_window, window: n (default 21 cycles)}`` (default when a scan is given),
  ``{kind: general, a: [...], b: [...]}`` or ``{kind: none}``; ``lag_compensation: bool``;
* ``method`` (1 | 2) and ``gravity`` (``full`` | ``first_order``) — used by the variation
  generator, accepted here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from strapdown_ros.core.rotations import dcm_from_euler, dcm_from_rotvec, rot_y, rot_z
from strapdown_ros.core.scan_filter import LinearFilter, smooth_attitude_offset

__all__ = ["VARIATION_KEYS", "OffsetHistory", "offset_history", "validate_offsets"]

Array = NDArray[np.float64]

VARIATION_KEYS = (
    "lever_arm_m",
    "bending",
    "displacement_m",
    "mounting_rph_deg",
    "scan",
    "filter",
    "lag_compensation",
    "method",
    "gravity",
)


@dataclass(frozen=True)
class OffsetHistory:
    """Offsets at cycles m = 0..M: ``l^Bref`` (m, FRD), ``s^Bvar`` (m, FRD), ``C_Bvar^Bref``."""

    lever_arm: Array
    displacement: Array
    c_bvar_bref: Array


# -- validation --------------------------------------------------------------------------------


def _mapping(value: Any, key: str, allowed: Sequence[str]) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ValueError(f"{key}: must be a mapping, got {type(value).__name__}")
    for k in value:
        if k not in allowed:
            raise ValueError(f"{key}.{k}: unknown key; expected one of: {', '.join(allowed)}")
    return dict(value)


def _number(d: Mapping[str, Any], name: str, key: str, default: float | None = None,
            positive: bool = False) -> float:  # fmt: skip
    full = f"{key}.{name}"
    if name not in d or d[name] is None:
        if default is None:
            raise ValueError(f"{full}: is required")
        return default
    v = d[name]
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ValueError(f"{full}: must be a finite number, got {v!r}")
    if positive and v <= 0:
        raise ValueError(f"{full}: must be > 0, got {v}")
    return float(v)


def _vector(d: Mapping[str, Any], name: str, key: str, default: Sequence[float] | None = None,
            ) -> Array:  # fmt: skip
    full = f"{key}.{name}"
    if name not in d or d[name] is None:
        if default is None:
            raise ValueError(f"{full}: is required")
        return np.asarray(default, dtype=np.float64)
    v = d[name]
    if (
        not isinstance(v, list | tuple)
        or len(v) != 3
        or any(isinstance(x, bool) or not isinstance(x, int | float) for x in v)
        or not all(math.isfinite(x) for x in v)
    ):
        raise ValueError(f"{full}: must be a list of 3 finite numbers, got {v!r}")
    return np.asarray(v, dtype=np.float64)


def _list(d: Mapping[str, Any], name: str, key: str) -> list[Any]:
    v = d.get(name)
    if v is None:
        return []
    if not isinstance(v, list):
        raise ValueError(f"{key}.{name}: must be a list, got {type(v).__name__}")
    return v


def validate_offsets(cfg: Mapping[str, Any] | None) -> None:
    """Check a ``variation`` section; raises ValueError starting with the dotted key."""
    offset_history(cfg, 0.01, 2)


# -- construction ------------------------------------------------------------------------------


def _bending(cfg: dict[str, Any], t: Array) -> Array:
    key = "variation.bending"
    out = np.zeros((t.size, 3))
    for i, item in enumerate(_list(cfg, "sinusoids", key)):
        k = f"{key}.sinusoids[{i}]"
        s = _mapping(item, k, ("amplitude_m", "frequency_hz", "phase_deg"))
        amp = _vector(s, "amplitude_m", k)
        f = _number(s, "frequency_hz", k, positive=True)
        phase = math.radians(_number(s, "phase_deg", k, 0.0))
        out += np.sin(2.0 * np.pi * f * t + phase)[:, None] * amp
    if cfg.get("random") is not None:
        k = f"{key}.random"
        r = _mapping(cfg["random"], k, ("sigma_m", "bandwidth_hz", "seed", "components"))
        sigma = _vector(r, "sigma_m", k)
        band = _number(r, "bandwidth_hz", k, positive=True)
        seed = r.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ValueError(f"{k}.seed: must be a non-negative integer, got {seed!r}")
        n = r.get("components", 64)
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ValueError(f"{k}.components: must be a positive integer, got {n!r}")
        rng = np.random.default_rng(seed)
        freq = band * (1.0 - rng.random((n, 3)))  # uniform in (0, B]
        phase = 2.0 * np.pi * rng.random((n, 3))
        scale = sigma * math.sqrt(2.0 / n)
        for j in range(n):  # K components, each vectorized over all cycles
            out += scale * np.sin(2.0 * np.pi * freq[j] * t[:, None] + phase[j])
    return out


def _triangle(t: Array, amplitude: float, rate: float) -> Array:
    """0 → +A → −A → 0 … at ``rate`` (same units as A per s)."""
    period = 4.0 * amplitude / rate
    u = np.mod(t / period, 1.0)
    return amplitude * np.where(u < 0.25, 4 * u, np.where(u < 0.75, 2 - 4 * u, 4 * u - 4))


def _scan(cfg: dict[str, Any], t: Array) -> Array | None:
    key = "variation.scan"
    if cfg.get("scan") is None:
        return None
    kind = cfg["scan"].get("kind") if isinstance(cfg["scan"], Mapping) else None
    if kind == "segments":
        s = _mapping(cfg["scan"], key, ("kind", "segments"))
        c = np.tile(np.eye(3), (t.size, 1, 1))
        start, c_start = 0.0, np.eye(3)
        segments = _list(s, "segments", key)
        if not segments:
            raise ValueError(f"{key}.segments: must be a non-empty list")
        for i, item in enumerate(segments):
            k = f"{key}.segments[{i}]"
            seg = _mapping(item, k, ("duration_s", "rate_dps"))
            dur = _number(seg, "duration_s", k, positive=True)
            rate = np.radians(_vector(seg, "rate_dps", k))
            last = i == len(segments) - 1
            sel = (t >= start) & ((t < start + dur) | last)
            tau = np.minimum(t[sel] - start, dur)  # constant rate, held after the last one
            c[sel] = c_start @ dcm_from_rotvec(tau[:, None] * rate)
            c_start = c_start @ dcm_from_rotvec(rate * dur)
            start += dur
        c[t >= start] = c_start
        return c
    if kind == "sweep":
        s = _mapping(cfg["scan"], key, ("kind", "axis", "amplitude_deg", "rate_dps"))
        axis = _vector(s, "axis", key, (0.0, 0.0, 1.0))
        norm = np.linalg.norm(axis)
        if norm == 0:
            raise ValueError(f"{key}.axis: must not be zero")
        amp = math.radians(_number(s, "amplitude_deg", key, positive=True))
        rate = math.radians(_number(s, "rate_dps", key, positive=True))
        return dcm_from_rotvec(_triangle(t, amp, rate)[:, None] * (axis / norm))
    if kind == "raster":
        names = ("kind", "amplitude_deg", "rate_dps", "elevation_step_deg", "rows")
        s = _mapping(cfg["scan"], key, names)
        amp = math.radians(_number(s, "amplitude_deg", key, positive=True))
        rate = math.radians(_number(s, "rate_dps", key, positive=True))
        step = math.radians(_number(s, "elevation_step_deg", key))
        rows = s.get("rows", 5)
        if isinstance(rows, bool) or not isinstance(rows, int) or rows < 1:
            raise ValueError(f"{key}.rows: must be a positive integer, got {rows!r}")
        az = _triangle(t, amp, rate)  # 0 -> +A -> -A -> ... about z
        first_turn, sweep = amp / rate, 2.0 * amp / rate  # turns at |az| = A
        row = np.where(t < first_turn, 0, np.floor((t - first_turn) / sweep).astype(np.int64) + 1)
        bounce = 2 * rows - 2 if rows > 1 else 1  # rows 0..n-1 then back
        r = np.mod(row, bounce)
        el_index = np.where(r < rows, r, bounce - r)
        return rot_z(az) @ rot_y(el_index * step)
    raise ValueError(f"{key}.kind: must be one of segments, sweep, raster; got {kind!r}")


def _filter(cfg: dict[str, Any]) -> LinearFilter | None:
    key = "variation.filter"
    f = cfg.get("filter")
    if f is None:
        return LinearFilter.walking_window(21)
    if not isinstance(f, Mapping):
        raise ValueError(f"{key}: must be a mapping, got {type(f).__name__}")
    kind = f.get("kind", "walking_window")
    if kind == "none":
        _mapping(f, key, ("kind",))
        return None
    if kind == "walking_window":
        s = _mapping(f, key, ("kind", "window"))
        n = s.get("window", 21)
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ValueError(f"{key}.window: must be a positive integer (cycles), got {n!r}")
        return LinearFilter.walking_window(n)
    if kind == "general":
        s = _mapping(f, key, ("kind", "a", "b"))
        try:
            return LinearFilter(_list(s, "a", key), _list(s, "b", key))
        except ValueError as exc:
            raise ValueError(f"{key}: {exc}") from None
    raise ValueError(f"{key}.kind: must be one of walking_window, general, none; got {kind!r}")


def offset_history(cfg: Mapping[str, Any] | None, period_s: float, cycles: int) -> OffsetHistory:
    """Offsets at t_m = m T, m = 0..cycles (Savage 2020 eq. (7) inputs, Appendix D smoothing).

    Raises
    ------
    ValueError
        Naming the dotted key (``variation.…``) of an unknown key or a bad value.
    """
    c = _mapping(cfg, "variation", VARIATION_KEYS)
    t = np.arange(cycles + 1) * period_s
    lever = _vector(c, "lever_arm_m", "variation", (0.0, 0.0, 0.0))
    bending = _mapping(c.get("bending"), "variation.bending", ("sinusoids", "random"))
    lever_arm = lever + _bending(bending, t)
    displacement = np.tile(_vector(c, "displacement_m", "variation", (0.0, 0.0, 0.0)),
                           (t.size, 1))  # fmt: skip
    mount_deg = _vector(c, "mounting_rph_deg", "variation", (0.0, 0.0, 0.0))
    mount = dcm_from_euler(*np.radians(mount_deg))
    lag = c.get("lag_compensation", False)
    if not isinstance(lag, bool):
        raise ValueError(f"variation.lag_compensation: must be true or false, got {lag!r}")
    if c.get("method", 2) not in (1, 2):
        raise ValueError(f"variation.method: must be 1 or 2, got {c.get('method')!r}")
    if c.get("gravity", "full") not in ("full", "first_order"):
        raise ValueError(
            f"variation.gravity: must be full or first_order, got {c.get('gravity')!r}"
        )
    filt = _filter(c)
    scan = _scan(c, t)
    if scan is None:
        c_bvar_bref = np.tile(mount, (t.size, 1, 1))
    else:
        c_bvar_bref = mount @ scan
        if filt is not None:
            try:
                c_bvar_bref = smooth_attitude_offset(c_bvar_bref, filt, lag)
            except ValueError as exc:
                raise ValueError(f"variation.{exc}") from None
    return OffsetHistory(lever_arm, displacement, c_bvar_bref)
