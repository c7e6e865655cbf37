"""The transfer-alignment stage: slave IMU, master state and slave truth in, ``/transfer/*`` out.

:class:`TransferStage` runs :class:`~strapdown_ros.core.transfer.filter.TransferFilter` on
serialized batches (``feed_batches``, any chunking): the slave INS integrates the variation IMU
(``transfer_alignment.imu_topic``), the master is the reference truth Odometry with the errors
of ``transfer_alignment.master`` (white noise and bias on velocity and attitude, an output
latency), carried to the slave with the *nominal* lever arm and mounting (bending is motion the
filter does not model). Every ``1/rate_hz`` (an even cycle: Method 2's velocity constraint) the
filter propagates, applies velocity (and attitude) matching and publishes its state.

Epoch m is processed once the slave increments up to m, the master states up to
``m − latency + 1`` and the slave truth at m have arrived; the end is known from the plan
(the variation's last cycle), so ``generate`` needs no flush. Repeated and older slave IMU
messages are ignored; a missing slave IMU cycle or a non-finite input the filter would use
raises :class:`TransferInputError` (the slave INS cannot go on; the outputs up to then stand);
a missing master or truth message stalls the stage (outputs stop).

On a scanning platform (a ``sweep``, docs/transfer_alignment.md §5) the stage simulates the
slave's resolver: the platform's true angle from the offsets the variation stage used (the
scenario's :meth:`~strapdown_ros.core.offsets.OffsetModel.history`), plus the configured bias
and white noise; the filter's nominal ``C_Bs^Br`` is ``M̂ Ĉ_scan(θ̃)`` and the carried offset
``C_r (l̂ + M̂ Ĉ_scan d)``.

Initialization at cycle 0 from the master (docs/transfer_alignment.md §4): ``R̂ = R_r + C_r l̂``,
``V̂`` the one-sided difference the variation uses at its first cycle, ``Ĉ_s = C_r M̂`` with the
nominal mounting ``M̂ = exp([μ0×]) M``; so the initial attitude error is ``φ0 = C_r μ0`` (plus the
master's attitude error) and P0 carries that correlation.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from strapdown_ros.bag import cdr
from strapdown_ros.bag.batches import Batch, header_stamps_ns, subset
from strapdown_ros.config import Scenario
from strapdown_ros.config.base import required_section
from strapdown_ros.config.transfer import TransferAlignmentSpec
from strapdown_ros.core.aided.model import SensorModels, StateOptions, build_model
from strapdown_ros.core.aided.outputs import nees, reported
from strapdown_ros.core.earth import (
    OMEGA_IE_VEC,
    dcm_e0_to_ecef,
    dcm_ecef_to_ned,
    ecef_to_geodetic,
)
from strapdown_ros.core.imu_errors import ImuErrorModel, ImuErrorParameters
from strapdown_ros.core.navigation.errors import (
    attitude_error_young,
    position_error_ned,
    velocity_error_ned,
)
from strapdown_ros.core.offsets import OffsetModel, SweepScan
from strapdown_ros.core.rotations import dcm_from_rotvec, euler_from_dcm, rotvec_from_dcm, skew
from strapdown_ros.core.transfer.filter import Platform, TransferFilter, TransferLayout
from strapdown_ros.core.transfer.measurements import (
    carried_position,
    platform_offset,
    resolver_noise_attitude,
    resolver_noise_velocity,
    scan_angle,
    scan_dcm,
    start_velocity,
    transport_matrix,
)
from strapdown_ros.logs import Log, quiet
from strapdown_ros.messages import (
    imu_increments,
    odometry_fields_from_ecef,
    odometry_state,
    twist_covariance_flu,
    vector3_stamped_fields,
)
from strapdown_ros.plan.model import TopicPlan
from strapdown_ros.stages.aided import velocity_fields
from strapdown_ros.stages.intake import format_stamp

__all__ = [
    "FLOOR_ATTITUDE",
    "FLOOR_VELOCITY",
    "TransferInputError",
    "TransferStage",
    "transfer_input_topics",
    "transfer_topic_plans",
]

F64 = np.ndarray

#: Variance floors of the matching measurements: velocity (m/s)², attitude rad².
FLOOR_VELOCITY = 1e-14
FLOOR_ATTITUDE = 1e-16
#: σ floors of P0 for the position and velocity when their configured σ is 0 (m, m/s).
FLOOR_P0 = (1e-3, 1e-3)
#: Spawn keys of the draws: master errors, mounting error, initial errors, resolver noise.
STREAM_MASTER, STREAM_MOUNT, STREAM_INITIAL, STREAM_RESOLVER = 20, 21, 22, 23
_FLU = np.array([1.0, -1.0, -1.0])
#: Message type of each output key not a Vector3Stamped.
_MSGTYPES = {"odom": cdr.ODOMETRY, "vel": cdr.TWIST_WITH_COVARIANCE_STAMPED}


class TransferInputError(ValueError):
    """An input the slave INS cannot go on from: a missing slave IMU cycle, a non-finite value."""


def _require(scenario: Scenario) -> TransferAlignmentSpec:
    return required_section(scenario, "transfer_alignment")


def transfer_input_topics(scenario: Scenario) -> list[str]:
    """Slave IMU, master Odometry, slave truth."""
    spec = _require(scenario)
    return [spec.imu_topic, spec.master_topic, spec.truth_topic]


def _epochs(scenario: Scenario, last_cycle: int) -> tuple[int, int, int]:
    """(cycles per epoch P, latency cycles L, number of epochs) for cycles 0..last_cycle."""
    spec = _require(scenario)
    period = spec.period_ns // scenario.period_ns
    lat = int(round(spec.master.latency_s * 1e9 / scenario.period_ns))
    return period, lat, last_cycle // period + 1


def _measured_epochs(period: int, lat: int, count: int) -> int:
    """Epochs k ≥ 1 whose master sample ``kP − L`` is ≥ 1."""
    return sum(1 for k in range(1, count) if k * period - lat >= 1)


def transfer_topic_plans(scenario: Scenario, last_cycle: int,
                         link: str = "transfer_alignment") -> list[TopicPlan]:  # fmt: skip
    """The ``/transfer/*`` topics for slave cycles 0..``last_cycle`` (the chain's outputs)."""
    spec = _require(scenario)
    period, lat, count = _epochs(scenario, last_cycle)
    t0, tp = scenario.start_time_ns, spec.period_ns
    n_meas = _measured_epochs(period, lat, count)
    out = []
    for key, topic in spec.output_topics().items():
        if key == "nis":
            first = next(k for k in range(1, count) if k * period - lat >= 1) if n_meas else 0
            out.append(TopicPlan(topic, cdr.VECTOR3_STAMPED, n_meas, link, None,
                                 t0 + first * tp if n_meas else None,
                                 t0 + (count - 1) * tp if n_meas else None))  # fmt: skip
            continue
        msgtype = _MSGTYPES.get(key, cdr.VECTOR3_STAMPED)
        out.append(TopicPlan(topic, msgtype, count, link, None, t0, t0 + (count - 1) * tp))
    return out


def _to_e0(t_s: float, r_e: F64, v_e: F64, c_b_e: F64, w_eb: F64) -> tuple[F64, ...]:
    """(R, V, C_B^E0, ω_ib^B) in E0 of an Earth-referenced state at t (s since the start)."""
    ce0 = dcm_e0_to_ecef(t_s).T  # C_E^E0
    r = ce0 @ r_e
    v = ce0 @ (v_e + np.cross(OMEGA_IE_VEC, r_e))
    c = ce0 @ c_b_e
    w = w_eb + c_b_e.T @ OMEGA_IE_VEC
    return r, v, c, w


class TransferStage:
    """Transfer alignment on serialized messages (see the module docstring).

    Parameters
    ----------
    scenario : Scenario
        With an enabled ``transfer_alignment`` section; its ``variation`` a fixed mount or a
        sweeping platform (the scenario's rules).
    last_cycle : int
        Last cycle of the slave streams (the plan's variation cycles).
    """

    def __init__(self, scenario: Scenario, last_cycle: int, *, info: Log = quiet) -> None:
        self.scenario = sc = scenario
        self.spec = spec = _require(scenario)
        assert sc.variation is not None
        self.info = info
        self.t0, self.T = sc.start_time_ns, sc.period_ns
        self.Ts = self.T * 1e-9
        self.P, self.L, self.count = _epochs(sc, last_cycle)
        self.topics = spec.output_topics()
        self.earth_frame = sc.recording.frames["earth"]
        self.body_frame = sc.recording.frames["reference_imu"]
        om = sc.variation.offset_model()
        self.mount_true = om.mount
        self.lever_nominal = np.asarray(om.lever_arm, dtype=np.float64) + np.asarray(
            spec.lever_arm_error_m)  # fmt: skip
        self.lever_true = np.asarray(om.lever_arm, dtype=np.float64)
        self.displacement = np.asarray(om.displacement, dtype=np.float64)
        #: a platform: a scan or a displacement on it (docs/transfer_alignment.md §5)
        self.platform = om.scan is not None or bool(np.any(self.displacement != 0.0))
        self.scan_axis = np.zeros(3)
        self.resolver: F64 | None = None  # θ̃ at cycles 0..last_cycle + 1 (rad)
        self.resolver_sigma = 0.0  # σ of the reading noise (rad)
        if om.scan is not None:
            self._simulate_resolver(om, last_cycle)
        # the slave IMU's error model (the filter's matched Q and P0 of the biases)
        params = ImuErrorParameters.perfect()
        slave_errors = sc.imu_errors_of(spec.imu_topic)
        if slave_errors is not None:
            params = slave_errors.parameters()
        model = build_model(params, self.Ts, SensorModels(), StateOptions(None, None, False))
        self.layout = TransferLayout(model, spec.lever_arm_state)
        self.rate_variance = ImuErrorModel(params, self.Ts).rate_noise_variance()[0]
        # draws
        def rng(stream: int, seed: int) -> np.random.Generator:
            return np.random.Generator(np.random.PCG64(np.random.SeedSequence(
                seed, spawn_key=(stream,))))  # fmt: skip

        ms = spec.master
        self._rng_master = rng(STREAM_MASTER, ms.seed)
        self.v_bias_ned = self._rng_master.standard_normal(3) * ms.velocity_bias_mps
        self.a_bias = self._rng_master.standard_normal(3) * np.radians(ms.attitude_bias_deg)
        sig_mu = np.radians(spec.mounting_sigma_deg)
        if spec.mounting_error_deg is None:
            self.mu0 = rng(STREAM_MOUNT, spec.seed).standard_normal(3) * sig_mu
        else:
            self.mu0 = np.radians(np.asarray(spec.mounting_error_deg, dtype=np.float64))
        self.mount_nominal = dcm_from_rotvec(self.mu0) @ self.mount_true
        self._rng_initial = rng(STREAM_INITIAL, spec.seed)
        # buffers
        self._da: list[F64] = []
        self._dv: list[F64] = []
        self._imu_last = 0  # last slave cycle buffered
        self._imu_used = 0  # last slave cycle given to the filter
        self._master: dict[int, tuple[F64, ...]] = {}
        self._master_last = -1
        self._truth: dict[int, tuple[F64, F64, F64]] = {}
        self.filter: TransferFilter | None = None
        self.k = 0  # next epoch index
        self._rows: list[dict[str, Any]] = []
        self._nis: list[tuple[int, float, float]] = []
        self.published = dict.fromkeys(self.topics.values(), 0)
        self.rejections = 0
        #: Why the stage stopped taking input (None: it has not).
        self.error: str | None = None
        self._bad_topic: str | None = None

    def _simulate_resolver(self, om: OffsetModel, last_cycle: int) -> None:
        """The resolver's readings ``θ̃ = θ + b + n`` at cycles 0..last_cycle + 1.

        θ: the platform's true angle, from the offsets the variation stage used
        (:meth:`~strapdown_ros.core.offsets.OffsetModel.history`: ``C_mount C_scan`` smoothed
        by Appendix D) by :func:`scan_angle`; b the configured bias, n white (σ, seed)."""
        if not isinstance(om.scan, SweepScan):  # refused by the scenario's rules
            raise ValueError("transfer_alignment: only a sweep scan has a resolver model")
        self.scan_axis = np.asarray(om.scan.axis, dtype=np.float64)
        hist = om.history(self.Ts, last_cycle + 1)
        theta = scan_angle(hist.c_bvar_bref, om.mount, self.scan_axis)
        rs = self.spec.resolver
        gen = np.random.Generator(np.random.PCG64(np.random.SeedSequence(
            rs.seed, spawn_key=(STREAM_RESOLVER,))))  # fmt: skip
        noise = gen.standard_normal(theta.size) * np.radians(rs.noise_deg)
        self.resolver = theta + np.radians(rs.bias_deg) + noise
        self.resolver_sigma = float(np.radians(rs.noise_deg))

    def _scan(self, m: int) -> F64:
        """``Ĉ_scan`` at slave cycle m from the resolver's reading (identity without a scan)."""
        if self.resolver is None:
            return np.eye(3)
        return scan_dcm(self.scan_axis, float(self.resolver[m]))

    # -- which master cycles are needed ---------------------------------------------------------

    def _needed_master(self, m: int) -> bool:
        if m <= 2:
            return True
        j = (m + self.L) % self.P  # m = kP - L + d, d in {-1, 0, 1}
        return j in (0, 1, self.P - 1)

    # -- input -----------------------------------------------------------------------------------

    def feed_batches(self, batches: Sequence[Batch]) -> list[Batch]:
        """Serialized batches in; the ``/transfer/*`` batches of the epochs now complete out.

        After a bad input (:attr:`error` set: a missing slave IMU cycle, a non-finite value)
        the inputs before it are still used, and so are the other topics', but that topic's
        later input is ignored: no epoch after the bad input completes."""
        for b in batches:
            if not len(b.payloads) or b.topic == self._bad_topic:
                continue
            try:
                if b.topic == self.spec.imu_topic:
                    self._read_imu(b)
                elif b.topic in (self.spec.master_topic, self.spec.truth_topic):
                    self._read_odometry(b, b.topic == self.spec.master_topic)
            except TransferInputError as exc:
                if self.error is None:
                    self.error, self._bad_topic = str(exc), b.topic
        self._process()
        return self._serialize()

    def _read_imu(self, b: Batch) -> None:
        inc = imu_increments(cdr.deserialize(cdr.IMU, list(b.payloads)), self.T)
        stamps = np.asarray(inc.stamps_ns, dtype=np.int64)
        cyc = (stamps - self.t0) // self.T
        seen = np.maximum.accumulate(np.concatenate([[self._imu_last], cyc[:-1]]))
        keep = cyc > seen  # repeated and older than one already taken: ignored
        stamps = stamps[keep]
        da, dv = np.asarray(inc.dalpha)[keep], np.asarray(inc.dv)[keep]
        want = self._imu_last + 1 + np.arange(len(stamps))
        gap = (stamps - self.t0) // self.T != want
        bad = gap | ~np.isfinite(da).all(axis=1) | ~np.isfinite(dv).all(axis=1)
        n = int(np.argmax(bad)) if bad.any() else len(stamps)
        if n:
            self._da.append(da[:n])
            self._dv.append(dv[:n])
            self._imu_last = int(want[n - 1])
        if n < len(stamps):
            at = format_stamp(self.t0 + int(want[n]) * self.T)
            raise TransferInputError(
                f"{b.topic}: slave IMU cycle {int(want[n])} (stamp {at}) missing, the next "
                f"is {format_stamp(int(stamps[n]))}; the transfer filter stops" if gap[n] else
                f"{b.topic}: stamp {at}: NaN or infinity; the transfer filter stops")  # fmt: skip

    def _read_odometry(self, b: Batch, master: bool) -> None:
        """Master states around the epochs, truth at the epochs; ``_master_last``: the latest
        master cycle received (the ones not needed count too)."""
        last = int((int(np.max(b.stamps_ns)) - self.t0) // self.T)
        b = self._needed(b, master)
        if len(b.payloads):
            st = odometry_state(cdr.deserialize(cdr.ODOMETRY, list(b.payloads)))
            stamps = np.asarray(st.stamps_ns, dtype=np.int64)
            rows = np.concatenate([st.r_e, st.v_e, st.omega_eb_b, st.c_b_e.reshape(-1, 9)], axis=1)
            bad = ~np.isfinite(rows).all(axis=1)
            n = int(np.argmax(bad)) if bad.any() else len(stamps)
            for i, m in enumerate(((stamps[:n] - self.t0) // self.T).tolist()):
                if master and self._needed_master(m):
                    self._master[m] = _to_e0(m * self.Ts, st.r_e[i], st.v_e[i], st.c_b_e[i],
                                             st.omega_eb_b[i])  # fmt: skip
                elif not master and m % self.P == 0:
                    self._truth[m] = (st.r_e[i], st.v_e[i], st.c_b_e[i])
            if n < len(stamps):
                if master:
                    self._master_last = max(self._master_last, int(
                        (int(stamps[n]) - self.t0) // self.T) - 1)  # fmt: skip
                raise TransferInputError(f"{b.topic}: stamp {format_stamp(int(stamps[n]))}: "
                                         "NaN or infinity; the transfer filter stops")  # fmt: skip
        if master:
            self._master_last = max(self._master_last, last)

    def _needed(self, b: Batch, master: bool) -> Batch:
        """The messages of an Odometry batch the filter uses, by their header stamps (read
        from the CDR bytes, as the aided stage does): master cycles around the epochs, truth
        at the epochs."""
        t = header_stamps_ns(b)
        if t is None:
            return b
        m = (t - self.t0) // self.T
        if master:
            j = (m + self.L) % self.P
            need = (m <= 2) | (j == 0) | (j == 1) | (j == self.P - 1)
        else:
            need = m % self.P == 0
        return subset(b, need)

    # -- processing ------------------------------------------------------------------------------

    def _ready(self, m: int) -> bool:
        return (self._imu_last >= m and self._master_last >= max(m - self.L + 1, 2)
                and m in self._truth)  # fmt: skip

    def _process(self) -> None:
        while self.k < self.count and self._ready(self.k * self.P):
            m = self.k * self.P
            if self.filter is None:
                self._start()
            else:
                self._step(m)
            self._record(m)
            self.k += 1

    def _take_imu(self, upto: int) -> tuple[F64, F64]:
        da = np.concatenate(self._da) if len(self._da) > 1 else self._da[0]
        dv = np.concatenate(self._dv) if len(self._dv) > 1 else self._dv[0]
        k = upto - self._imu_used
        self._da, self._dv = ([da[k:]], [dv[k:]]) if k < len(da) else ([], [])
        self._imu_used = upto
        return da[:k], dv[:k]

    def _master_at(self, j: int) -> tuple[F64, F64, F64, F64, F64, F64]:
        """Master sample j as received: (V, C_prev, C, C_next, ω_ib, R_v) with its errors."""
        ms = self.spec.master
        _, v, c, w = self._master[j]
        c_prev = self._master[j - 1][2] if j >= 1 else c
        c_next = self._master[j + 1][2]
        rng = self._rng_master
        # attitude error (rotation about the master's body axes), the same on the three samples
        eps = self.a_bias + rng.standard_normal(3) * np.radians(ms.attitude_noise_deg)
        err = dcm_from_rotvec(eps)
        # velocity error in NED at the master's position
        r_e = dcm_e0_to_ecef(j * self.Ts) @ self._master[j][0]
        lat, lon, _ = ecef_to_geodetic(r_e)
        cne0 = dcm_e0_to_ecef(j * self.Ts).T @ dcm_ecef_to_ned(lat, lon).T  # C_N^E0
        dv_ned = self.v_bias_ned + rng.standard_normal(3) * ms.velocity_noise_mps
        return (v + cne0 @ dv_ned, c_prev @ err, c @ err, c_next @ err, w, cne0)

    def _r_velocity(self, cne0: F64) -> F64:
        ms, tu = self.spec.master, self.spec.tuning
        r = cne0 @ np.diag(np.full(3, ms.velocity_noise_mps**2)) @ cne0.T
        return r + np.eye(3) * (tu.velocity_sigma_mps**2 + FLOOR_VELOCITY)

    def _r_attitude(self, c: F64) -> F64:
        ms, tu = self.spec.master, self.spec.tuning
        s2 = np.radians(ms.attitude_noise_deg) ** 2
        return np.eye(3) * (s2 + np.radians(tu.attitude_sigma_deg) ** 2 + FLOOR_ATTITUDE)

    def _start(self) -> None:
        spec, lay = self.spec, self.layout
        r, v, c, w = self._master[0]
        c0 = self._master_at(0)[2]  # the master's attitude as received (its error applied)
        c1, c2 = self._master[1][2], self._master[2][2]
        lever = self.lever_nominal
        s_p = spec.initial_sigma_position_m
        s_v = spec.initial_sigma_velocity_mps
        e = self._rng_initial.standard_normal(6)
        scans = [self._scan(j) for j in range(3)]
        w3 = [platform_offset(self.mount_nominal, cs, self.displacement) for cs in scans]
        if self.platform:  # S_j = C_r,j (l̂ + M̂ Ĉ_scan,j d) (eq. (7))
            r0 = carried_position(r, c, lever + w3[0]) + e[:3] * s_p
            v0 = start_velocity(c, c1, c2, v, lever, self.Ts, (w3[0], w3[1], w3[2]))
            d0 = (-3.0 * c + 4.0 * c1 - c2) / (2.0 * self.Ts)
        elif spec.velocity_transport == "central_difference":
            r0 = carried_position(r, c, lever) + e[:3] * s_p
            v0 = start_velocity(c, c1, c2, v, lever, self.Ts)
            d0 = (-3.0 * c + 4.0 * c1 - c2) / (2.0 * self.Ts)
        else:
            r0 = carried_position(r, c, lever) + e[:3] * s_p
            d0 = transport_matrix("rate", c, c, c, w, self.Ts)
            v0 = v + d0 @ lever
        v0 = v0 + e[3:] * s_v
        chat = c0 @ self.mount_nominal
        if self.platform:
            chat = chat @ scans[0]
        # P0 = A Σ Aᵀ: independent parts, then the correlations of the start from the master
        n = lay.n
        sig = np.zeros(n)
        # the start from the master carries the unmodelled motion too (tuning σ, e.g. bending)
        tune = spec.tuning.velocity_sigma_mps
        sig[0:3] = s_p if s_p > 0 else FLOOR_P0[0]
        sig[3:6] = np.hypot(s_v, tune) if (s_v > 0 or tune > 0) else FLOOR_P0[1]
        sig[6:9] = np.sqrt(np.radians(spec.master.attitude_noise_deg) ** 2
                           + np.radians(spec.master.attitude_bias_deg) ** 2 + FLOOR_ATTITUDE)
        sig[9 : lay.n_aided] = lay.model.sigma0[9:]
        sig[lay.i_mu : lay.i_mu + 3] = np.radians(spec.mounting_sigma_deg)
        a = np.eye(n)
        a[6:9, lay.i_mu : lay.i_mu + 3] = c
        if self.platform:  # ∂S_j/∂μ = −C_r,j [w_j×]
            ds = [-cj @ skew(wj) for cj, wj in zip((c, c1, c2), w3, strict=True)]
            a[0:3, lay.i_mu : lay.i_mu + 3] = ds[0]
            a[3:6, lay.i_mu : lay.i_mu + 3] = (-3.0 * ds[0] + 4.0 * ds[1] - ds[2]) / (2 * self.Ts)
        if lay.i_l >= 0:
            sig[lay.i_l : lay.i_l + 3] = spec.lever_arm_sigma_m
            a[0:3, lay.i_l : lay.i_l + 3] = c
            a[3:6, lay.i_l : lay.i_l + 3] = d0
        p0 = a @ np.diag(sig**2) @ a.T
        if self.resolver is not None and self.resolver_sigma > 0.0:
            p0 += self._resolver_p0(n, (c, c1, c2), scans)
        q_mu = spec.tuning.mounting_random_walk**2
        self.filter = TransferFilter(lay, self.T, str(self.scenario.gravity_model), r0, v0,
                                     chat, self.mount_nominal, lever, 0.5 * (p0 + p0.T),
                                     q_mu, spec.attitude_jacobian)  # fmt: skip
        self.info(f"transfer_alignment: slave INS starts at cycle 0 ({n} states)")

    def _resolver_p0(self, n: int, cr: tuple[F64, F64, F64], scans: list[F64]) -> F64:
        """P0's part from the resolver noise of readings 0, 1, 2 (σ² G Gᵀ): the start carries
        ``g_j ε_j`` (``g_j = C_r,j M̂ Ĉ_scan,j (a × d)``) into R̂ (j = 0) and V̂ (the one-sided
        difference) and ``C_r M̂ a ε_0`` into the slave's attitude."""
        ad = np.cross(self.scan_axis, self.displacement)
        mh = self.mount_nominal
        g = [cj @ (mh @ (cs @ ad)) for cj, cs in zip(cr, scans, strict=True)]
        big = np.zeros((n, 3))
        big[0:3, 0] = g[0]
        big[3:6] = np.column_stack([-3.0 * g[0], 4.0 * g[1], -g[2]]) / (2.0 * self.Ts)
        big[6:9, 0] = cr[0] @ (mh @ self.scan_axis)
        return self.resolver_sigma**2 * (big @ big.T)

    def _step(self, m: int) -> None:
        f = self.filter
        assert f is not None
        da, dv = self._take_imu(m)
        f.propagate(da, dv)
        j = m - self.L
        if j < 1:
            return
        v, c_prev, c, c_next, w, cne0 = self._master_at(j)
        d = transport_matrix(self.spec.velocity_transport, c_prev, c, c_next, w, self.Ts)
        gate = np.inf
        if self.spec.gate_probability < 1.0:
            from scipy.stats import chi2

            gate = float(chi2.ppf(self.spec.gate_probability, 3))
        r_v = self._r_velocity(cne0)
        plat = None
        if self.platform:
            plat = Platform(c_prev, c_next, self._scan(m - 1), self._scan(m + 1), self.displacement)
            if self.resolver is not None and self.resolver_sigma > 0.0:
                r_v = r_v + resolver_noise_velocity(c_prev, c_next, f.mount, plat.scan_prev,
                                                    plat.scan_next, self.scan_axis,
                                                    self.displacement, self.resolver_sigma,
                                                    self.Ts)  # fmt: skip
        rv = f.update_velocity(v, d, r_v, gate, plat)
        nis_a = 0.0
        if "attitude" in self.spec.measurements:
            r_a = self._r_attitude(c)
            if self.resolver is not None and self.resolver_sigma > 0.0:
                r_a = r_a + resolver_noise_attitude(c, f.mount, self.scan_axis,
                                                    self.resolver_sigma)  # fmt: skip
            ra = f.update_attitude(c, r_a, gate, self._scan(m) if self.platform else None)
            nis_a = ra.nis
            self.rejections += not ra.accepted
        self.rejections += not rv.accepted
        self._nis.append((m, rv.nis, nis_a))
        for old in [q for q in self._master if q < j - 1]:
            del self._master[old]

    def _record(self, m: int) -> None:
        f = self.filter
        assert f is not None
        self._rows.append({"m": m, "nav": f.nav.copy(), "est": f.est.copy(), "p": f.p.copy(),
                           "mount": f.mount.copy(), "lever": f.lever.copy(),
                           "truth": self._truth.pop(m)})  # fmt: skip

    # -- output ----------------------------------------------------------------------------------

    def _serialize(self) -> list[Batch]:
        out: list[Batch] = []
        if self._rows:
            out += [self._batch(k, v) for k, v in self._state_fields(self._rows).items()]
            self._rows = []
        if self._nis:
            arr = np.array(self._nis)
            stamps = self.t0 + arr[:, 0].astype(np.int64) * self.T
            v = np.column_stack([arr[:, 1], arr[:, 2], np.zeros(len(arr))])
            out.append(self._batch("nis", vector3_stamped_fields(stamps, v, "nis")))
            self._nis = []
        for b in out:
            self.published[b.topic] += len(b.payloads)
        return out

    def _batch(self, key: str, fields: Any) -> Batch:
        stamps = np.asarray(fields.stamps_ns, dtype=np.int64)
        return Batch(self.topics[key], cdr.msgtype_of(fields), stamps, cdr.serialize(fields))

    def _state_fields(self, rows: list[dict[str, Any]]) -> dict[str, Any]:
        lay = self.layout
        na = lay.n_aided
        m = np.array([r["m"] for r in rows], dtype=np.int64)
        nav = np.array([r["nav"] for r in rows])
        est = np.array([r["est"] for r in rows])
        p = np.array([r["p"] for r in rows])
        stamps = self.t0 + m * self.T
        t = (m * self.T) * 1e-9
        rep = reported(t, nav, est[:, :na], p[:, :na, :na], lay.model.layout, self.Ts,
                       self.rate_variance)  # fmt: skip
        k = len(m)
        twist = twist_covariance_flu(rep.twist_cov_frd)
        out: dict[str, Any] = {"odom": odometry_fields_from_ecef(
            stamps, rep.r_e, rep.v_e, rep.c_b_e, rep.omega_eb_b, self.spec.frame_id,
            self.earth_frame, pose_covariance=rep.pose_cov.reshape(k, 36),
            twist_covariance=twist.reshape(k, 36))}  # fmt: skip
        out["vel"] = velocity_fields(stamps, self.spec.frame_id, rep)  # as /aided/vel
        r_true = np.array([r["truth"][0] for r in rows])
        v_true = np.array([r["truth"][1] for r in rows])
        c_true = np.array([r["truth"][2] for r in rows])
        lat, lon, _ = ecef_to_geodetic(r_true)
        c_true_en = dcm_ecef_to_ned(lat, lon).reshape(-1, 3, 3)
        cen = dcm_ecef_to_ned(rep.lat, rep.lon).reshape(k, 3, 3)
        dr = position_error_ned(rep.r_e, r_true, lat, lon)
        dv = velocity_error_ned(rep.v_ned, np.einsum("kij,kj->ki", c_true_en, v_true))
        da = attitude_error_young(cen @ rep.c_b_e, c_true_en @ c_true)
        nees_v = np.stack([nees(dr, rep.pos_cov_ned), nees(dv, rep.vel_cov_ned),
                           nees(da, rep.att_cov_young)], axis=-1)  # fmt: skip
        out["error_position"] = vector3_stamped_fields(stamps, dr, "ned")
        out["error_velocity"] = vector3_stamped_fields(stamps, dv, "ned")
        out["error_attitude"] = vector3_stamped_fields(stamps, da, "young_uen")
        out["nees"] = vector3_stamped_fields(stamps, nees_v, "nees")
        mount = np.array([r["mount"] for r in rows])
        roll, pitch, yaw = euler_from_dcm(mount)
        out["mounting"] = vector3_stamped_fields(stamps, np.stack([roll, pitch, yaw], -1), "rph")
        mu_err = rotvec_from_dcm(mount @ self.mount_true.T)  # Br FRD
        i = lay.i_mu
        p_mu = p[:, i : i + 3, i : i + 3]
        out["mounting_error"] = vector3_stamped_fields(stamps, mu_err * _FLU, self.body_frame)
        out["mounting_sigma"] = vector3_stamped_fields(
            stamps, np.sqrt(np.diagonal(p_mu, axis1=1, axis2=2)), self.body_frame)
        nz = mu_err[:, 2] ** 2 / p_mu[:, 2, 2]
        out["mounting_nees"] = vector3_stamped_fields(
            stamps, np.column_stack([nees(mu_err, p_mu), nz, np.zeros(k)]), "nees")
        if lay.i_l >= 0:
            lever = np.array([r["lever"] for r in rows])
            out["lever_arm_error"] = vector3_stamped_fields(
                stamps, (lever - self.lever_true) * _FLU, self.body_frame)
        return out
