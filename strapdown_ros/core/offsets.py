"""Offset history of a variation trajectory on the cycle grid (inputs of Savage 2020 eq. (5)-(7)).

The variation differs from the reference by an attitude offset ``C_Bvar^Bref`` (eq. (5)), a lever
arm ``l^Bref`` and a displacement ``s^Bvar`` (eq. (7):
``S^E0 = C_Bvar^E0 [(C_Bvar^Bref)ᵀ l^Bref + s^Bvar]``). They are functions of time only, given by
the scenario's ``variation`` section and evaluated here at ``t_m = m T``, m = 0..M, vectorized
over the cycles (loops run only over the few segments, rows or sinusoids). Body vectors are FRD,
lengths in metres, angles in degrees where the key says ``_deg``, rates in deg/s (``_dps``).

Keys of ``variation`` (all optional):

* ``lever_arm_m: [x, y, z]`` — constant part of ``l^Bref`` (m, Bref FRD axes), default 0.
* ``bending`` — time-varying part added to the lever arm (Savage's "fixed plus bending
  oscillations"):

  - ``sinusoids: [{amplitude_m: [3], frequency_hz: f, phase_deg: p}, ...]`` —
    ``Σ A sin(2π f t + p)`` per axis; ``f > 0`` required, ``p`` default 0;
  - ``random: {sigma_m: [3], bandwidth_hz: B, seed: 0, components: 64}`` — band-limited random
    motion, a sum of K = ``components`` sinusoids per axis with independent phases uniform in
    [0, 2π) and frequencies ``(k + u_k) B / K`` (k = 0..K-1, u_k uniform in (0, 1]: one per
    sub-band of width B/K, so each is uniform in (0, B] and the spectrum is flat on average),
    each of amplitude ``σ sqrt(2/K)`` so that the standard deviation is ``σ`` (m, ``>= 0``).
    Smooth (C∞), evaluable at any t, bit-reproducible from ``seed`` (numpy ``default_rng``).

* ``displacement_m: [x, y, z]`` — constant ``s^Bvar`` (m, Bvar FRD axes), default 0.
* ``mounting_rph_deg: [roll, pitch, yaw]`` — fixed mounting rotation ``C_mount`` of Bvar
  relative to Bref when the scan is at zero, ``Rz(yaw) Ry(pitch) Rx(roll)``
  (:func:`~strapdown_ros.core.rotations.dcm_from_euler`), default 0.
* ``scan`` — a scanning platform ``C_scan(t) = C_Bvar^M`` relative to the mount frame M, so
  ``C_Bvar^Bref = C_mount · C_scan`` (scan axes are Bvar axes, equal to M axes at zero scan):

  - ``{kind: segments, segments: [{duration_s: d, rate_dps: [3]}, ...]}`` — constant rates about
    Bvar axes (``Ċ_scan = C_scan (ω×)``) for ``d > 0`` s each, starting at t = 0 from identity;
    after the last segment the scan holds its attitude;
  - ``{kind: sweep, axis: [0, 0, 1], amplitude_deg: A, rate_dps: R, start_s: 0}`` — triangular
    sweep of the angle about ``axis`` (normalized; default z = yaw): 0 → +A → −A → +A … at R
    deg/s, from ``start_s`` (at rest before); ``A, R > 0``;
  - ``{kind: raster, amplitude_deg: A, rate_dps: R, elevation_step_deg: E, rows: n,
    elevation_rate_dps: R, start_s: 0}`` — azimuth ``az`` about z sweeping as above; at each
    end of a sweep the azimuth holds while the elevation ``el`` (about y) moves by one step of
    ``E`` at ``elevation_rate_dps`` (default R); rows 0, E, …, (n-1)E, then back to 0, and so
    on. ``C_scan = Rz(az) Ry(el)`` (azimuth outer gimbal, elevation inner). ``n = 1`` or
    ``E = 0`` is the sweep.

  All scan kinds are closed-form (piecewise constant-rate single-axis rotations) on the grid,
  evaluated with ``C_mount`` in long double and rounded once to float64 (orthonormal to the
  element rounding at any angle).
* ``filter`` — Appendix D smoothing of ``C_Bvar^Bref`` (:mod:`~strapdown_ros.core.scan_filter`),
  applied when a scan is given: ``{kind: walking_window, window: 21}`` (the default, n cycles),
  ``{kind: general, a: [a_0, ...], b: [b_1, ...]}`` (eq. (D-4), must satisfy (D-3)) or
  ``{kind: none}``.
* ``lag_compensation: false`` — advance the filter input by ``round(τ_Flt/T)`` cycles (text after
  eq. (D-8)); exact (no steady lag) for an odd walking window. The scan is evaluated that many
  cycles past the end so the last offsets do not depend on a guess.
* ``method``, ``gravity``, ``topics`` — accepted but not interpreted here (the variation
  generator and nodes read them; :func:`passthrough_settings`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from strapdown_ros.core.scan_filter import LinearFilter, smooth_attitude_offset

__all__ = [
    "DEFAULT_RANDOM_COMPONENTS",
    "DEFAULT_WINDOW",
    "PASSTHROUGH_KEYS",
    "VARIATION_KEYS",
    "OffsetHistory",
    "OffsetModel",
    "offset_history",
    "passthrough_settings",
    "validate_offsets",
]

Array = NDArray[np.float64]
LongArray = NDArray[np.longdouble]

_LD = np.longdouble
_X, _Y, _Z = np.eye(3)

#: Keys this module does not interpret (variation generator / node settings).
PASSTHROUGH_KEYS = ("method", "gravity", "topics")

#: Every key of the ``variation`` section.
VARIATION_KEYS = (
    "lever_arm_m",
    "bending",
    "displacement_m",
    "mounting_rph_deg",
    "scan",
    "filter",
    "lag_compensation",
    *PASSTHROUGH_KEYS,
)

#: Default walking-window length (cycles); odd, so lag compensation is a whole-cycle shift.
DEFAULT_WINDOW = 21

#: Default number of sinusoids of the random bending model.
DEFAULT_RANDOM_COMPONENTS = 64

_SCAN_KEYS = {
    "segments": ("kind", "segments"),
    "sweep": ("kind", "axis", "amplitude_deg", "rate_dps", "start_s"),
    "raster": (
        "kind",
        "amplitude_deg",
        "rate_dps",
        "elevation_step_deg",
        "rows",
        "elevation_rate_dps",
        "start_s",
    ),
}
_FILTER_KEYS = {
    "walking_window": ("kind", "window"),
    "general": ("kind", "a", "b"),
    "none": ("kind",),
}


@dataclass(frozen=True)
class OffsetHistory:
    """Offsets at cycles m = 0..M (Savage 2020 eqs. (5), (7)).

    Attributes
    ----------
    lever_arm : array (M+1, 3)
        ``l^Bref_m`` (m, Bref FRD axes): constant lever arm plus bending.
    displacement : array (M+1, 3)
        ``s^Bvar_m`` (m, Bvar FRD axes).
    c_bvar_bref : array (M+1, 3, 3)
        ``C_{Bvar_m}^{Bref}``: mounting times scan, smoothed by Appendix D.
    """

    lever_arm: Array
    displacement: Array
    c_bvar_bref: Array


# -- validation helpers ------------------------------------------------------------------------


def _mapping(value: Any, key: str, allowed: Sequence[str]) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ValueError(f"{key}: must be a mapping, got {type(value).__name__}")
    for k in value:
        if k not in allowed:
            raise ValueError(f"{key}.{k}: unknown key; expected one of: {', '.join(allowed)}")
    return dict(value)


def _is_number(v: Any) -> bool:
    return not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)


def _number(
    d: Mapping[str, Any],
    name: str,
    key: str,
    default: float | None = None,
    positive: bool = False,
) -> float:
    full = f"{key}.{name}"
    if d.get(name) is None:
        if default is None:
            raise ValueError(f"{full}: is required")
        return default
    v = d[name]
    if not _is_number(v):
        raise ValueError(f"{full}: must be a finite number, got {v!r}")
    if positive and v <= 0:
        raise ValueError(f"{full}: must be > 0, got {v}")
    return float(v)


def _integer(d: Mapping[str, Any], name: str, key: str, default: int | None, minimum: int) -> int:
    full = f"{key}.{name}"
    if d.get(name) is None:
        if default is None:
            raise ValueError(f"{full}: is required")
        return default
    v = d[name]
    if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
        raise ValueError(f"{full}: must be an integer >= {minimum}, got {v!r}")
    return v


def _vector(
    d: Mapping[str, Any],
    name: str,
    key: str,
    default: Sequence[float] | None = None,
    nonnegative: bool = False,
) -> Array:
    full = f"{key}.{name}"
    if d.get(name) is None:
        if default is None:
            raise ValueError(f"{full}: is required")
        return np.asarray(default, dtype=np.float64)
    v = d[name]
    if not isinstance(v, list | tuple) or len(v) != 3 or not all(_is_number(x) for x in v):
        raise ValueError(f"{full}: must be a list of 3 finite numbers, got {v!r}")
    if nonnegative and any(x < 0 for x in v):
        raise ValueError(f"{full}: must be >= 0, got {v!r}")
    return np.asarray(v, dtype=np.float64)


def _list(d: Mapping[str, Any], name: str, key: str, required: bool = False) -> list[Any]:
    v = d.get(name)
    if v is None:
        if required:
            raise ValueError(f"{key}.{name}: is required")
        return []
    if not isinstance(v, list | tuple):
        raise ValueError(f"{key}.{name}: must be a list, got {type(v).__name__}")
    if required and not v:
        raise ValueError(f"{key}.{name}: must be a non-empty list")
    return list(v)


def _kind(d: Any, key: str, kinds: Sequence[str], default: str | None) -> str:
    if not isinstance(d, Mapping):
        raise ValueError(f"{key}: must be a mapping, got {type(d).__name__}")
    kind = d.get("kind", default)
    if kind not in kinds:
        raise ValueError(f"{key}.kind: must be one of {', '.join(kinds)}; got {kind!r}")
    return str(kind)


# -- the model ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Sinusoids:
    """``Σ_j amp_j sin(2π f_j t + φ_j)`` per axis; arrays (K, 3) (m, Hz, rad)."""

    amplitude: Array
    frequency: Array
    phase: Array

    def __call__(self, t: Array) -> Array:
        out = np.zeros((t.size, 3))
        buf = np.empty((t.size, 3))
        tt = t[:, None]
        for amp, f, ph in zip(self.amplitude, self.frequency, self.phase, strict=True):
            # amp sin(2π f t + φ): K terms, each vectorized over the cycles, in place
            np.multiply(tt, 2.0 * np.pi * f, out=buf)
            buf += ph
            np.sin(buf, out=buf)
            buf *= amp
            out += buf
        return out


def _parse_bending(value: Any) -> _Sinusoids:
    key = "variation.bending"
    b = _mapping(value, key, ("sinusoids", "random"))
    amps, freqs, phases = [], [], []
    for i, item in enumerate(_list(b, "sinusoids", key)):
        k = f"{key}.sinusoids[{i}]"
        if item is None:
            raise ValueError(f"{k}: must be a mapping, got None")
        s = _mapping(item, k, ("amplitude_m", "frequency_hz", "phase_deg"))
        amps.append(_vector(s, "amplitude_m", k))
        freqs.append(np.full(3, _number(s, "frequency_hz", k, positive=True)))
        phases.append(np.full(3, math.radians(_number(s, "phase_deg", k, 0.0))))
    if b.get("random") is not None:
        k = f"{key}.random"
        r = _mapping(b["random"], k, ("sigma_m", "bandwidth_hz", "seed", "components"))
        sigma = _vector(r, "sigma_m", k, nonnegative=True)
        band = _number(r, "bandwidth_hz", k, positive=True)
        seed = _integer(r, "seed", k, 0, 0)
        n = _integer(r, "components", k, DEFAULT_RANDOM_COMPONENTS, 1)
        rng = np.random.default_rng(seed)
        u = 1.0 - rng.random((n, 3))  # uniform in (0, 1]
        freqs.extend(band * (np.arange(n)[:, None] + u) / n)
        phases.extend(2.0 * np.pi * rng.random((n, 3)))
        amps.extend(np.tile(sigma * math.sqrt(2.0 / n), (n, 1)))
    shape = (len(amps), 3)
    return _Sinusoids(
        np.reshape(np.asarray(amps, dtype=np.float64), shape),
        np.reshape(np.asarray(freqs, dtype=np.float64), shape),
        np.reshape(np.asarray(phases, dtype=np.float64), shape),
    )


def _triangle(t: Array, amplitude: float, rate: float) -> Array:
    """0 → +A → −A → +A … at ``rate`` (A per s), continuous and piecewise linear."""
    period = 4.0 * amplitude / rate
    u = np.mod(t / period, 1.0)
    return amplitude * np.where(u < 0.25, 4.0 * u, np.where(u < 0.75, 2.0 - 4.0 * u, 4.0 * u - 4.0))


def _axis_rotation(axis: ArrayLike, angle: ArrayLike) -> LongArray:
    """``I + sin θ (u×) + (1 - cos θ) (u×)²`` for the unit vector along ``axis``, in long double.

    The scans are evaluated in extended precision (where numpy's long double has it, e.g. the
    80-bit x87 format) and rounded once to float64, so that the offsets are orthonormal to the
    rounding of their elements at any angle (the float64 Rodrigues form reaches 3e-15 near π).
    """
    theta = np.asarray(angle, dtype=_LD)
    u = np.asarray(axis, dtype=_LD)
    u = u / np.sqrt(np.sum(u * u))
    k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]], dtype=_LD)
    k2 = np.outer(u, u) - np.eye(3, dtype=_LD)
    return (
        np.eye(3, dtype=_LD)
        + np.sin(theta)[..., None, None] * k
        + (1 - np.cos(theta))[..., None, None] * k2
    )


@dataclass(frozen=True)
class _Segments:
    """Constant Bvar-axis rates (rad/s) over durations (s), held after the last one."""

    durations: Array
    rates: Array

    def __call__(self, t: Array) -> LongArray:
        c = np.empty((t.size, 3, 3), dtype=_LD)
        start, c_start = 0.0, np.eye(3, dtype=_LD)
        for i, (dur, rate) in enumerate(zip(self.durations, self.rates, strict=True)):
            last = i == len(self.durations) - 1
            sel = (t >= start) & ((t < start + dur) | last)
            tau = np.minimum(t[sel] - start, dur)  # held at the end of the last segment
            speed = float(np.linalg.norm(rate))
            if speed == 0.0:
                c[sel] = c_start
            else:
                c[sel] = c_start @ _axis_rotation(rate, tau * speed)
                c_start = c_start @ _axis_rotation(rate, dur * speed)
            start += dur
        return c


@dataclass(frozen=True)
class _Sweep:
    axis: Array
    amplitude: float  # rad
    rate: float  # rad/s
    start: float  # s

    def __call__(self, t: Array) -> LongArray:
        angle = _triangle(np.maximum(t - self.start, 0.0), self.amplitude, self.rate)
        return _axis_rotation(self.axis, angle)


@dataclass(frozen=True)
class _Raster:
    amplitude: float  # rad
    rate: float  # rad/s
    step: float  # rad
    rows: int
    elevation_rate: float  # rad/s
    start: float  # s

    def __call__(self, t: Array) -> LongArray:
        s = np.maximum(t - self.start, 0.0)
        if self.rows == 1 or self.step == 0.0:
            return _axis_rotation(_Z, _triangle(s, self.amplitude, self.rate))
        a, r = self.amplitude, self.rate
        step_time = abs(self.step) / self.elevation_rate
        unit = step_time + 2.0 * a / r  # one elevation step, then one full sweep
        u = s - a / r  # time since the end of the first half sweep (0 -> +A)
        j = np.floor(np.maximum(u, 0.0) / unit)  # completed step+sweep units
        w = np.maximum(u, 0.0) - j * unit  # time into unit j
        bounce = 2 * (self.rows - 1)  # rows 0..n-1..1 then again
        ji = j.astype(np.int64)
        row_from = _bounce(ji, self.rows, bounce)
        row_to = _bounce(ji + 1, self.rows, bounce)
        frac = np.minimum(w / step_time, 1.0)
        el = self.step * (row_from + (row_to - row_from) * frac)
        side = np.where(ji % 2 == 0, a, -a)  # azimuth at the start of unit j
        az_unit = side - np.sign(side) * r * np.maximum(w - step_time, 0.0)
        az = np.where(u < 0.0, r * s, az_unit)
        el = np.where(u < 0.0, 0.0, el)
        return _axis_rotation(_Z, az) @ _axis_rotation(_Y, el)


def _bounce(i: NDArray[np.int64], rows: int, period: int) -> NDArray[np.float64]:
    r = np.mod(i, period)
    return np.where(r < rows, r, period - r).astype(np.float64)


def _parse_scan(value: Any) -> _Segments | _Sweep | _Raster | None:
    key = "variation.scan"
    if value is None:
        return None
    kind = _kind(value, key, tuple(_SCAN_KEYS), None)
    s = _mapping(value, key, _SCAN_KEYS[kind])
    if kind == "segments":
        durations, rates = [], []
        for i, item in enumerate(_list(s, "segments", key, required=True)):
            k = f"{key}.segments[{i}]"
            if item is None:
                raise ValueError(f"{k}: must be a mapping, got None")
            seg = _mapping(item, k, ("duration_s", "rate_dps"))
            durations.append(_number(seg, "duration_s", k, positive=True))
            rates.append(np.radians(_vector(seg, "rate_dps", k)))
        return _Segments(np.asarray(durations), np.asarray(rates))
    amplitude = math.radians(_number(s, "amplitude_deg", key, positive=True))
    rate = math.radians(_number(s, "rate_dps", key, positive=True))
    start = _number(s, "start_s", key, 0.0)
    if start < 0:
        raise ValueError(f"{key}.start_s: must be >= 0, got {start}")
    if kind == "sweep":
        axis = _vector(s, "axis", key, (0.0, 0.0, 1.0))
        norm = float(np.linalg.norm(axis))
        if norm == 0.0:
            raise ValueError(f"{key}.axis: must not be zero, got {s['axis']!r}")
        return _Sweep(axis / norm, amplitude, rate, start)
    step = math.radians(_number(s, "elevation_step_deg", key))
    rows = _integer(s, "rows", key, None, 1)
    el_rate = math.radians(_number(s, "elevation_rate_dps", key, math.degrees(rate), True))
    return _Raster(amplitude, rate, step, rows, el_rate, start)


def _parse_filter(value: Any) -> LinearFilter | None:
    key = "variation.filter"
    if value is None:
        return LinearFilter.walking_window(DEFAULT_WINDOW)
    kind = _kind(value, key, tuple(_FILTER_KEYS), "walking_window")
    f = _mapping(value, key, _FILTER_KEYS[kind])
    if kind == "none":
        return None
    if kind == "walking_window":
        return LinearFilter.walking_window(_integer(f, "window", key, DEFAULT_WINDOW, 1))
    a = _list(f, "a", key, required=True)
    b = _list(f, "b", key)
    for name, coeffs in (("a", a), ("b", b)):
        for i, x in enumerate(coeffs):
            if not _is_number(x):
                raise ValueError(f"{key}.{name}[{i}]: must be a finite number, got {x!r}")
    try:
        return LinearFilter(a, b)
    except ValueError as exc:
        msg = str(exc)
        if msg.startswith(("a:", "b:")):
            raise ValueError(f"{key}.{msg}") from None
        raise ValueError(f"{key}: {msg}") from None


@dataclass(frozen=True)
class OffsetModel:
    """A parsed, validated ``variation`` section: the offsets as functions of time.

    Attributes
    ----------
    lever_arm : array (3,)
        Constant lever arm (m, Bref FRD).
    bending : callable
        ``t (N,) s -> (N, 3) m``: bending added to the lever arm.
    displacement : array (3,)
        Constant ``s^Bvar`` (m, Bvar FRD).
    mounting_rph : array (3,)
        Mounting roll, pitch, yaw (rad): ``C_mount = Rz(yaw) Ry(pitch) Rx(roll)``.
    scan : callable or None
        ``t (N,) s -> (N, 3, 3)``: ``C_scan`` (unfiltered), None without a scan.
    filter : LinearFilter or None
        Appendix D smoothing filter (None: ``kind: none``).
    lag_compensation : bool
        Advance the filter input by ``round(τ_Flt/T)`` cycles.
    passthrough : dict
        ``method``, ``gravity``, ``topics`` as given (not interpreted).
    """

    lever_arm: Array
    bending: _Sinusoids
    displacement: Array
    mounting_rph: Array
    scan: _Segments | _Sweep | _Raster | None
    filter: LinearFilter | None
    lag_compensation: bool
    passthrough: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any] | None) -> OffsetModel:
        """Parse and validate a ``variation`` section.

        Raises
        ------
        ValueError
            The message starts with the dotted key (``variation.…: problem``).
        """
        c = _mapping(cfg, "variation", VARIATION_KEYS)
        lag = c.get("lag_compensation", False)
        if not isinstance(lag, bool):
            raise ValueError(f"variation.lag_compensation: must be true or false, got {lag!r}")
        mount_deg = _vector(c, "mounting_rph_deg", "variation", (0.0, 0.0, 0.0))
        return cls(
            lever_arm=_vector(c, "lever_arm_m", "variation", (0.0, 0.0, 0.0)),
            bending=_parse_bending(c.get("bending")),
            displacement=_vector(c, "displacement_m", "variation", (0.0, 0.0, 0.0)),
            mounting_rph=np.radians(mount_deg),
            scan=_parse_scan(c.get("scan")),
            filter=_parse_filter(c.get("filter")),
            lag_compensation=lag,
            passthrough=passthrough_settings(c),
        )

    @property
    def mount(self) -> Array:
        """``C_mount`` (Bvar relative to Bref at zero scan), ``dcm_from_euler`` convention."""
        return self._mount_ld().astype(np.float64)

    def _mount_ld(self) -> LongArray:
        roll, pitch, yaw = self.mounting_rph
        return _axis_rotation(_Z, yaw) @ _axis_rotation(_Y, pitch) @ _axis_rotation(_X, roll)

    def lever_arm_at(self, t: ArrayLike) -> Array:
        """``l^Bref(t)`` (m, Bref FRD) at times ``t`` (s, shape (N,)): constant plus bending."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        return self.lever_arm + self.bending(t)

    def history(self, period_s: float, cycles: int) -> OffsetHistory:
        """Offsets at ``t_m = m T``, m = 0..``cycles``.

        Parameters
        ----------
        period_s : float
            Cycle period T (s), > 0.
        cycles : int
            Last cycle M (>= 0).

        Returns
        -------
        OffsetHistory
            Bit-reproducible; the history for M is a prefix of the history for any M' > M.
        """
        if not (math.isfinite(period_s) and period_s > 0):
            raise ValueError(f"period_s: must be > 0, got {period_s!r}")
        if isinstance(cycles, bool) or not isinstance(cycles, int | np.integer) or cycles < 0:
            raise ValueError(f"cycles: must be an integer >= 0, got {cycles!r}")
        n = int(cycles) + 1
        t = np.arange(n) * period_s
        lever_arm = self.lever_arm_at(t)
        displacement = np.tile(self.displacement, (n, 1))
        if self.scan is None:
            return OffsetHistory(lever_arm, displacement, np.tile(self.mount, (n, 1, 1)))
        ahead = 0
        if self.filter is not None and self.lag_compensation:
            ahead = max(self.filter.compensation_shift(), 0)  # the shifted filter looks ahead
        t_ext = np.arange(n + ahead) * period_s
        c = (self._mount_ld() @ self.scan(t_ext)).astype(np.float64)  # rounded once
        if self.filter is not None:
            c = smooth_attitude_offset(c, self.filter, self.lag_compensation)
        return OffsetHistory(lever_arm, displacement, c[:n])


def passthrough_settings(cfg: Mapping[str, Any] | None) -> dict[str, Any]:
    """The ``method``, ``gravity`` and ``topics`` entries of a ``variation`` section, untouched."""
    if not isinstance(cfg, Mapping):
        return {}
    return {k: cfg[k] for k in PASSTHROUGH_KEYS if k in cfg}


def validate_offsets(cfg: Mapping[str, Any] | None) -> None:
    """Check a ``variation`` section without evaluating it.

    Raises
    ------
    ValueError
        Starting with the dotted key, e.g.
        ``variation.bending.random.bandwidth_hz: must be > 0, got -1``; unknown keys list the
        valid ones.
    """
    OffsetModel.from_config(cfg)


def offset_history(cfg: Mapping[str, Any] | None, period_s: float, cycles: int) -> OffsetHistory:
    """Offsets of a ``variation`` section at ``t_m = m T``, m = 0..``cycles``.

    Parameters
    ----------
    cfg : mapping or None
        The scenario's ``variation`` section (keys in the module docstring); None: no offsets.
    period_s : float
        Cycle period T (s).
    cycles : int
        Last cycle M.

    Returns
    -------
    OffsetHistory
        ``l^Bref_m``, ``s^Bvar_m``, ``C_{Bvar_m}^{Bref}`` for Savage 2020 eqs. (5), (7).

    Raises
    ------
    ValueError
        Naming the dotted key (``variation.…``) of an unknown key or a bad value.
    """
    return OffsetModel.from_config(cfg).history(period_s, cycles)
