"""Rerun of Waldmann's Table 3 (seeds/004, §6): RSS horizontal error after 300 s of coning.

Scenarios ``config/scenarios/waldmann_rest.yaml`` and ``waldmann_moving.yaml``: the body cones
about the local vertical (θ = π/2, Ω_p = π/6 rad/s) while its centre of mass (CM) rests or
moves with the §6 sinusoids; the IMU sits 1 m ahead of the CM (the scenario's ``variation``
section, lever arm [1, 0, 0] m in body FRD). The navigators run on the IMU (variation) stream
and are compared with its own truth.

Columns (Table 3): T_nav = 9.996e-2 s with N = 12 (T_gyr = 8.33e-3 s, the scenario's rate) and
N = 120 (T_gyr = 8.33e-4 s), and T_nav = 9.996e-3 s with N = 12 (T_gyr = 8.33e-4 s), for the CM
at rest and moving (the paper has no "rest, T_nav/10" column). Rows: the simultaneous scheme
(Table 2), the multirate scheme (Table 1) in ``paper`` mode with P = 4 and P = 40, and in the
high-accuracy ``exact`` mode with P = 4 and P = 40.

Two IMU data sets:

* ``integrated`` (the rerun proper): increments as an integrating IMU reports them, each
  ``Δφ_b``, ``Δβ_b`` the sum of the two increments of a Method 2 pair of a stream generated at
  ``T_gyr/2`` (docs/interface.md §2's oversampled output), so that Method 2's odd/even
  specific-force term
  (Savage 2020 eqs. (49)-(50)) cancels inside every sample, as in the paper's data integrated
  from a continuous-time simulation. Truth: the generation truth at the output instants.
* ``exact``: the stream at ``T_gyr`` itself, what ``strapdown-sim generate`` writes as
  ``/variation/imu`` (exact to docs/interface.md §3 at its own rate).

Main settings (closest to the paper): Table 1's first-order radii (``table1_radii=True``, also
for Table 2), the quaternion normalized after every fast step (the navigator's default), no
vertical damping (horizontal errors change by < 0.4 m with it; Table 1's printed damping signs
diverge, see the variants), Table 2's sampled ``f_b = Δβ_b/T_gyr`` from the first increment
of each T_nav cycle (the library's reading). The error is the one at the last whole T_nav cycle
within the stream: 3001 T_nav = 299.98 s (30011 T_nav = 299.99 s for T_nav/10).

Further tables (``integrated`` data): single settings changed (exact WGS-84 radii, no
quaternion normalization, vertical damping with stable or printed signs, Table 2 sampling the
increment that ends at t_k, the IMU at the CM); the coning phase (initial heading) at
N = 12; and, for both data sets, the end error vectors split into their T_nav- and
T_gyr-proportional parts next to the first-order predictions explained in docs/navigator.md
("Waldmann Table 3 rerun").

Usage: python bench/waldmann_table3.py [--duration S] [--no-variants] [--no-phase]
Last line: ``exact_vs_paper_at_N12: X x`` (smallest paper/exact ratio over every N = 12 case).
"""

from __future__ import annotations

import argparse
import math
import time
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from strapdown_ros.config import load_scenario
from strapdown_ros.core.navigation import (
    VerticalDamping,
    navigate_multirate,
    navigate_simultaneous,
    state_from_stream,
    truth_navigation,
)
from strapdown_ros.core.navigation.errors import navigation_errors
from strapdown_ros.core.rotations import dcm_from_quat
from strapdown_ros.core.stream import Stream
from strapdown_ros.core.variation import generate_variation
from strapdown_ros.stages.trajectory import generate_reference
from strapdown_ros.stages.variation import scenario_offsets, variation_settings

SCENARIOS = Path(__file__).resolve().parents[1] / "config" / "scenarios"
#: IMU periods of Table 3 (ns): T_gyr = 8.33e-3 s (the scenario files) and 8.33e-4 s.
PERIOD_SLOW, PERIOD_FAST = 8_330_000, 833_000
CASES = ("rest", "moving")
DATA = ("integrated", "exact")
#: Generation cycles summed per output increment for the ``integrated`` data set.
SUM = 2
T_END = 300.0


@dataclass(frozen=True)
class Column:
    """One Table 3 column: CM case, label, N and the IMU period T_gyr (ns)."""

    case: str
    label: str
    n: int
    period_ns: int

    @property
    def t_gyr(self) -> float:
        return self.period_ns * 1e-9

    @property
    def t_nav(self) -> float:
        return self.n * self.t_gyr


@dataclass(frozen=True)
class Scheme:
    """A navigator configuration (row)."""

    name: str
    algorithm: str  # "simultaneous" | "multirate"
    mode: str = "paper"
    p: int = 1


LABELS = (("N=12", 12, PERIOD_SLOW), ("N=120", 120, PERIOD_FAST), ("Tnav/10", 12, PERIOD_FAST))
COLUMNS = tuple(Column(case, *lab) for case in CASES for lab in LABELS)
SIMULT = Scheme("simultaneous (Table 2)", "simultaneous")
PAPER4 = Scheme("multirate paper P=4", "multirate", "paper", 4)
PAPER40 = Scheme("multirate paper P=40", "multirate", "paper", 40)
EXACT4 = Scheme("multirate exact P=4", "multirate", "exact", 4)
EXACT40 = Scheme("multirate exact P=40", "multirate", "exact", 40)
SCHEMES = (SIMULT, PAPER4, PAPER40, EXACT4, EXACT40)

#: Waldmann Table 3 (RSS horizontal error at the end, m): (simultaneous, multirate).
PAPER = {
    ("rest", "N=12"): (7.0, 17.0),
    ("rest", "N=120"): (1.0, 1.0),
    ("moving", "N=12"): (119.0, 79.0),
    ("moving", "N=120"): (45.0, 15.0),
    ("moving", "Tnav/10"): (11.0, 9.0),
}


@dataclass
class Result:
    """End-of-run errors of one navigator on one stream."""

    t_end: float
    horizontal: float  # RSS horizontal error at the last output, m
    ned: np.ndarray  # position error (N, E, D) at the last output, m
    seconds: float  # navigator run time
    attitude: np.ndarray  # Young angles (up, east, north) at the last output, rad
    diverged_at: float | None = None  # first non-finite output time, s


@dataclass
class Streams:
    """The IMU (variation) and CM (reference) streams of one case, data set and period."""

    imu: Stream
    cm: Stream
    seconds: float


def summed(stream: Stream, k: int) -> Stream:
    """Output stream at ``k T``: increments summed over k cycles, truth every k-th sample.

    What an IMU integrating over ``k T`` reports (docs/interface.md §2, ``oversample``); trailing
    cycles that
    do not fill an output cycle are dropped.
    """
    if k == 1:
        return stream
    m = stream.cycles // k * k
    return replace(
        stream,
        period_ns=stream.period_ns * k,
        dalpha=stream.dalpha[:m].reshape(-1, k, 3).sum(axis=1),
        dv=stream.dv[:m].reshape(-1, k, 3).sum(axis=1),
        c_b_e0=stream.c_b_e0[: m + 1 : k],
        v_e0=stream.v_e0[: m + 1 : k],
        r_e0=stream.r_e0[: m + 1 : k],
    )


def load_streams(
    case: str, period_ns: int, data: str, duration_s: float, overrides: Iterable[str] = ()
) -> Streams:
    """CM reference and IMU variation of ``waldmann_<case>.yaml`` at ``period_ns``.

    ``data="exact"``: generated at ``period_ns``; ``"integrated"``: generated at
    ``period_ns / SUM`` and summed (:func:`summed`).
    """
    if data not in DATA:
        raise ValueError(f"data must be one of {DATA}, got {data!r}")
    k = SUM if data == "integrated" else 1
    if period_ns % k:
        raise ValueError(f"{period_ns} ns is not divisible by {k}")
    t0 = time.perf_counter()
    scenario = load_scenario(
        SCENARIOS / f"waldmann_{case}.yaml",
        [f"rate_hz={1e9 / (period_ns // k)!r}", *overrides],
        duration_s,
    )
    reference = generate_reference(scenario)
    method, gravity = variation_settings(scenario)
    offsets = scenario_offsets(scenario, reference.cycles + 1)
    variation = generate_variation(reference, offsets, method, gravity)
    return Streams(summed(variation, k), summed(reference, k), time.perf_counter() - t0)


def shifted_sample(dv: np.ndarray) -> np.ndarray:
    """Increments shifted by one: index m holds Δβ_{m-1} (index 0 keeps Δβ_0).

    :class:`SimultaneousNavigator` samples ``dv[j N]``, the first increment of cycle j (over
    ``(t_k, t_k + T_gyr]``); with this array it samples the increment that *ends* at ``t_k``
    (Table 2's ``Δβ_b(n T_gyr)`` at ``k T_nav = n T_gyr``, read with docs/interface.md §2 stamps).
    The
    simultaneous scheme reads ``dv`` nowhere else (the thrust velocity of the shared
    fast-cycle routine is discarded), which ``test/test_waldmann_table3.py`` checks.
    """
    return np.concatenate([dv[:1], dv[:-1]])


def run(
    stream: Stream,
    n: int,
    scheme: Scheme,
    table1_radii: bool = True,
    damping: VerticalDamping | None = None,
    sample: str = "first",
    normalize: bool = True,
) -> Result:
    """Navigate ``stream`` with ``scheme`` at N = ``n``; errors at the last output."""
    initial = state_from_stream(stream)
    t_gyr = stream.period_ns * 1e-9
    h_aux = None
    if damping is not None:  # auxiliary altitude: the truth at the start of every cycle
        cycles = stream.cycles // n
        h_aux = truth_navigation(stream, np.arange(cycles) * n)[3]
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # diverging damping: overflow
        if scheme.algorithm == "simultaneous":
            dv = stream.dv if sample == "first" else shifted_sample(stream.dv)
            sol = navigate_simultaneous(
                initial, stream.dalpha, dv, t_gyr, n, gravity_model=stream.gravity_model,
                normalize=normalize, table1_radii=table1_radii, damping=damping, h_aux=h_aux,
            )  # fmt: skip
        else:
            sol = navigate_multirate(
                initial, stream.dalpha, stream.dv, t_gyr, n, scheme.p,
                gravity_model=stream.gravity_model, normalize=normalize,
                table1_radii=table1_radii and scheme.mode == "paper", mode=scheme.mode,
                damping=damping, h_aux=h_aux,
            )  # fmt: skip
        seconds = time.perf_counter() - t0
        err = navigation_errors(sol, stream)
    bad = ~np.isfinite(err.position_ned).all(axis=1)
    diverged = float(sol.t[np.argmax(bad)]) if bad.any() else None
    return Result(
        float(sol.t[-1]), float(err.horizontal[-1]), err.position_ned[-1].copy(), seconds,
        err.attitude_young[-1].copy(), diverged,
    )  # fmt: skip


def rotation_compensation(stream: Stream, n: int) -> np.ndarray:
    """First-order term a first-order velocity update leaves out, as a position error (NED, m).

    ``δU(t) = Σ ½ C_B^N (Δφ_b × Δβ_b)`` over the increments up to t (the rotation-compensation
    term ``½ Δα × Δv`` of Savage 1998, mapped to the local level with the true attitude at the
    start of each increment), ``δx = ∫ δU dt``, at the last whole T_nav cycle of N = ``n``.
    Eq. (19)'s Euler step makes ``+δx``; Table 2 (``D_l^b`` at ``t_k``, ``f_b`` over the next
    increment) about ``-δx`` on continuous (``integrated``) data (docs/navigator.md).
    """
    m = stream.cycles // n * n
    q = truth_navigation(stream, np.arange(m))[5]
    c = dcm_from_quat(q)
    term = 0.5 * np.einsum("nij,nj->ni", c, np.cross(stream.dalpha[:m], stream.dv[:m]))
    return np.cumsum(np.cumsum(term, axis=0), axis=0)[-1] * stream.period_ns * 1e-9


def imu_kinematics(stream: Stream, n: int) -> dict[str, np.ndarray]:
    """IMU ground-velocity change to the last whole T_nav and acceleration at t = 0 (NED)."""
    m_end = stream.cycles // n * n
    v = truth_navigation(stream, np.array([0, 1, m_end]))[4]
    return {
        "dv": v[2] - v[0],
        "a0": (v[1] - v[0]) / (stream.period_ns * 1e-9),
        "t": np.array(m_end * stream.period_ns * 1e-9),
    }


@dataclass
class Study:
    """All results, keyed by (data set, case, column label, row name)."""

    duration_s: float
    results: dict[tuple[str, str, str, str], Result] = field(default_factory=dict)
    kinematics: dict[tuple[str, str], dict[str, np.ndarray]] = field(default_factory=dict)
    rotation: dict[tuple[str, str, str], np.ndarray] = field(default_factory=dict)
    generation_s: float = 0.0

    def h(self, data: str, case: str, label: str, row: str) -> float:
        return self.results[(data, case, label, row)].horizontal


def _variants(study: Study, data: str, col: Column, streams: Streams) -> None:
    key = (data, col.case, col.label)
    res = study.results
    res[(*key, "Table 2: f_b ending at t_k")] = run(streams.imu, col.n, SIMULT, sample="last")
    for scheme, tag in ((SIMULT, "Table 2"), (PAPER4, "Table 1 P=4")):
        res[(*key, f"{tag}: IMU at the CM")] = run(streams.cm, col.n, scheme)
        if col.label == "Tnav/10":
            continue
        res[(*key, f"{tag}: exact WGS-84 radii")] = run(
            streams.imu, col.n, scheme, table1_radii=False
        )
        res[(*key, f"{tag}: no q normalization")] = run(
            streams.imu, col.n, scheme, normalize=False
        )
        res[(*key, f"{tag}: damping, stable signs")] = run(
            streams.imu, col.n, scheme, damping=VerticalDamping()
        )
        res[(*key, f"{tag}: damping, printed signs")] = run(
            streams.imu, col.n, scheme, damping=VerticalDamping(paper_signs=True)
        )


def run_study(
    duration_s: float = T_END,
    columns: Iterable[Column] = COLUMNS,
    schemes: Iterable[Scheme] = SCHEMES,
    data_sets: Iterable[str] = DATA,
    variants: bool = True,
    phase: bool = True,
    decomposition: bool = True,
    progress: Callable[[str], None] | None = None,
) -> Study:
    """Run every (data set, column, scheme); optionally the variants, phase sweep, parts."""
    columns, schemes = tuple(columns), tuple(schemes)
    study = Study(duration_s)
    say = progress or (lambda _msg: None)
    for data in data_sets:
        for case in dict.fromkeys(c.case for c in columns):
            for period in dict.fromkeys(c.period_ns for c in columns if c.case == case):
                streams = load_streams(case, period, data, duration_s)
                study.generation_s += streams.seconds
                say(f"{data} {case} T_gyr = {period} ns: streams in {streams.seconds:.1f} s")
                cols = [c for c in columns if c.case == case and c.period_ns == period]
                for col in cols:
                    for scheme in schemes:
                        study.results[(data, case, col.label, scheme.name)] = run(
                            streams.imu, col.n, scheme
                        )
                    if variants and data == "integrated":
                        _variants(study, data, col, streams)
                    if decomposition and col.label in ("N=12", "N=120"):
                        study.rotation[(data, case, col.label)] = rotation_compensation(
                            streams.imu, col.n
                        )
                if decomposition and period == PERIOD_FAST:
                    study.kinematics[(data, case)] = imu_kinematics(streams.imu, 120)
                del streams
    if phase:
        for case in dict.fromkeys(c.case for c in columns):
            for heading in (90, 180, 270):
                streams = load_streams(
                    case, PERIOD_SLOW, "integrated", duration_s,
                    [f"initial.attitude_rph_deg=[0,0,{heading}]"],
                )  # fmt: skip
                study.generation_s += streams.seconds
                for scheme in (SIMULT, PAPER4):
                    study.results[("integrated", case, f"hdg{heading}", scheme.name)] = run(
                        streams.imu, 12, scheme
                    )
        say("phase sweep done")
    return study


# ---------------------------------------------------------------------------------- analysis
def ratios(study: Study, data: str) -> dict[str, float]:
    """The acceptance ratios (ours) of one data set; keys name the comparison."""
    r: dict[str, float] = {}
    res = study.results
    for label in ("N=12", "N=120", "Tnav/10"):
        a, b = (data, "moving", label, SIMULT.name), (data, "moving", label, PAPER4.name)
        if a in res and b in res:
            r[f"simult/multirate moving {label}"] = res[a].horizontal / res[b].horizontal
    for case in CASES:
        for s in (SIMULT, PAPER4, PAPER40):
            a, b = (data, case, "N=12", s.name), (data, case, "N=120", s.name)
            if a in res and b in res:
                r[f"N12/N120 {case} {s.name}"] = res[a].horizontal / res[b].horizontal
    for case in CASES:
        for label in ("N=12", "Tnav/10"):
            for p, e in ((PAPER4, EXACT4), (PAPER40, EXACT40)):
                a, b = (data, case, label, p.name), (data, case, label, e.name)
                if a in res and b in res:
                    num, den = res[a].horizontal, res[b].horizontal
                    r[f"paper/exact {case} {label} P={p.p}"] = num / den if den else math.inf
    return r


PAPER_RATIOS = {
    "simult/multirate moving N=12": 119 / 79,
    "simult/multirate moving N=120": 45 / 15,
    "simult/multirate moving Tnav/10": 11 / 9,
    f"N12/N120 rest {SIMULT.name}": 7.0,
    f"N12/N120 moving {SIMULT.name}": 119 / 45,
    f"N12/N120 rest {PAPER4.name}": 17.0,
    f"N12/N120 moving {PAPER4.name}": 79 / 15,
    f"N12/N120 rest {PAPER40.name}": 17.0,
    f"N12/N120 moving {PAPER40.name}": 79 / 15,
}


def tnav_parts(study: Study, data: str) -> dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]:
    """Measured and predicted ``e(N=120) - e(T_nav/10)`` (same T_gyr), horizontal (N, E), m.

    Euler-truncation predictions (docs/navigator.md): multirate ``-½ T_nav ΔU`` (eq. (9) with
    the start-of-cycle velocity); simultaneous ``½ T_nav a(0) t - T_nav ΔU`` (eq. (14) with the
    start-of-cycle specific force, then (9)); times the T_nav difference.
    """
    out = {}
    dt = 120 * PERIOD_FAST * 1e-9 - 12 * PERIOD_FAST * 1e-9
    for case in CASES:
        kin = study.kinematics.get((data, case))
        for s in (SIMULT, PAPER4):
            a = study.results.get((data, case, "N=120", s.name))
            b = study.results.get((data, case, "Tnav/10", s.name))
            if kin is None or a is None or b is None:
                continue
            if s is SIMULT:
                pred = dt * (0.5 * kin["a0"] * kin["t"] - kin["dv"])
            else:
                pred = dt * (-0.5 * kin["dv"])
            out[(case, s.name)] = ((a.ned - b.ned)[:2], pred[:2])
    return out


def tgyr_parts(study: Study, data: str) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """T_gyr parts of ``e(N=12) - e(N=120)`` (same T_nav), horizontal (N, E), m, per case.

    Returns ``(antisymmetric, predicted, common)``: ``(d_multirate - d_simultaneous) / 2``, its
    prediction from the rotation-compensation term ``δx`` (:func:`rotation_compensation`) —
    ``δx`` on ``integrated`` data (eq. (19) makes ``+δx``, Table 2 ``-δx``), ``⅚ δx`` on
    ``exact`` data (Table 2's single increments carry Method 2's odd/even term: ``-⅔ δx``) —
    and ``(d_multirate + d_simultaneous) / 2``, the part the two schemes share (the attitude
    drift of their common eq. (33), second order in T_gyr).
    """
    out = {}
    factor = 1.0 if data == "integrated" else 5.0 / 6.0
    for case in CASES:
        r12 = study.rotation.get((data, case, "N=12"))
        r120 = study.rotation.get((data, case, "N=120"))
        d = {}
        for s in (SIMULT, PAPER4):
            a = study.results.get((data, case, "N=12", s.name))
            b = study.results.get((data, case, "N=120", s.name))
            if a is not None and b is not None:
                d[s.name] = (a.ned - b.ned)[:2]
        if r12 is None or r120 is None or len(d) < 2:
            continue
        dm, ds = d[PAPER4.name], d[SIMULT.name]
        out[case] = (0.5 * (dm - ds), factor * (r12 - r120)[:2], 0.5 * (dm + ds))
    return out


# ---------------------------------------------------------------------------------- printing
def _fmt(x: float | None, width: int = 9) -> str:
    if x is None:
        return "—".rjust(width)
    if math.isinf(x):
        return "inf".rjust(width)
    if not math.isfinite(x):
        return "diverged".rjust(width)
    if x == 0.0:
        return "0".rjust(width)
    if 0.01 <= abs(x) < 1e4:
        return (f"{x:.0f}" if abs(x) >= 100 else f"{x:.3g}").rjust(width)
    return f"{x:.2g}".rjust(width)


def _header(columns: tuple[Column, ...], first: int) -> list[str]:
    return [
        " " * first + "".join(f"{'CM ' + c.case:>10}" for c in columns),
        " " * first + "".join(f"{c.label:>10}" for c in columns),
        f"{'T_nav [s]':{first}}" + "".join(f"{c.t_nav:10.4g}" for c in columns),
        f"{'T_gyr [s]':{first}}" + "".join(f"{c.t_gyr:10.3g}" for c in columns),
    ]


def format_main(study: Study, data: str, columns: tuple[Column, ...] = COLUMNS) -> str:
    first = 30
    out = _header(columns, first)

    def ours(name: str) -> list[float | None]:
        got = [study.results.get((data, c.case, c.label, name)) for c in columns]
        return [None if r is None else r.horizontal for r in got]

    def paper(i: int) -> list[float | None]:
        got = [PAPER.get((c.case, c.label)) for c in columns]
        return [None if v is None else v[i] for v in got]

    rows = [("paper: simultaneous", paper(0)), ("ours:  " + SIMULT.name, ours(SIMULT.name))]
    rows.append(("paper: multirate", paper(1)))
    rows += [("ours:  " + s.name, ours(s.name)) for s in SCHEMES[1:]]
    for name, values in rows:
        out.append(f"{name:{first}}" + "".join(_fmt(v, 10) for v in values))
    return "\n".join(out)


def format_ratios(study: Study) -> str:
    per = {d: ratios(study, d) for d in DATA}
    keys = list(dict.fromkeys(k for d in DATA for k in per[d]))
    out = [f"{'ratio':40}{'integrated':>12}{'exact':>12}{'paper':>10}"]
    for k in keys:
        out.append(
            f"{k:40}{_fmt(per['integrated'].get(k), 12)}{_fmt(per['exact'].get(k), 12)}"
            f"{_fmt(PAPER_RATIOS.get(k), 10)}"
        )
    return "\n".join(out)


def format_variants(study: Study, columns: tuple[Column, ...] = COLUMNS) -> str:
    first = 34
    out = _header(columns, first)
    names = sorted(
        {k[3] for k in study.results if k[3].startswith(("Table 2:", "Table 1 P=4:"))},
        key=lambda s: (not s.startswith("Table 2"), s),
    )
    notes = []
    for name in names:
        cells = []
        for c in columns:
            r = study.results.get(("integrated", c.case, c.label, name))
            if r is not None and r.diverged_at is not None:
                notes.append(f"  {name}, {c.case} {c.label}: non-finite from t = "
                             f"{r.diverged_at:.1f} s")  # fmt: skip
            cells.append(_fmt(None if r is None else r.horizontal, 10))
        out.append(f"{name:{first}}" + "".join(cells))
    return "\n".join(out + notes)


def format_phase(study: Study) -> str:
    out = [f"{'N = 12, initial heading':26}" + "".join(
        f"{case + ' ' + str(h):>11}" for case in CASES for h in (0, 90, 180, 270)
    )]  # fmt: skip
    for s in (SIMULT, PAPER4):
        cells = []
        for case in CASES:
            for h in (0, 90, 180, 270):
                label = "N=12" if h == 0 else f"hdg{h}"
                r = study.results.get(("integrated", case, label, s.name))
                cells.append(_fmt(None if r is None else r.horizontal, 11))
        out.append(f"{s.name:26}" + "".join(cells))
    return "\n".join(out)


def format_parts(study: Study, data: str) -> str:
    out = [f"end error (N, E) [m]{'':10}" + "".join(
        f"{c.case + ' ' + c.label:>17}" for c in COLUMNS
    )]  # fmt: skip
    for s in (SIMULT, PAPER4):
        cells = []
        for c in COLUMNS:
            r = study.results.get((data, c.case, c.label, s.name))
            cells.append(" " * 17 if r is None else f"{r.ned[0]:9.1f}{r.ned[1]:8.1f}")
        out.append(f"{s.name:30}" + "".join(cells))
    parts = tnav_parts(study, data)
    if parts:
        out.append("T_nav part e(N=120) - e(T_nav/10), same T_gyr = 8.33e-4 s, (N, E) m:")
        for (case, name), (meas, pred) in parts.items():
            out.append(f"  {case:7}{name:24} measured {meas[0]:7.2f} {meas[1]:7.2f}"
                       f"   Euler formula {pred[0]:7.2f} {pred[1]:7.2f}")  # fmt: skip
    parts = tgyr_parts(study, data)
    if parts:
        factor = "dx" if data == "integrated" else "5/6 dx"
        out.append(f"T_gyr part d = e(N=12) - e(N=120), same T_nav = 9.996e-2 s, (N, E) m: "
                   f"(d_multirate - d_simult)/2 against {factor} (rotation compensation), "
                   "and the shared part (d_multirate + d_simult)/2:")  # fmt: skip
        for case, (anti, pred, common) in parts.items():
            out.append(f"  {case:7}(d_m - d_s)/2 {anti[0]:7.2f} {anti[1]:7.2f}   {factor:>6} "
                       f"{pred[0]:7.2f} {pred[1]:7.2f}   shared {common[0]:7.2f} "
                       f"{common[1]:7.2f}")  # fmt: skip
        for case in CASES:
            a = study.results.get((data, case, "N=12", PAPER4.name))
            b = study.results.get((data, case, "N=120", PAPER4.name))
            if a is not None and b is not None:
                out.append(f"  {case:7}eq. (33) attitude error at the end (Young up, east, "
                           f"north), N=12: {np.array2string(a.attitude, precision=1)} rad, "
                           f"N=120: {np.array2string(b.attitude, precision=1)} rad")  # fmt: skip
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--duration", type=float, default=T_END, help="seconds (Table 3: 300)")
    ap.add_argument("--no-variants", action="store_true", help="skip the variants table")
    ap.add_argument("--no-phase", action="store_true", help="skip the initial-heading sweep")
    args = ap.parse_args()
    t0 = time.perf_counter()
    study = run_study(
        args.duration, variants=not args.no_variants, phase=not args.no_phase,
        progress=lambda m: print(f"[{time.perf_counter() - t0:6.1f} s] {m}", flush=True),
    )  # fmt: skip
    names = {s.name for s in SCHEMES}
    ends = {k[2]: r.t_end for k, r in study.results.items() if k[3] in names}
    print()
    print(f"Waldmann Table 3 rerun: RSS horizontal error (m) at the last T_nav output "
          f"(t = {ends['N=12']:.2f} s; T_nav/10: {ends['Tnav/10']:.2f} s)")  # fmt: skip
    if args.duration != T_END:
        print(f"NOTE: --duration {args.duration:g}: the paper's figures are for 300 s")
    print("IMU 1 m ahead of the CM; Table 1 radii; quaternion normalized; no vertical damping; "
          "Table 2 samples the first increment of each T_nav cycle")  # fmt: skip
    print()
    print(f"A. integrated IMU data (each increment the sum of a Method 2 pair at T_gyr/{SUM}):")
    print(format_main(study, "integrated"))
    print()
    print("B. exact streams at T_gyr (interface.md §3; strapdown-sim generate's /variation/imu):")
    print(format_main(study, "exact"))
    print()
    print(format_ratios(study))
    if not args.no_variants:
        print()
        print("Variants on A (one setting changed; RSS horizontal error, m):")
        print(format_variants(study))
    if not args.no_phase:
        print()
        print("Coning phase on A: initial heading (C_0 = Rz(heading)), RSS horizontal (m):")
        print(format_phase(study))
    for data, tag in (("integrated", "A"), ("exact", "B")):
        print()
        print(f"{tag}. error parts ({data}):")
        print(format_parts(study, data))
    print()
    print(f"generation {study.generation_s:.1f} s, total {time.perf_counter() - t0:.1f} s")
    mins = {}
    for data in DATA:
        n12 = [v for k, v in ratios(study, data).items() if k.startswith("paper/exact")]
        mins[data] = min(n12)
        print(f"exact_vs_paper_at_N12 ({data} data): {mins[data]:.3g} x")
    print(f"exact_vs_paper_at_N12: {min(mins.values()):.3g} x")


if __name__ == "__main__":
    main()
