"""Navigation (docs/model.md, "Navigation"): the laws fly the estimate of a filter fed by the
vehicle's own sensors.

The filter is checked against one written here from its equations in numpy, over the samples
the engine's sensors gave it (the flight's record); its consistency by the normalised
estimation error squared over many realisations; the sensors' noise by its statistics; and
``"truth"`` by the paper's bits.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from scipy import stats

import quadrs

# Every sensor key given (the filter below reads them), some away from their defaults.
SENSORS: dict[str, Any] = {
    "navigation.mode": "ekf",
    "navigation.rate": 100.0,
    "navigation.attitude_error": [0.01, 0.01, 0.05],
    "sensors.imu.rate": 200.0,
    "sensors.imu.gyro_noise": 1.5e-3,
    "sensors.imu.accel_noise": 3.5e-2,
    "sensors.imu.gyro_bias_walk": 1e-4,
    "sensors.imu.accel_bias_walk": 3e-4,
    "sensors.imu.gyro_bias": 5e-3,
    "sensors.imu.accel_bias": 5e-2,
    "sensors.gnss.rate": 5.0,
    "sensors.gnss.delay": 0.11,
    "sensors.gnss.position_noise": [0.5, 0.5, 0.75],
    "sensors.gnss.velocity_noise": 0.3,
    "sensors.gnss.drift": 0.5,
    "sensors.gnss.drift_time": 60.0,
    "sensors.baro.rate": 50.0,
    "sensors.baro.noise": 1.0,
    "sensors.baro.drift": 1.0,
    "sensors.baro.drift_time": 300.0,
    "sensors.heading.rate": 10.0,
    "sensors.heading.noise": 0.3,
}


def flight_scenario(route: list[list[float]], hold: list[float], names: list[str],
                    duration: float, **more: Any) -> quadrs.Scenario:  # fmt: skip
    """The delivery vehicle (rigid body, rotors, parcel on a line) in still air on ``route``,
    flying on its senses, at a 1 ms step (the IMU at 200 Hz every 5 steps)."""
    return quadrs.Scenario.preset("delivery").override({
        **SENSORS, "integrator.dt": 0.001, "gust.enabled": False, "wind.speed": 0.0,
        "trajectory.route": route,
        "trajectory.speed": 3.0, "trajectory.hold": hold, "trajectory.lower": [0.0] * len(hold),
        "trajectory.names": names, "integrator.duration": duration, **more,
    })  # fmt: skip


def hover_scenario(**more: Any) -> quadrs.Scenario:
    """A climb from 2 m to 5 m, then a hover."""
    more.setdefault("integrator.duration", 12.0)
    duration = more.pop("integrator.duration")
    hold = [1.0, duration - 6.0]
    return flight_scenario([[0.0, 0.0, 2.0], [0.0, 0.0, 5.0]], hold, ["lift", "climb", "hover"],
                           duration, **more)  # fmt: skip


def leg_scenario(**more: Any) -> quadrs.Scenario:
    """The climb, then a 12 m leg at 3 m/s, then a hover."""
    route = [[0.0, 0.0, 2.0], [0.0, 0.0, 5.0], [12.0, 0.0, 5.0]]
    names = ["lift", "climb", "wait", "leg", "hover"]
    return flight_scenario(route, [1.0, 3.0, 3.0], names, 22.0, **more)


# --- the filter written here ---------------------------------------------------------------


def quat_mult(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, v1 = a[0], a[1:]
    w2, v2 = b[0], b[1:]
    return np.concatenate([[w1 * w2 - v1 @ v2], w1 * v2 + w2 * v1 + np.cross(v1, v2)])


def rot(q: np.ndarray) -> np.ndarray:
    """Body-to-world rotation of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip


def skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def wrap(a: float) -> float:
    return float((a + math.pi) % (2 * math.pi) - math.pi) if a != math.pi else a


class Filter:
    """The error-state EKF of docs/model.md, "Navigation", as matrices."""

    def __init__(self, s: quadrs.Scenario, initial: np.ndarray) -> None:
        def key(name: str, sensor: str) -> Any:
            v = s.get(f"navigation.{name}")
            return s[sensor] if v is None else v

        dt = float(s["integrator.dt"])
        self.dt = dt
        steps = lambda rate: max(1, round(1 / (rate * dt))) if rate else 1  # noqa: E731
        self.mi = steps(float(s["sensors.imu.rate"]))
        self.mf = steps(float(s["navigation.rate"]))
        self.mg = steps(float(s["sensors.gnss.rate"]))
        self.mb = steps(float(s["sensors.baro.rate"]))
        self.mh = steps(float(s["sensors.heading.rate"]))
        self.delay = round(float(s["sensors.gnss.delay"]) / dt)
        self.g = float(s["environment.gravity"])
        gn = key("gyro_noise", "sensors.imu.gyro_noise")
        an = key("accel_noise", "sensors.imu.accel_noise")
        gw = key("gyro_bias_walk", "sensors.imu.gyro_bias_walk")
        aw = key("accel_bias_walk", "sensors.imu.accel_bias_walk")
        gb = key("gyro_bias", "sensors.imu.gyro_bias")
        ab = key("accel_bias", "sensors.imu.accel_bias")
        pn = np.asarray(key("position_noise", "sensors.gnss.position_noise"), float)
        vn = key("velocity_noise", "sensors.gnss.velocity_noise")
        dr = key("drift", "sensors.gnss.drift")
        dtau = key("drift_time", "sensors.gnss.drift_time")
        bn = key("baro_noise", "sensors.baro.noise")
        bd = key("baro_drift", "sensors.baro.drift")
        btau = key("baro_drift_time", "sensors.baro.drift_time")
        hn = key("heading_noise", "sensors.heading.noise")
        att = np.asarray(s["navigation.attitude_error"], float)
        period = self.mf * dt
        self.ae, self.ab = math.exp(-period / dtau), math.exp(-period / btau)
        self.q_diag = np.concatenate([
            np.zeros(3), np.full(3, an**2 * period), np.full(3, gn**2 * period),
            np.full(3, gw**2 * period), np.full(3, aw**2 * period),
            np.full(3, (1 - self.ae**2) * dr**2), [(1 - self.ab**2) * bd**2],
        ])  # fmt: skip
        self.r_pos, self.r_vel, self.r_baro, self.r_head = pn**2, vn**2, bn**2, hn**2
        sd = np.concatenate([pn, np.full(3, vn), att, np.full(3, gb), np.full(3, ab),
                             np.full(3, dr), [bd]])  # fmt: skip
        height = s.get("navigation.height_error")  # the filter's height at the start
        sd[2] = pn[2] if height is None else height
        self.P = np.diag(sd**2)
        self.p, self.v, self.q = initial[:3].copy(), initial[3:6].copy(), initial[6:10].copy()
        self.bg, self.ba, self.e, self.beta = np.zeros(3), np.zeros(3), np.zeros(3), 0.0
        self.sum_r, self.sum_dv = np.zeros((3, 3)), np.zeros(3)
        self.window = [np.zeros(6) for _ in range(self.delay // self.mf)]
        self.mark = np.concatenate([self.p, self.v])

    def propagate(self, gyro: np.ndarray, accel: np.ndarray) -> None:
        h = self.mi * self.dt
        r = rot(self.q)
        fw = r @ (accel - self.ba)
        a = fw - np.array([0, 0, self.g])
        self.p = self.p + self.v * h + a * h * h / 2
        self.v = self.v + a * h
        self.sum_dv += fw * h
        self.sum_r += r * h
        w = (gyro - self.bg) * h
        n2 = w @ w
        d = np.concatenate([[1 - n2 / 8], w * (1 - n2 / 24) / 2])
        q = quat_mult(self.q, d)
        self.q = q / np.linalg.norm(q)

    def predict(self) -> None:
        dt = self.mf * self.dt
        F = np.eye(19)
        F[0:3, 3:6] = dt * np.eye(3)
        F[3:6, 6:9] = -skew(self.sum_dv)
        F[3:6, 12:15] = -self.sum_r
        F[6:9, 9:12] = -self.sum_r
        F[15:18, 15:18] *= self.ae
        F[18, 18] = self.ab
        self.P = F @ self.P @ F.T + np.diag(self.q_diag)
        self.e, self.beta = self.e * self.ae, self.beta * self.ab
        self.sum_r, self.sum_dv = np.zeros((3, 3)), np.zeros(3)
        if self.window:
            now = np.concatenate([self.p, self.v])
            self.window = [*self.window[1:], now - self.mark]

    def fuse(self, h: np.ndarray, y: float, r: float, on: float = 1.0) -> None:
        ph = self.P @ h
        k = ph * (on / (h @ ph + r))
        self.P = self.P - np.outer(k, ph)
        dx = k * y
        self.p, self.v = self.p + dx[0:3], self.v + dx[3:6]
        self.bg, self.ba, self.e = self.bg + dx[9:12], self.ba + dx[12:15], self.e + dx[15:18]
        self.beta += dx[18]
        q = quat_mult(np.concatenate([[1.0], dx[6:9] / 2]), self.q)
        self.q = q / np.linalg.norm(q)

    def fuse_gnss(self, z: np.ndarray, on: float) -> None:
        back = np.sum(self.window, axis=0) if self.window else np.zeros(6)
        tau = self.delay * self.dt
        for i in range(3):
            h = np.zeros(19)
            h[i], h[3 + i], h[15 + i] = 1.0, -tau, 1.0
            y = (z[i] - (self.p[i] - back[i] + self.e[i])) * on
            self.fuse(h, y, self.r_pos[i], on)
        for i in range(3):
            h = np.zeros(19)
            h[3 + i] = 1.0
            self.fuse(h, (z[3 + i] - (self.v[i] - back[3 + i])) * on, self.r_vel, on)

    def fuse_baro(self, z: float) -> None:
        h = np.zeros(19)
        h[2] = h[18] = 1.0
        self.fuse(h, z - (self.p[2] + self.beta), self.r_baro)

    def fuse_heading(self, z: float) -> None:
        c0 = rot(self.q)[:, 0]
        n = c0[0] ** 2 + c0[1] ** 2
        h = np.zeros(19)
        h[6:9] = [-c0[0] * c0[2] / n, -c0[1] * c0[2] / n, 1.0]
        self.fuse(h, wrap(z - math.atan2(c0[1], c0[0])), self.r_head)

    def euler(self) -> np.ndarray:
        r = rot(self.q)
        return np.array([
            math.atan2(r[2, 1], r[2, 2]), math.asin(-np.clip(r[2, 0], -1, 1)),
            math.atan2(r[1, 0], r[0, 0]),
        ])  # fmt: skip

    def replay(self, record: dict[str, np.ndarray], steps: int) -> dict[float, np.ndarray]:
        """Run over the record's samples; the estimate and its sigmas at every step."""
        imu = iter(record["imu"])
        gnss, baro, head = iter(record["gnss"]), iter(record["baro"]), iter(record["heading"])
        out = {}
        for k in range(steps + 1):
            if k > 0 and k % self.mi == 0:
                row = next(imu)
                assert abs(row[0] - k * self.dt) < 1e-9
                self.propagate(row[1:4], row[4:7])
            if k % self.mf == 0:
                if k > 0:
                    self.predict()
                if k >= self.delay and (k - self.delay) % self.mg == 0:
                    row = next(gnss)
                    self.fuse_gnss(row[1:7], row[7])
                if k % self.mb == 0:
                    self.fuse_baro(next(baro)[1])
                if k % self.mh == 0:
                    self.fuse_heading(next(head)[1])
                self.mark = np.concatenate([self.p, self.v])
            sd = np.sqrt(np.diag(self.P))
            out[round(k * self.dt, 9)] = np.concatenate([self.p, self.v, self.euler(), sd[:9]])
        return out


EST = ["x_est", "y_est", "z_est", "vx_est", "vy_est", "vz_est", "phi_est", "theta_est",
       "psi_est", "x_std", "y_std", "z_std", "vx_std", "vy_std", "vz_std", "phi_std",
       "theta_std", "psi_std"]  # fmt: skip


@pytest.mark.parametrize("outage", [False, True])
def test_the_engines_filter_is_the_filter_of_its_equations(outage: bool) -> None:
    changes: dict[str, Any] = {}
    if outage:
        changes["sensors.gnss.outages"] = [{"start": 8.0, "duration": 4.0}]
    s = leg_scenario(**changes, **{"navigation.accel_noise": 0.05})
    f = quadrs.simulate(s, "pd", seed=3)
    rec = f.navigation
    assert rec is not None
    ref = Filter(s, rec["initial"])
    steps = round(float(s["integrator.duration"]) / float(s["integrator.dt"]))
    want = ref.replay(rec, steps)
    got = f.trace[EST]
    assert set(got.columns) == set(EST)
    worst = 0.0
    for t, row in zip(got.index, got.to_numpy(), strict=True):
        w = want[round(t, 9)]
        d = np.abs(row - w)
        d[6:9] = np.abs((row[6:9] - w[6:9] + math.pi) % (2 * math.pi) - math.pi)
        worst = max(worst, float(np.max(d / np.maximum(1.0, np.abs(w)))))
    assert worst < 1e-9, worst
    state = np.concatenate([ref.p, ref.v, ref.q, ref.bg, ref.ba, ref.e, [ref.beta]])
    np.testing.assert_allclose(rec["state"], state, rtol=1e-9, atol=1e-9)
    cov = rec["covariance"].reshape(19, 19)
    np.testing.assert_allclose(cov, ref.P, rtol=1e-9, atol=1e-12)
    if outage:
        # The fixes inside the outage were not received, and the filter coasted.
        received = rec["gnss"][:, 7]
        t_fix = rec["gnss"][:, 0] - float(s["sensors.gnss.delay"])
        inside = (t_fix >= 8.0 - 1e-9) & (t_fix < 12.0 - 1e-9)
        assert inside.any() and not received[inside].any() and received[~inside].all()


def test_the_laws_read_the_estimate_and_the_metrics_the_truth() -> None:
    s = hover_scenario()
    f = quadrs.simulate(s, "pd", seed=1)
    tr = f.trace
    err = np.hypot(tr["x_est"] - tr["x"], tr["y_est"] - tr["y"])
    flight = f.metrics[f.metrics["phase"] == "flight"].iloc[0]
    assert flight["nav_error_max"] == pytest.approx(err.max(), rel=1e-12)
    assert flight["nav_error_max"] > 0.01
    truth = quadrs.simulate(s.override({"navigation.mode": "truth"}), "pd", seed=1)
    assert truth.navigation is None and "x_est" not in truth.trace
    assert math.isnan(truth.metrics["nav_error_max"].iloc[-1])
    # The estimate moves the vehicle: its path differs from the one flown on the truth.
    assert np.max(np.abs(tr["x"].to_numpy() - truth.trace["x"].to_numpy())) > 1e-3


@pytest.mark.parametrize("height", [None, 0.1])
def test_the_filter_starts_within_its_initial_height_error(height: float | None) -> None:
    """The estimate's height at the start is the truth's less a draw of
    ``navigation.height_error`` (a filter aligned on the pad), or of the GNSS's vertical noise
    (0.75 m) where it is not set: the sample sigma of 120 starts within its 95 % chi-square
    band, the horizontal errors the GNSS's 0.5 m whatever the height's."""
    s = hover_scenario(**{"integrator.duration": 7.0, "navigation.height_error": height})
    sigma = 0.75 if height is None else height
    starts = []
    for i in range(120):
        row = quadrs.simulate(s, "pd", seed=5, realisation=i, record_every=1000).trace.iloc[0]
        starts.append([row["x_est"] - row["x"], row["z_est"] - row["z"], row["z_std"]])
    e = np.asarray(starts)
    # Its own sigma at the first row (after the first update) is the start's, narrowed a little.
    assert np.all(e[:, 2] <= sigma) and np.all(e[:, 2] > 0.8 * sigma)
    n = len(e)
    lo, hi = (np.sqrt(stats.chi2.ppf(q, n) / n) for q in (0.025, 0.975))
    assert lo < np.sqrt(np.mean(e[:, 1] ** 2)) / sigma < hi
    assert lo < np.sqrt(np.mean(e[:, 0] ** 2)) / 0.5 < hi


def test_a_batch_row_is_its_single_flight_with_the_navigation_on() -> None:
    s = hover_scenario(**{"integrator.duration": 6.0})
    mc = quadrs.monte_carlo(s, runs=5, seed=11, controllers=("pd",), workers=2, progress=False)
    for i in (0, 3, 4):
        one = quadrs.simulate(s, "pd", seed=11, realisation=i)
        row = mc.runs[(mc.runs["realisation"] == i) & (mc.runs["phase"] == "flight")]
        single = one.metrics[one.metrics["phase"] == "flight"]
        for m in ("nav_error_max", "nav_error_rms", "tracking_rms"):
            assert row[m].iloc[0] == single[m].iloc[0], m


def nees(flights: list[quadrs.Flight], times: list[float], axes: list[str]) -> np.ndarray:
    """Mean over the flights of sum over the axes of (error / sigma)^2, at each time."""
    out = []
    for t in times:
        total = 0.0
        for f in flights:
            row = f.trace.loc[f.trace.index[np.argmin(np.abs(f.trace.index - t))]]
            total += sum(((row[f"{a}_est"] - row[a]) / row[f"{a}_std"]) ** 2 for a in axes)
        out.append(total / len(flights))
    return np.array(out)


@pytest.mark.parametrize("leg", [False, True])
def test_the_filter_is_consistent(leg: bool) -> None:
    """Over 200 realisations the mean NEES of position and of velocity (3 axes each, from the
    trace's columns) lies within its chi-square bounds at four times. Eight checks of one
    test: each at 1 - 0.05 / 8 (Bonferroni), so that the test as a whole is a 95 % one; the
    NEES at different times of the same flights are correlated, which makes this conservative."""
    s = leg_scenario() if leg else hover_scenario()
    n = 200
    flights = [quadrs.simulate(s, "pd", seed=5, realisation=i, record_every=100) for i in range(n)]
    times = [2.0, 6.0, 10.0, 14.0] if leg else [1.0, 4.0, 8.0, 11.0]
    alpha = 0.05 / 8
    lo, hi = stats.chi2.ppf([alpha / 2, 1 - alpha / 2], 3 * n) / n
    velocity = ["vx", "vy", "vz"] if "vx" in flights[0].trace else None
    for axes in (["x", "y", "z"], velocity):
        if axes is None:
            continue
        e = nees(flights, times, axes)
        assert np.all((e > lo) & (e < hi)), (axes, e, lo, hi)


@pytest.mark.filterwarnings("ignore::quadrs.StepSizeWarning")  # coarse on purpose
def test_the_sensors_sample_at_whole_steps_on_a_coarser_step() -> None:
    """On a 2 ms step the IMU's 200 Hz is every 3 steps (2.5 rounded: 6 ms), the filter's
    100 Hz two IMU periods (12 ms), the GNSS's 5 Hz 17 filter periods (204 ms), its 110 ms
    delay 9 (108 ms)."""
    s = hover_scenario(**{"integrator.dt": 0.002, "integrator.duration": 6.0})
    rec = quadrs.simulate(s, "pd", seed=2).navigation
    assert rec is not None
    np.testing.assert_allclose(np.diff(rec["imu"][:, 0]), 0.006, atol=1e-9)
    np.testing.assert_allclose(np.diff(rec["gnss"][:, 0]), 0.204, atol=1e-9)
    assert rec["gnss"][0, 0] == pytest.approx(0.108)


def test_bad_navigation_settings_are_refused_naming_the_key() -> None:
    s = hover_scenario()
    cases = {
        "sensors.imu.gyro_noise": -1.0,
        "sensors.gnss.rate": 0.0,
        "navigation.rate": -1.0,
    }
    for key, value in cases.items():
        with pytest.raises(quadrs.ScenarioError, match=key.replace(".", r"\.")) as e:
            s.override({key: value})
        assert e.value.key == key
    with pytest.raises(quadrs.ScenarioError, match=r"navigation\.mode"):
        quadrs.Scenario.preset("paper").override({"sensors.imu.gyro_noise": 0.01})


def test_sensor_noise_may_be_dispersed_and_the_schedule_may_not() -> None:
    s = hover_scenario(**{"integrator.duration": 6.0})
    noise = {"dist": "uniform", "low": 1e-3, "high": 2e-3}
    d = s.override({"dispersions": {"sensors.imu.gyro_noise": noise}})
    mc = quadrs.monte_carlo(d, runs=2, seed=0, controllers=("pd",), progress=False)
    assert mc.runs["nav_error_max"].notna().all()
    rate = {"dist": "uniform", "low": 100.0, "high": 200.0}
    with pytest.raises(quadrs.ScenarioError, match="cannot be dispersed"):
        s.override({"dispersions": {"sensors.imu.rate": rate}})
