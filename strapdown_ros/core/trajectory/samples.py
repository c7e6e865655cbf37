"""Trajectory kind ``samples``: a continuous truth fitted to coarse samples (Giribet 2007).

Coarse samples of a motion (a flight log, a planned path, odometry from a bag) become a
:class:`~strapdown_ros.core.trajectory.base.Trajectory` with the B-spline problems of Giribet,
España & Miranda 2007 (``seeds/003``, implemented in
:mod:`strapdown_ros.core.trajectory.giribet`):

* **Position** — Problem PV (eqs. (15)–(17)) in ECEF: the position spline is fitted to the
  position samples with the velocity (and acceleration) samples as derivative data; velocity
  relative to the Earth is the derivative of that one spline, so position and velocity are
  consistent. (The paper fits in an inertial frame; ECEF is used because the truth is
  Earth-referenced and E → E0 is an exact rotation, :func:`~.base.local_to_e0`.)
* **Attitude** — ``q_B^E0`` (body FRD to the inertial frame E0 of docs/interface.md §1, the paper's
  ``q_b^i``), either

  - ``fit``: Problem 1 on the attitude samples with ``½ q̃ ⊗ [0, ω̃]`` as derivative data
    when rate samples are given, or
  - ``integrate``: Problem ω (eqs. (18)–(20)) on the rate samples, Problem q1 (eq. (21))
    from the first attitude, Problem q2 (eqs. (22)–(23)),

  and in both cases ``q = q̄/‖q̄‖`` with ``ω_ib^B = vec(2 q* ⊗ q̇)``, a pair that satisfies
  eq. (21) exactly.
* **No attitude samples** — the attitude is derived from the fitted velocity: heading along
  the horizontal velocity, pitch along the flight path (``atan2(−v_D, |v_H|)``), roll 0;
  heading (pitch) is held at its last defined value while the horizontal (total) speed is
  below 0.1 m/s (before the first defined value: the first one; never defined: 0). Those
  attitudes, evaluated at the sample times, are then fitted like samples (``fit``).

Time: ``t`` of :meth:`SamplesTrajectory.local_truth` is seconds since the first sample
(``t0`` of the stream); knot times in the options are also seconds since the first sample.

Units are SI with angles in rad. Reading samples from files (CSV, a bag's Odometry topic) is
:mod:`strapdown_ros.inputs.samples`; the scenario keys are
``config.trajectory.SamplesTrajectorySpec``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import BSpline

from strapdown_ros.core._compiled import matmul33
from strapdown_ros.core.array_types import F64
from strapdown_ros.core.earth import (
    OMEGA_IE,
    dcm_e0_to_ecef,
    dcm_ecef_to_e0,
    dcm_ecef_to_ned,
    dcm_ned_to_ecef,
    ecef_state_to_e0,
    ecef_to_geodetic,
    geodetic_to_ecef,
    ned_velocity_from_ecef,
)
from strapdown_ros.core.rotations import dcm_from_quat, quat_from_dcm, rot_x, rot_y, rot_z
from strapdown_ros.core.threads import MIN_ROWS, WORKERS
from strapdown_ros.core.trajectory.base import LocalTruth, TrajectoryError, TruthE0
from strapdown_ros.core.trajectory.giribet import (
    QuaternionSpline,
    breakpoint_continuity,
    fit_quaternion,
    problem_omega,
    problem_pv,
    problem_q1,
    problem_q2,
)

__all__ = [
    "FitOptions",
    "Samples",
    "SamplesTrajectory",
    "SplineOptions",
    "Weights",
    "check_times",
    "samples_from_arrays",
]


#: Speed (m/s) below which the derived heading / pitch are held (no defined direction).
DERIVED_ATTITUDE_MIN_SPEED = 0.1

# --------------------------------------------------------------------------------------------
# Options
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SplineOptions:
    """Spline space of one fitted function (Giribet 2007 Theorem 1 / Problem 1 inputs).

    Attributes
    ----------
    degree : int
        Polynomial degree ``p`` (paper order ``k = p + 1``). Default 3 (the paper's k = 4).
    knots : float, sequence of float, or None
        Breakpoint spacing (s; the span is divided into ``floor(duration/spacing)`` equal
        intervals, so the actual spacing is at least this), or an explicit list of
        breakpoints (s since the first sample, strictly increasing, inside
        ``[0, duration]``; 0 and ``duration`` are added if missing). None: spacing of
        ``2 (p + 1)`` median sample intervals.
    continuity : int, sequence of int, or None
        ``C^c`` order at the interior breakpoints: one int for all, or one per interior
        breakpoint (before ``breaks`` are applied). None: ``p − 1`` (simple knots). Position
        needs ``c >= 1`` (continuous velocity); attitude ``c >= 0`` (``c = 1`` gives a corner
        in ω, ``c = 0`` a jump in ω).
    breaks : sequence of (float, int)
        Extra breakpoints ``(t_s, continuity)`` (e.g. a de-spin start, paper §5): inserted,
        or, if within 1 µs of an existing breakpoint, that breakpoint's continuity is set.
    """

    degree: int = 3
    knots: float | Sequence[float] | None = None
    continuity: int | Sequence[int] | None = None
    breaks: Sequence[tuple[float, int]] = ()


@dataclass(frozen=True)
class Weights:
    """Least-squares weights ``w = 1/σ²`` per data type (eqs. (15), (18); 0 ignores the data).

    Each is a float or an array (N,) of per-sample weights. Only ratios within one problem
    matter (position vs velocity vs acceleration; attitude vs rate).

    Attributes
    ----------
    position : float or array
        1/m² (default 1: σ = 1 m).
    velocity : float or array
        s²/m² (default 100: σ = 0.1 m/s).
    acceleration : float or array
        s⁴/m² (default 0).
    attitude : float or array
        1/rad² of the attitude angle error (default 1e4: σ = 0.01 rad).
    rate : float or array
        s²/rad² (default 1e4: σ = 0.01 rad/s).
    """

    position: float | ArrayLike = 1.0
    velocity: float | ArrayLike = 100.0
    acceleration: float | ArrayLike = 0.0
    attitude: float | ArrayLike = 1.0e4
    rate: float | ArrayLike = 1.0e4


@dataclass(frozen=True)
class FitOptions:
    """How :class:`SamplesTrajectory` fits the samples.

    Attributes
    ----------
    position, attitude : SplineOptions
        Spline spaces of the ECEF position and of the attitude quaternion ``q_B^E0``.
    weights : Weights
    attitude_method : {"auto", "fit", "integrate"}
        ``fit``: Problem 1 on attitude samples (rates as derivative data). ``integrate``:
        Problems ω, q1, q2 from the rate samples and the first attitude (sample or derived);
        the rate spline has degree ``p − 1`` and continuity ``c − 1`` of the attitude
        options. ``auto``: ``fit`` when attitude samples exist or no rates exist, else
        ``integrate``.
    q_step : float or None
        Problem q1 output spacing (s). None: ``min(min breakpoint interval / 8,
        0.05 / max|ω̂|)``.
    q2_degree : int
        Degree of the Problem q2 interpolant (odd, default 5).
    """

    position: SplineOptions = field(default_factory=SplineOptions)
    attitude: SplineOptions = field(default_factory=SplineOptions)
    weights: Weights = field(default_factory=Weights)
    attitude_method: str = "auto"
    q_step: float | None = None
    q2_degree: int = 5


# --------------------------------------------------------------------------------------------
# Samples in canonical form
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Samples:
    """Coarse samples in canonical frames (what the fit consumes).

    Attributes
    ----------
    t : array (N,)
        Sample times (s, any origin), strictly increasing.
    r_ecef : array (N, 3)
        ECEF position (m).
    v_ecef : array (N, 3) or None
        Velocity relative to the Earth in ECEF axes (m/s).
    a_ecef : array (N, 3) or None
        ``d²r^E/dt²`` in ECEF axes (m/s²).
    c_b_e : array (N, 3, 3) or None
        Attitude ``C_B^E``, body FRD to ECEF.
    omega_b : array (N, 3) or None
        Body angular rate in FRD axes (rad/s), relative to inertial space (``ω_ib^B``,
        gyro-like) or to the Earth (``ω_eb^B``, odometry ``twist.angular``) per
        ``omega_frame``.
    omega_frame : {"inertial", "earth"}
    """

    t: F64
    r_ecef: F64
    v_ecef: F64 | None = None
    a_ecef: F64 | None = None
    c_b_e: F64 | None = None
    omega_b: F64 | None = None
    omega_frame: str = "inertial"


def _dcm_from_euler(roll: F64, pitch: F64, heading: F64) -> F64:
    """``rotations.dcm_from_euler``: ``C_B^N = Rz(heading) Ry(pitch) Rx(roll)``, rad in.

    Same bits, the stacked products compiled (:func:`~strapdown_ros.core._compiled.matmul33`).
    """
    return matmul33(matmul33(rot_z(heading), rot_y(pitch)), rot_x(roll))


def _arr(name: str, x: ArrayLike, n: int, width: int | tuple[int, ...] | None) -> F64:
    a = np.asarray(x, dtype=np.float64)
    shape = (n,) if width is None else (n,) + ((width,) if isinstance(width, int) else width)
    if a.shape != shape:
        raise ValueError(f"{name}: expected shape {shape}, got {a.shape}")
    bad = ~np.isfinite(a.reshape(n, -1)).all(axis=1)
    if np.any(bad):
        raise ValueError(f"{name}: NaN or infinite value at sample {int(np.argmax(bad))}")
    return a


def check_times(name: str, t: ArrayLike) -> F64:
    """``t`` as float64 if a 1-D, finite, strictly increasing array of >= 2 times (s).

    Raises ValueError naming ``name`` and the first offending sample otherwise.
    """
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1:
        raise ValueError(f"{name}: expected a 1-D array of times, got shape {t.shape}")
    if t.size < 2:
        raise ValueError(f"{name}: need at least 2 samples, got {t.size}")
    bad = ~np.isfinite(t)
    if np.any(bad):
        raise ValueError(f"{name}: NaN or infinite time at sample {int(np.argmax(bad))}")
    d = np.diff(t)
    if np.any(d <= 0.0):
        i = int(np.argmax(d <= 0.0))
        raise ValueError(
            f"{name}: times must be strictly increasing (sample {i + 1}: {float(t[i + 1])!r} "
            f"after {float(t[i])!r})"
        )
    return t


def samples_from_arrays(
    t: ArrayLike,
    *,
    r_ecef: ArrayLike | None = None,
    lat: ArrayLike | None = None,
    lon: ArrayLike | None = None,
    alt: ArrayLike | None = None,
    v_ecef: ArrayLike | None = None,
    v_ned: ArrayLike | None = None,
    v_body: ArrayLike | None = None,
    a_ecef: ArrayLike | None = None,
    c_b_e: ArrayLike | None = None,
    q_b_e: ArrayLike | None = None,
    c_b_n: ArrayLike | None = None,
    q_b_n: ArrayLike | None = None,
    roll: ArrayLike | None = None,
    pitch: ArrayLike | None = None,
    heading: ArrayLike | None = None,
    omega_ib_b: ArrayLike | None = None,
    omega_eb_b: ArrayLike | None = None,
) -> Samples:
    """Validate plain arrays and convert them to :class:`Samples`.

    Body axes are FRD and local level is NED throughout (a ROS Odometry loader converts
    FLU → FRD first: ``C_FRD^E = C_FLU^E · diag(1, −1, −1)``, ``v^FRD = diag(1, −1, −1) v^FLU``).

    Parameters
    ----------
    t : array_like (N,)
        Sample times (s), strictly increasing, N >= 2.
    r_ecef : array_like (N, 3)
        ECEF position (m); or ``lat, lon`` (rad, geodetic WGS-84) and ``alt`` (m, ellipsoidal).
    v_ecef, v_ned, v_body : array_like (N, 3), optional (at most one)
        Velocity relative to the Earth (m/s) in ECEF, NED or body FRD axes (``v_body`` needs an
        attitude; ``v_ned`` uses the NED frame at the sample position).
    a_ecef : array_like (N, 3), optional
        ``d²r^E/dt²`` (m/s²) in ECEF.
    c_b_e, q_b_e, c_b_n, q_b_n, (roll, pitch, heading) : optional (at most one form)
        Attitude of body FRD: DCM/quaternion (scalar first) to ECEF or to NED, or Euler angles
        (rad) w.r.t. NED, ``C_B^N = Rz(heading) Ry(pitch) Rx(roll)``.
    omega_ib_b, omega_eb_b : array_like (N, 3), optional (at most one)
        Body angular rate in FRD axes (rad/s) relative to inertial space (gyro) or to the Earth
        (odometry ``twist.angular``).

    Returns
    -------
    Samples

    Raises
    ------
    ValueError
        Naming the argument: missing/duplicate inputs, wrong shape, NaN, non-increasing time.
    """
    t = check_times("t", t)
    n = t.size
    geo = {"lat": lat, "lon": lon, "alt": alt}
    given_geo = [k for k, v in geo.items() if v is not None]
    if r_ecef is not None and given_geo:
        raise ValueError("position: give r_ecef or lat/lon/alt, not both")
    if r_ecef is not None:
        r = _arr("r_ecef", r_ecef, n, 3)
        lat_s, lon_s, _ = ecef_to_geodetic(r)
    elif given_geo:
        missing = [k for k in geo if geo[k] is None]
        if missing:
            raise ValueError(f"position: missing {', '.join(missing)} (lat, lon, alt go together)")
        lat_s = _arr("lat", lat, n, None)
        lon_s = _arr("lon", lon, n, None)
        r = geodetic_to_ecef(lat_s, lon_s, _arr("alt", alt, n, None))
    else:
        raise ValueError("position: missing r_ecef (or lat, lon, alt)")
    c_n_e = dcm_ned_to_ecef(lat_s, lon_s)

    euler = {"roll": roll, "pitch": pitch, "heading": heading}
    forms = {"c_b_e": c_b_e, "q_b_e": q_b_e, "c_b_n": c_b_n, "q_b_n": q_b_n}
    given = [k for k, v in forms.items() if v is not None]
    if any(v is not None for v in euler.values()):
        missing = [k for k, v in euler.items() if v is None]
        if missing:
            raise ValueError(
                f"attitude: missing {', '.join(missing)} (roll, pitch, heading go together)"
            )
        given.append("roll/pitch/heading")
    if len(given) > 1:
        raise ValueError(f"attitude: give one form only, got {', '.join(given)}")
    cbe: F64 | None = None
    if c_b_e is not None:
        cbe = _arr("c_b_e", c_b_e, n, (3, 3))
    elif q_b_e is not None:
        cbe = dcm_from_quat(_arr("q_b_e", q_b_e, n, 4))
    elif c_b_n is not None:
        cbe = matmul33(c_n_e, _arr("c_b_n", c_b_n, n, (3, 3)))
    elif q_b_n is not None:
        cbe = matmul33(c_n_e, dcm_from_quat(_arr("q_b_n", q_b_n, n, 4)))
    elif roll is not None:
        roll_a = _arr("roll", roll, n, None)
        pitch_a = _arr("pitch", pitch, n, None)
        cbe = matmul33(c_n_e, _dcm_from_euler(roll_a, pitch_a, _arr("heading", heading, n, None)))
    if cbe is not None and np.any(np.linalg.norm(cbe.reshape(n, 9), axis=1) < 1e-6):
        raise ValueError("attitude: zero quaternion or matrix in the attitude samples")

    vel = {"v_ecef": v_ecef, "v_ned": v_ned, "v_body": v_body}
    given = [k for k, v in vel.items() if v is not None]
    if len(given) > 1:
        raise ValueError(f"velocity: give one form only, got {', '.join(given)}")
    ve: F64 | None = None
    if v_ecef is not None:
        ve = _arr("v_ecef", v_ecef, n, 3)
    elif v_ned is not None:
        ve = np.einsum("nij,nj->ni", c_n_e, _arr("v_ned", v_ned, n, 3))
    elif v_body is not None:
        if cbe is None:
            raise ValueError(
                "v_body: needs attitude samples (c_b_e, q_b_e, c_b_n, q_b_n or roll/pitch/heading)"
            )
        ve = np.einsum("nij,nj->ni", cbe, _arr("v_body", v_body, n, 3))

    if omega_ib_b is not None and omega_eb_b is not None:
        raise ValueError("rate: give omega_ib_b or omega_eb_b, not both")
    om, frame = None, "inertial"
    if omega_ib_b is not None:
        om = _arr("omega_ib_b", omega_ib_b, n, 3)
    elif omega_eb_b is not None:
        om, frame = _arr("omega_eb_b", omega_eb_b, n, 3), "earth"
    acc = None if a_ecef is None else _arr("a_ecef", a_ecef, n, 3)
    return Samples(t=t, r_ecef=r, v_ecef=ve, a_ecef=acc, c_b_e=cbe, omega_b=om, omega_frame=frame)


# --------------------------------------------------------------------------------------------
# The trajectory
# --------------------------------------------------------------------------------------------


def _breakpoints(
    spec: SplineOptions, kind: str, duration: float, median_dt: float
) -> tuple[F64, NDArray[np.int64]]:
    """Breakpoints (s since the first sample) and interior continuity of one spline.

    Errors are :class:`TrajectoryError` with ``where = (kind, option)``.
    """
    p = spec.degree
    if not isinstance(p, int | np.integer) or p < 1:
        raise TrajectoryError((kind, "degree"), f"must be an integer >= 1, got {p!r}")
    knots = spec.knots
    tol = 1e-9 * max(1.0, duration)
    if knots is None:
        knots = 2.0 * (p + 1) * median_dt
    if np.ndim(knots) == 0:
        spacing = float(knots)  # type: ignore[arg-type]
        if not spacing > 0.0:
            raise TrajectoryError((kind, "knots"), f"spacing must be > 0 s, got {knots!r}")
        nint = max(1, math.floor(duration / spacing + 1e-9))
        bp = np.linspace(0.0, duration, nint + 1)
    else:
        bp = np.asarray(knots, dtype=np.float64).reshape(-1)
        if bp.size and (bp.min() < -tol or bp.max() > duration + tol):
            raise TrajectoryError(
                (kind, "knots"),
                f"breakpoints [{float(bp.min())!r}, {float(bp.max())!r}] s outside the data span "
                f"[0, {duration!r}] s (knots are seconds since the first sample)",
            )
        if bp.size == 0 or abs(bp[0]) > tol:
            bp = np.concatenate([[0.0], bp])
        if abs(bp[-1] - duration) > tol:
            bp = np.concatenate([bp, [duration]])
        bp[0], bp[-1] = 0.0, duration
    cont = spec.continuity
    if cont is None:
        cont = p - 1
    try:
        bp, c = breakpoint_continuity(bp, p, cont)
    except ValueError as exc:
        raise _under(kind, exc) from None
    for i, item in enumerate(spec.breaks):
        try:
            tb, cb = float(item[0]), int(item[1])
        except (TypeError, ValueError, IndexError):
            raise TrajectoryError(
                (kind, "breaks", i), f"expected (t_s, continuity), got {item!r}"
            ) from None
        if not tol < tb < duration - tol:
            raise TrajectoryError(
                (kind, "breaks", i), f"t_s={tb!r} outside the data span (0, {duration!r}) s"
            )
        near = np.flatnonzero(np.abs(bp[1:-1] - tb) <= 1e-6)
        if near.size:
            c[near[0]] = cb
        else:
            j = int(np.searchsorted(bp, tb))
            bp = np.insert(bp, j, tb)
            c = np.insert(c, j - 1, cb)
    try:
        bp, c = breakpoint_continuity(bp, p, c)
    except ValueError as exc:
        raise _under(kind, exc) from None
    return bp, c


def _under(fit: str, exc: ValueError) -> TrajectoryError:
    """An error of a spline routine as a :class:`TrajectoryError` under ``fit``."""
    if isinstance(exc, TrajectoryError):
        return exc.under(fit)
    return TrajectoryError((fit,), str(exc))


def _derived_c_b_n(v_ned: F64) -> F64:
    """Heading along the horizontal velocity, pitch along the flight path, roll 0 (held)."""
    vh = np.hypot(v_ned[:, 0], v_ned[:, 1])
    speed = np.linalg.norm(v_ned, axis=1)

    def held(value: F64, ok: NDArray[np.bool_]) -> F64:
        if not np.any(ok):
            return np.zeros_like(value)
        idx = np.where(ok, np.arange(value.size), 0)
        idx = np.maximum.accumulate(idx)
        idx[: int(np.argmax(ok))] = int(np.argmax(ok))
        return value[idx]

    heading = held(np.arctan2(v_ned[:, 1], v_ned[:, 0]), vh >= DERIVED_ATTITUDE_MIN_SPEED)
    pitch = held(np.arctan2(-v_ned[:, 2], vh), speed >= DERIVED_ATTITUDE_MIN_SPEED)
    return _dcm_from_euler(np.zeros_like(pitch), pitch, heading)


def _weights(name: str, w: float | ArrayLike, n: int) -> F64:
    a = np.asarray(w, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,) or not np.all(np.isfinite(a)) or np.any(a < 0.0):
        raise TrajectoryError(("weights", name), f"expected a number >= 0 or {n} of them")
    return a


class SamplesTrajectory:
    """Continuous truth fitted to coarse samples (Giribet 2007); a ``Trajectory``.

    Parameters
    ----------
    samples : Samples
        The data (see :func:`samples_from_arrays`, :func:`load_samples_csv`).
    options : FitOptions, optional

    Attributes
    ----------
    t0 : float
        Time of the first sample (in the samples' time base); ``t = 0`` of the trajectory.
    attitude_source : {"samples", "derived"}
    attitude_method : {"fit", "integrate"}
    position_breakpoints, attitude_breakpoints : ndarray
        Breakpoints actually used (s since the first sample).

    Raises
    ------
    TrajectoryError
        For inconsistent options or samples that do not determine the splines; ``where``
        names the option: ``(fit, option)`` with ``fit`` ``position`` or ``attitude`` and
        ``option`` ``degree``, ``knots``, ``continuity`` or ``breaks`` (``(fit,)`` alone for
        a problem of the fit as a whole), ``("weights", name)`` or ``("attitude_method",)``.
    """

    def __init__(self, samples: Samples, options: FitOptions | None = None) -> None:
        opts = options or FitOptions()
        self.samples = samples
        self.options = opts
        t = np.asarray(samples.t, dtype=np.float64)
        self.t0 = float(t[0])
        tl = t - t[0]
        n = tl.size
        self._duration = float(tl[-1])
        median_dt = float(np.median(np.diff(tl)))
        w = opts.weights

        # Position: Problem PV in ECEF.
        pos = opts.position
        if n < pos.degree + 1:
            raise TrajectoryError(
                ("position", "degree"),
                f"{n} samples are too few for a degree-{pos.degree} position spline "
                f"(need >= {pos.degree + 1})",
            )
        bp, c = _breakpoints(pos, "position", self._duration, median_dt)
        if c.size and c.min() < 1:
            raise TrajectoryError(
                ("position", "continuity"),
                f"must be >= 1 (continuous velocity), got {c.tolist()}",
            )
        self.position_breakpoints = bp
        w_v = _weights("velocity", w.velocity, n) if samples.v_ecef is not None else None
        w_a = _weights("acceleration", w.acceleration, n) if samples.a_ecef is not None else None
        w_p = _weights("position", w.position, n)

        def fit_position() -> BSpline:
            try:
                return problem_pv(
                    bp,
                    pos.degree,
                    c,
                    tl,
                    samples.r_ecef,
                    w_p,
                    tau_v=None if w_v is None else tl,
                    v=samples.v_ecef,
                    w_v=0.0 if w_v is None else w_v,
                    tau_a=None if w_a is None else tl,
                    a=samples.a_ecef,
                    w_a=0.0 if w_a is None else w_a,
                )
            except ValueError as exc:
                raise _under("position", exc) from None

        if samples.c_b_e is None or n < MIN_ROWS or WORKERS < 2:
            self._pos = fit_position()
            self._fit_attitude(samples, tl, median_dt)
            return
        # The two fits are independent here: the position's on a second thread (numpy, scipy
        # and the compiled kernels release the GIL; same bits). A position error is raised
        # first, as on one thread.
        with ThreadPoolExecutor(1) as pool:
            position = pool.submit(fit_position)
            try:
                self._fit_attitude(samples, tl, median_dt)
            except BaseException:
                self._pos = position.result()
                raise
            self._pos = position.result()

    def _fit_attitude(self, samples: Samples, tl: F64, median_dt: float) -> None:
        """The attitude spline (``attitude_method`` fit or integrate) of the samples."""
        n = tl.size
        opts = self.options
        w = opts.weights
        # Attitude samples in E0 (q_B^E0 = C_E^E0(t) C_B^E), rates as omega_ib^B.
        if samples.c_b_e is not None:
            c_b_e = samples.c_b_e
            self.attitude_source = "samples"
        else:
            r, v = self._pos(tl), self._pos(tl, 1)
            lat, lon, _ = ecef_to_geodetic(r)
            c_b_e = matmul33(
                dcm_ned_to_ecef(lat, lon), _derived_c_b_n(ned_velocity_from_ecef(lat, lon, v))
            )
            self.attitude_source = "derived"
        q_e0 = quat_from_dcm(matmul33(dcm_ecef_to_e0(tl), c_b_e))
        omega = samples.omega_b
        if omega is not None and samples.omega_frame == "earth":
            omega = omega + OMEGA_IE * c_b_e[:, 2, :]  # ω_ib = ω_eb + C_E^B ω_ie^E
        elif omega is not None and samples.omega_frame != "inertial":
            raise ValueError(f"omega_frame: 'inertial' or 'earth', got {samples.omega_frame!r}")

        att = opts.attitude
        method = opts.attitude_method
        if method == "auto":
            method = "integrate" if (omega is not None and samples.c_b_e is None) else "fit"
        if method not in ("fit", "integrate"):
            raise TrajectoryError(
                ("attitude_method",),
                f"'auto', 'fit' or 'integrate', got {opts.attitude_method!r}",
            )
        self.attitude_method = method
        if n < att.degree + 1:
            raise TrajectoryError(
                ("attitude", "degree"),
                f"{n} samples are too few for a degree-{att.degree} attitude spline "
                f"(need >= {att.degree + 1})",
            )
        if method == "integrate" and omega is None:
            raise TrajectoryError(("attitude_method",), "'integrate' needs angular-rate samples")
        if method == "integrate" and att.degree < 2:
            raise TrajectoryError(
                ("attitude", "degree"), "must be >= 2 with attitude_method 'integrate'"
            )
        bp, c = _breakpoints(att, "attitude", self._duration, median_dt)
        if c.size and c.min() < 0:
            raise TrajectoryError(("attitude", "continuity"), f"must be >= 0, got {c.tolist()}")
        self.attitude_breakpoints = bp
        w_r = None if omega is None else _weights("rate", w.rate, n)
        w_q = _weights("attitude", w.attitude, n) if method == "fit" else None
        try:
            if method == "fit":
                assert w_q is not None
                self._att = fit_quaternion(
                    bp,
                    att.degree,
                    c,
                    tl,
                    q_e0,
                    w_q,
                    omega=omega if w_r is not None and np.any(w_r > 0) else None,
                    w_omega=0.0 if w_r is None else w_r,
                )
            else:
                assert omega is not None and w_r is not None
                self._att = self._integrate(tl, q_e0[0], omega, bp, c, w_r)
        except ValueError as exc:
            raise _under("attitude", exc) from None

    def _integrate(
        self,
        tl: F64,
        q0: F64,
        omega: F64,
        bp: F64,
        c: NDArray[np.int64],
        w_rate: F64,
    ) -> QuaternionSpline:
        """Problems ω, q1, q2 (rate spline of degree p − 1, continuity c − 1)."""
        opts = self.options
        p = opts.attitude.degree - 1
        w_spline = problem_omega(bp, p, c - 1, tl, omega, w_rate)
        self._omega_fit = w_spline
        step = opts.q_step
        if step is None:
            w_max = float(np.max(np.linalg.norm(w_spline(tl), axis=1)))
            step = min(float(np.min(np.diff(bp))) / 8.0, 0.05 / max(w_max, 1e-3))
        tau, q, _ = problem_q1(w_spline, q0, bp, step=step)
        corners = bp[1:-1][(c - 1) < p - 1]
        return problem_q2(tau, q, corners, degree=opts.q2_degree)

    # ----------------------------------------------------------------------------------------
    # Constructors
    # ----------------------------------------------------------------------------------------

    @classmethod
    def from_arrays(
        cls, t: ArrayLike, *, options: FitOptions | None = None, **arrays: ArrayLike | None
    ) -> SamplesTrajectory:
        """Fit plain arrays; keyword arguments as :func:`samples_from_arrays`.

        Example (odometry: ECEF position, ``C_B^E`` and body velocity, FRD)::

            SamplesTrajectory.from_arrays(t, r_ecef=r, c_b_e=c, v_body=v, omega_eb_b=w)
        """
        return cls(samples_from_arrays(t, **arrays), options)

    # ----------------------------------------------------------------------------------------
    # Evaluation
    # ----------------------------------------------------------------------------------------

    @property
    def duration(self) -> float:
        """Span of the samples (s): last sample time minus first."""
        return self._duration

    def _t(self, t: ArrayLike) -> F64:
        t = np.asarray(t, dtype=np.float64)
        tol = 1e-9 * max(1.0, self._duration)
        if t.size and (np.min(t) < -tol or np.max(t) > self._duration + tol):
            raise ValueError(
                f"t: times [{float(np.min(t))!r}, {float(np.max(t))!r}] s outside the "
                f"trajectory span [0, {self._duration!r}] s"
            )
        return np.clip(t, 0.0, self._duration)

    def position_ecef(self, t: ArrayLike, nu: int = 0) -> F64:
        """``nu``-th derivative of the fitted ECEF position (m, m/s, m/s²), shape (..., 3).

        ``nu = 1`` is the velocity relative to the Earth in ECEF axes, ``nu = 2`` its rate.
        """
        return self._pos(self._t(t), nu)

    def q_b_e0(self, t: ArrayLike) -> F64:
        """Attitude quaternion ``q_B^E0`` (body FRD to E0), scalar first, unit, (..., 4)."""
        return self._att.q(self._t(t))

    def q_dot_b_e0(self, t: ArrayLike) -> F64:
        """``dq_B^E0/dt`` (1/s), exact derivative of :meth:`q_b_e0` (Giribet eq. (22))."""
        return self._att.q_dot(self._t(t))

    def omega_ib_b(self, t: ArrayLike) -> F64:
        """Consistent body rate ``ω_ib^B`` (rad/s, FRD) of eq. (23): ``q̇ = ½ q ⊗ [0, ω]``."""
        return self._att.omega(self._t(t))

    def c_b_e(self, t: ArrayLike) -> F64:
        """``C_B^E = C_E0^E(t) C_B^E0`` (body FRD to ECEF), (..., 3, 3)."""
        t = self._t(t)
        return dcm_e0_to_ecef(t) @ dcm_from_quat(self._att.q(t))

    def local_truth(self, t: ArrayLike) -> LocalTruth:
        """Truth at ``t`` (s since the first sample), ``0 <= t <= duration``.

        Position from the position spline, velocity its derivative (NED at the fitted
        position), ``C_B^N = C_E^N C_E0^E(t) C_B^E0`` with the normalized fitted quaternion.
        """
        t = self._t(np.atleast_1d(t))
        r = self._pos(t)
        v = self._pos(t, 1)
        lat, lon, alt = ecef_to_geodetic(r)
        c_b_n = dcm_ecef_to_ned(lat, lon) @ dcm_e0_to_ecef(t) @ dcm_from_quat(self._att.q(t))
        return LocalTruth(
            t=t, lat=lat, lon=lon, alt=alt, v_ned=ned_velocity_from_ecef(lat, lon, v), c_b_n=c_b_n
        )

    def truth_e0(self, t: ArrayLike) -> TruthE0:
        """Truth at ``t`` directly in E0 (docs/interface.md §1), without the geodetic round trip.

        ``R^E0 = C_E^E0(t) r^E``, ``V^E0 = C_E^E0 (v^E + ω_ie × r^E)`` from the position spline
        and its derivative, ``C_B^E0`` from the fitted quaternion (normalized). Equal to
        ``local_to_e0(local_truth(t))`` up to that round trip's rounding (~1e-9 m).
        """
        t = self._t(np.atleast_1d(t))
        r0, v0, _ = ecef_state_to_e0(t, self._pos(t), self._pos(t, 1))
        return TruthE0(t=t, c_b_e0=dcm_from_quat(self._att.q(t)), v_e0=v0, r_e0=r0)

    def residuals(self) -> dict[str, float]:
        """RMS fit residuals at the samples, for the data given.

        Keys: ``position`` (m), ``velocity`` (m/s), ``attitude`` (rad), ``rate`` (rad/s,
        ``ω_ib^B``).
        """
        s = self.samples
        tl = s.t - s.t[0]
        out = {"position": float(np.sqrt(np.mean(np.sum((self._pos(tl) - s.r_ecef) ** 2, 1))))}
        if s.v_ecef is not None:
            dv = self._pos(tl, 1) - s.v_ecef
            out["velocity"] = float(np.sqrt(np.mean(np.sum(dv**2, 1))))
        if s.c_b_e is not None:
            d = np.swapaxes(s.c_b_e, -1, -2) @ self.c_b_e(tl)
            ang = np.arccos(np.clip((np.trace(d, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0))
            out["attitude"] = float(np.sqrt(np.mean(ang**2)))
        if s.omega_b is not None:
            om = s.omega_b
            if s.omega_frame == "earth":
                om = om + OMEGA_IE * self.c_b_e(tl)[:, 2, :]
            out["rate"] = float(np.sqrt(np.mean(np.sum((self.omega_ib_b(tl) - om) ** 2, 1))))
        return out
