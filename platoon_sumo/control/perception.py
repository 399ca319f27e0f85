"""Laser perception for followers: scan segmentation, rear-face fitting and a rear tracker.

No SUMO. Three stages, each usable on its own:

1. ``segment_scan``: split a scan into clusters of consecutive hits. A
   cluster breaks where the distance between consecutive hit points exceeds
   ``break_abs_m + r sin(dphi) / sin(lambda - dphi)`` (the adaptive breakpoint detector
   of Borges and Aldon: r the nearer range, dphi the angle between the rays, lambda =
   ``break_angle_deg`` the most grazing incidence still taken as one surface; the jump
   allowed grows with range, and the rule holds for any scanner resolution), at any
   ``+inf`` / ``-inf`` reading, and at runs of more than ``max_dropout_gap`` NaN
   dropouts (shorter dropout runs are bridged, so a missing return does not cut a
   vehicle in two).
2. ``fit_rear``: per cluster, in the sensor frame (x forward, y left), find the rear face
   of a vehicle: a straight line, or an L-shape (rear + one side, split at the point
   farthest from the chord, each side fitted by total least squares and the corner taken
   as their intersection). The side that is closer to perpendicular to the expected
   heading is the rear. Each end of the rear is classified as a true edge (the ray
   beyond it reads farther or nothing) or truncated (occluded by something closer, a
   dropout, or the end of the field of view); when the visible rear is narrower than the
   expected width and exactly one end is true, the centre is placed half a width from
   that end, so partial occlusion and the field-of-view edge do not bias the estimate.
3. ``RearTracker``: a constant-velocity Kalman filter on the predecessor's rear centre
   in the odometry (world) frame, with Mahalanobis gating (plus a floor of half a vehicle
   width), initiation on the candidate closest to straight ahead inside a start gate,
   confirmation after a few consecutive hits, and loss after N missed scans or T seconds.

Defaults are for cars (utm30lx: 0.25 deg steps, 0.1..30 m). For robots (0.3 x 0.25 m,
paper_follower-like scans, 0.3..1-3 m) use ``PerceptionParams(break_abs_m=0.03,
corner_abs_m=0.01)`` and ``TrackerParams(accel_noise_mps2=1.0, meas_noise_m=0.01,
start_range_max_m=1.5, start_lateral_m=0.2, init_speed_std_mps=0.3)``.

The per-scan work runs in compiled kernels (``platoon_sumo.kernels.perception``): one
call segments a scan and fits the rears of its clusters. ``detect_rear_rows`` is that
fast path with the candidates as rows of numbers (what the laser follower uses);
``segment_scan``, ``fit_rear`` and ``detect_rears`` wrap the same kernels in the records
below. The tracker's 4-state Kalman algebra is written out in scalars.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.config_loader import bounded, require, require_positive
from platoon_sumo.kernels.perception import (
    CANDIDATE_COLUMNS,
    STATE_SIZE,
    detect,
    fit_kernel,
    kalman_step,
    segment_kernel,
)
from platoon_sumo.sensors.laser import LaserScan

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


# ----------------------------------------------------------------------------- parameters


@dataclass(frozen=True)
class PerceptionParams:
    """Segmentation and rear fitting. Robot scale: ``break_abs_m=0.03, corner_abs_m=0.01``."""

    break_abs_m: float = bounded(0.1, ge=0, le=100)
    """Constant part of the break distance between consecutive hits, about 3 noise std
    [m] (robots: 0.03)."""
    break_angle_deg: float = bounded(10.0, gt=0, lt=90)
    """Most grazing incidence on a surface still kept in one cluster [deg]."""
    max_dropout_gap: int = bounded(2, ge=0, le=1000)
    """Longest run of NaN dropouts bridged inside one cluster [samples]."""
    min_points: int = bounded(3, ge=2, le=10_000)
    """Clusters with fewer hits are ignored."""
    corner_abs_m: float = bounded(0.08, gt=0, le=100)
    """An L-shape needs its corner at least this far off the chord [m] (robots: 0.01) ..."""
    corner_rel: float = bounded(0.05, ge=0, le=10)
    """... and at least this fraction of the chord length."""
    max_width_factor: float = bounded(1.6, ge=1, le=100)
    """Rears wider than this times the expected width are not vehicles (walls)."""

    def __post_init__(self) -> None:
        require(self.break_abs_m >= 0, "break_abs_m", "must be >= 0")
        require(0 < self.break_angle_deg < 90, "break_angle_deg", "must be in (0, 90)")
        require(self.max_dropout_gap >= 0, "max_dropout_gap", "must be >= 0")
        require(self.min_points >= 2, "min_points", "must be >= 2")
        require(self.corner_abs_m > 0, "corner_abs_m", "must be > 0")
        require(self.corner_rel >= 0, "corner_rel", "must be >= 0")
        require(self.max_width_factor >= 1, "max_width_factor", "must be >= 1")


@dataclass(frozen=True)
class TrackerParams:
    """Rear tracker. Robot scale: ``accel_noise_mps2=1.0, meas_noise_m=0.01,
    start_range_max_m=1.5, start_lateral_m=0.2, init_speed_std_mps=0.3``."""

    accel_noise_mps2: float = bounded(4.0, gt=0, le=100)
    """Std of the white acceleration driving the constant-velocity model [m/s^2]
    (robots: 1.0)."""
    meas_noise_m: float = bounded(0.1, gt=0, le=100)
    """Std of a rear-centre measurement [m] (doubled when the rear is not fully seen)."""
    gate_chi2: float = bounded(13.8, gt=0, le=1e6)
    """Mahalanobis gate on the 2-D innovation (13.8 = 99.9 %)."""
    start_range_max_m: float = bounded(30.0, gt=0, le=1000)
    """Start gate: a new track starts on a rear at most this far ahead [m] ..."""
    start_lateral_m: float = bounded(1.5, gt=0, le=100)
    """... and at most this far left or right of the sensor's axis [m]."""
    init_speed_std_mps: float = bounded(3.0, gt=0, le=150)
    """Std of the initial velocity (initialised to the follower's own) [m/s]."""
    confirm_scans: int = bounded(3, ge=1, le=1000)
    """Consecutive hits before a new track is trusted."""
    max_missed_scans: int = bounded(10, ge=0, le=100_000)
    """The track is lost after this many consecutive scans without a hit ..."""
    lost_after_s: float = bounded(1.0, gt=0, le=10_000)
    """... or this long without a hit [s], whichever comes first."""

    def __post_init__(self) -> None:
        require_positive(
            self,
            "accel_noise_mps2",
            "meas_noise_m",
            "gate_chi2",
            "start_range_max_m",
            "start_lateral_m",
            "init_speed_std_mps",
            "lost_after_s",
        )
        require(self.confirm_scans >= 1, "confirm_scans", "must be >= 1")
        require(self.max_missed_scans >= 0, "max_missed_scans", "must be >= 0")


# ----------------------------------------------------------------------------- segmentation


@dataclass(frozen=True, eq=False)
class Segmentation:
    """Clusters of a scan. Cluster c is ``points[starts[c]:stops[c]]`` (sensor frame, m),
    taken from scan samples ``index[starts[c]:stops[c]]`` (increasing angle, right to left)."""

    points: FloatArray
    index: IntArray
    starts: IntArray
    stops: IntArray

    def __len__(self) -> int:
        return int(self.starts.size)

    def cluster(self, c: int) -> FloatArray:
        return self.points[self.starts[c] : self.stops[c]]


_RAY_TABLES: dict[tuple[float, float, int], tuple[FloatArray, FloatArray]] = {}


def ray_table(scan: LaserScan) -> tuple[FloatArray, FloatArray]:
    """Cosine and sine of each ray's angle (``scan.angles``), computed once per scan
    geometry (angle_min, angle_increment, samples)."""
    key = (scan.angle_min, scan.angle_increment, scan.ranges.size)
    table = _RAY_TABLES.get(key)
    if table is None:
        if len(_RAY_TABLES) >= 64:  # a handful of laser models in a run
            _RAY_TABLES.clear()
        angles = scan.angles
        table = _RAY_TABLES[key] = (np.cos(angles), np.sin(angles))
    return table


@functools.lru_cache(maxsize=64)
def params_array(params: PerceptionParams) -> FloatArray:
    """The parameters as the detection kernel takes them
    (``platoon_sumo.kernels.perception.PARAM_NAMES``)."""
    return np.array(
        [
            params.break_abs_m,
            math.radians(params.break_angle_deg),
            params.max_dropout_gap,
            params.min_points,
            params.corner_abs_m,
            params.corner_rel,
            params.max_width_factor,
        ],
        dtype=np.float64,
    )


def scan_ranges(scan: LaserScan) -> FloatArray:
    """The ranges as the kernels take them (C-contiguous float64; usually no copy)."""
    return np.ascontiguousarray(scan.ranges, dtype=np.float64)


def segment_scan(scan: LaserScan, params: PerceptionParams) -> Segmentation:
    """Split a scan into clusters (see the module docstring)."""
    cos_a, sin_a = ray_table(scan)
    pts, idx, starts, stops = segment_kernel(
        scan_ranges(scan),
        cos_a,
        sin_a,
        float(scan.angle_increment),
        float(params.break_abs_m),
        math.radians(params.break_angle_deg),
        int(params.max_dropout_gap),
    )
    return Segmentation(pts, idx.astype(np.intp), starts.astype(np.intp), stops.astype(np.intp))


# ----------------------------------------------------------------------------- rear fitting


@dataclass(frozen=True, eq=False)
class RearCandidate:
    """A possible vehicle rear, in the sensor frame (x forward, y left)."""

    x_m: float
    y_m: float
    """Estimated centre of the rear face."""
    width_m: float
    """Visible width of the rear face."""
    heading_rad: float
    """Direction of the rear face's normal, away from the sensor (the vehicle's heading)."""
    complete: bool
    """Both ends of the rear are true edges (not occluded or cut by the field of view)."""
    l_shape: bool
    """A side of the vehicle is visible as well."""
    points: FloatArray
    """The cluster's hit points (k, 2)."""
    alternative: bool = False
    """The less likely reading of an L-shape (its other side taken as the rear)."""

    @property
    def range_m(self) -> float:
        return math.hypot(self.x_m, self.y_m)

    @property
    def bearing_rad(self) -> float:
        return math.atan2(self.y_m, self.x_m)


def candidate_from_row(points: FloatArray, row: Sequence[float]) -> RearCandidate:
    """A kernel's candidate row as a record; ``points`` are the cluster's points."""
    return RearCandidate(
        x_m=row[0],
        y_m=row[1],
        width_m=row[2],
        heading_rad=row[3],
        complete=row[4] != 0.0,
        l_shape=row[5] != 0.0,
        points=points,
        alternative=row[6] != 0.0,
    )


def fit_rear(
    points: FloatArray,
    first_true: bool,
    last_true: bool,
    expected_width_m: float,
    heading_hint_rad: float,
    params: PerceptionParams,
    ray_step_rad: float = 0.0,
) -> list[RearCandidate]:
    """Fit a vehicle rear to one cluster (ordered right to left).

    ``first_true`` / ``last_true`` say whether the cluster's right / left end is a true
    edge; ``heading_hint_rad`` is the expected vehicle heading in the sensor frame. A
    true edge lies between the last ray that hit and the next one: with ``ray_step_rad``
    (the angle between rays) true ends are moved out by half a ray spacing on the face.
    Returns no candidate (implausible), one (a line), or two for an L-shape: first the
    side closer to perpendicular to the hint as the rear, then the other side as the
    rear (``alternative=True``), for a tracker to choose by its prediction.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
    rows = fit_kernel(
        pts,
        bool(first_true),
        bool(last_true),
        float(expected_width_m),
        float(heading_hint_rad),
        int(params.min_points),
        float(params.corner_abs_m),
        float(params.corner_rel),
        float(params.max_width_factor),
        float(ray_step_rad),
    )
    return [candidate_from_row(points, row) for row in rows.tolist()]


def detect_rear_rows(
    scan: LaserScan,
    params: PerceptionParams,
    expected_width_m: float,
    heading_hint_rad: float = 0.0,
    roi: tuple[float, float, float] | None = None,
) -> tuple[FloatArray, FloatArray]:
    """``detect_rears`` without the records: the scan's hit points (H, 2) in the sensor
    frame, and one row per candidate with the columns of
    ``platoon_sumo.kernels.perception.CANDIDATE_COLUMNS`` (centre x, y, width, heading,
    complete, l_shape, alternative as 0 / 1, and the cluster's rows lo, hi of the
    points)."""
    roi_x, roi_y, roi_r = roi if roi is not None else (0.0, 0.0, 0.0)
    cos_a, sin_a = ray_table(scan)
    return detect(
        scan_ranges(scan),
        cos_a,
        sin_a,
        float(scan.angle_increment),
        params_array(params),
        float(expected_width_m),
        float(heading_hint_rad),
        roi is not None,
        float(roi_x),
        float(roi_y),
        float(roi_r),
    )


def detect_rears(
    scan: LaserScan,
    params: PerceptionParams,
    expected_width_m: float,
    heading_hint_rad: float = 0.0,
    roi: tuple[float, float, float] | None = None,
) -> list[RearCandidate]:
    """All plausible vehicle rears in a scan (sensor frame).

    ``roi = (x, y, radius)`` (sensor frame, m) keeps only clusters with a point within
    ``radius`` of (x, y): only those are fitted, which bounds the cost on cluttered scans.
    """
    pts, rows = detect_rear_rows(scan, params, expected_width_m, heading_hint_rad, roi)
    return [candidate_from_row(pts[int(r[7]) : int(r[8])], r) for r in rows.tolist()]


# ----------------------------------------------------------------------------- tracking


@dataclass(frozen=True)
class SensorPose:
    """World pose of the sensor when a scan was taken."""

    x_m: float
    y_m: float
    heading_rad: float

    def to_world(self, x_m: float, y_m: float) -> tuple[float, float]:
        c, s = math.cos(self.heading_rad), math.sin(self.heading_rad)
        return self.x_m + c * x_m - s * y_m, self.y_m + s * x_m + c * y_m

    def to_sensor(self, x_m: float, y_m: float) -> tuple[float, float]:
        c, s = math.cos(self.heading_rad), math.sin(self.heading_rad)
        dx, dy = x_m - self.x_m, y_m - self.y_m
        return c * dx + s * dy, -s * dx + c * dy


_P_INDEX = ((0, 1, 2, 3), (1, 4, 5, 6), (2, 5, 7, 8), (3, 6, 8, 9))
"""Where entry (i, j) of the symmetric 4x4 covariance sits in its 10 stored numbers."""


def _rows(candidates: Sequence[RearCandidate]) -> FloatArray:
    """Candidates as kernel rows (the columns the tracker reads: x, y, complete)."""
    rows = np.zeros((len(candidates), len(CANDIDATE_COLUMNS)))
    for k, c in enumerate(candidates):
        rows[k, 0], rows[k, 1], rows[k, 4] = c.x_m, c.y_m, float(c.complete)
    return rows


class RearTracker:
    """Constant-velocity Kalman filter on one vehicle's rear centre, in the world frame.

    State ``[x, y, vx, vy]`` (m, m/s). Call ``step`` once per new scan (or
    ``step_rows`` with ``detect_rear_rows``' candidate rows). The filter's algebra runs
    in ``platoon_sumo.kernels.perception.kalman_step``; ``x`` and ``P`` give the state
    and its covariance as arrays.
    """

    def __init__(self, params: TrackerParams | None = None):
        self.params = params or TrackerParams()
        self._state = np.zeros(STATE_SIZE)
        """time, x, y, vx, vy, upper triangle of P (see ``kalman_step``)."""
        self.reset()

    def reset(self) -> None:
        self._set(0.0, (0.0, 0.0, 0.0, 0.0), 1.0, 1.0)
        self.active = False
        self.hits = 0
        self.missed = 0
        self.last_hit_s = -math.inf
        self._last: RearCandidate | Callable[[], RearCandidate] | None = None

    def _set(
        self, time_s: float, x: tuple[float, float, float, float], var_p: float, var_v: float
    ) -> None:
        """State x with a diagonal covariance (var_p for the position, var_v the velocity)."""
        self._state[:] = (time_s, *x, var_p, 0.0, 0.0, 0.0, var_p, 0.0, 0.0, var_v, 0.0, var_v)
        self.time_s = time_s
        self._x = x
        self._position_variance = 2.0 * var_p
        self._velocity_variance = 2.0 * var_v

    @property
    def x(self) -> FloatArray:
        """The state ``[x, y, vx, vy]`` (a copy)."""
        return np.array(self._x, dtype=np.float64)

    @property
    def P(self) -> FloatArray:
        """The state covariance (4, 4) (a copy)."""
        p = self._state[5:]
        return np.array([[p[k] for k in row] for row in _P_INDEX], dtype=np.float64)

    @property
    def last_candidate(self) -> RearCandidate | None:
        """The candidate last associated (or started on)."""
        last = self._last
        if callable(last):  # built when asked for
            last = self._last = last()
        return last

    @property
    def confirmed(self) -> bool:
        return self.active and self.hits >= self.params.confirm_scans

    @property
    def position(self) -> tuple[float, float]:
        return self._x[0], self._x[1]

    @property
    def velocity(self) -> tuple[float, float]:
        return self._x[2], self._x[3]

    @property
    def position_variance(self) -> float:
        """Trace of the position block of the covariance [m^2]."""
        return self._position_variance

    def predicted(self, time_s: float) -> FloatArray:
        """State extrapolated to ``time_s`` (no covariance, no side effects)."""
        return np.array(self.predicted_state(time_s), dtype=np.float64)

    def predicted_state(self, time_s: float) -> tuple[float, float, float, float]:
        """``predicted`` as four floats."""
        dt = max(time_s - self.time_s, 0.0)
        x, y, vx, vy = self._x
        return x + dt * vx, y + dt * vy, vx, vy

    def heading_hint(self, fallback_rad: float) -> float:
        """Velocity direction when the speed estimate is significant, else ``fallback_rad``."""
        if not self.active:
            return fallback_rad
        _, _, vx, vy = self._x
        speed = math.hypot(vx, vy)
        sigma = math.sqrt(max(self._velocity_variance, 0.0))
        return math.atan2(vy, vx) if speed > 2.0 * sigma else fallback_rad

    def _noise(self, complete: bool) -> float:
        sigma = self.params.meas_noise_m * (1.0 if complete else 2.0)
        return sigma * sigma

    def step(
        self,
        time_s: float,
        candidates: list[RearCandidate],
        pose: SensorPose,
        own_velocity: tuple[float, float],
        gate_floor_m: float,
    ) -> RearCandidate | None:
        """Process one scan's candidates; returns the one associated (or started), if any."""
        if not self.active:
            k = self._start(
                time_s,
                [(c.x_m, c.y_m, c.complete, c.alternative) for c in candidates],
                (pose.x_m, pose.y_m, pose.heading_rad),
                own_velocity,
            )
        else:
            k = self._associate(
                time_s, _rows(candidates), (pose.x_m, pose.y_m, pose.heading_rad), gate_floor_m
            )
        if k < 0:
            return None
        self._last = candidates[k]
        return candidates[k]

    def step_rows(
        self,
        time_s: float,
        points: FloatArray,
        rows: FloatArray,
        pose: tuple[float, float, float],
        own_velocity: tuple[float, float],
        gate_floor_m: float,
    ) -> int:
        """``step`` on the candidate rows of ``detect_rear_rows`` (with its ``points``) and
        a sensor pose (x, y, heading): the index of the row associated (or started on),
        or -1."""
        if not self.active:
            items = [(r[0], r[1], r[4] != 0.0, r[6] != 0.0) for r in rows.tolist()]
            k = self._start(time_s, items, pose, own_velocity)
        else:
            k = self._associate(time_s, rows, pose, gate_floor_m)
        if k >= 0:
            row = rows[k]
            self._last = lambda: candidate_from_row(points[int(row[7]) : int(row[8])], row.tolist())
        return k

    def _start(
        self,
        time_s: float,
        candidates: list[tuple[float, float, bool, bool]],
        pose: tuple[float, float, float],
        own_velocity: tuple[float, float],
    ) -> int:
        """Start a track on the candidate (x, y, complete, alternative; sensor frame)
        closest to straight ahead in the start gate, if any."""
        p = self.params
        best, best_bearing = -1, math.inf
        for k, (cx, cy, _, alternative) in enumerate(candidates):
            in_gate = 0.0 < cx <= p.start_range_max_m and abs(cy) <= p.start_lateral_m
            if in_gate and not alternative:
                bearing = abs(math.atan2(cy, cx))
                if bearing < best_bearing:
                    best, best_bearing = k, bearing
        if best >= 0:
            cx, cy, complete, _ = candidates[best]
            c, s = math.cos(pose[2]), math.sin(pose[2])
            zx, zy = pose[0] + c * cx - s * cy, pose[1] + s * cx + c * cy
            var_v = p.init_speed_std_mps**2
            v = (zx, zy, float(own_velocity[0]), float(own_velocity[1]))
            self._set(time_s, v, self._noise(complete), var_v)
            self.active, self.hits, self.missed = True, 1, 0
            self.last_hit_s = time_s
        return best

    def _associate(
        self,
        time_s: float,
        rows: FloatArray,
        pose: tuple[float, float, float],
        gate_floor_m: float,
    ) -> int:
        """Predict, gate and update an active track with candidate rows (sensor frame)."""
        p = self.params
        k, x, y, vx, vy, var_p, var_v = kalman_step(
            self._state, float(time_s), rows, float(pose[0]), float(pose[1]),
            math.cos(pose[2]), math.sin(pose[2]), float(p.accel_noise_mps2),
            float(p.meas_noise_m), float(p.gate_chi2), float(gate_floor_m),
        )  # fmt: skip
        return self.record_step(time_s, k, (x, y, vx, vy), var_p, var_v)

    def keep_state_in(self, array: FloatArray) -> None:
        """Keep the filter's state in `array` (15 numbers, e.g. a row of a pool of many
        trackers' states) from now on; the current state is copied there."""
        array[:] = self._state
        self._state = array

    @property
    def state_array(self) -> FloatArray:
        """The filter's state as ``kalman_step`` takes it (updated in place: a kernel that
        runs ``kalman_step`` on it reports with ``record_step``)."""
        return self._state

    def record_step(
        self,
        time_s: float,
        k: int,
        x: tuple[float, float, float, float],
        var_p: float,
        var_v: float,
        candidate: Callable[[], RearCandidate] | None = None,
    ) -> int:
        """Book a ``kalman_step`` of an active track on ``state_array`` at ``time_s``: the
        row it associated (-1: none), its results (state, position and velocity
        variances), and what builds the candidate associated (for ``last_candidate``).
        Returns the row, or -1 (the track may have been lost)."""
        p = self.params
        self.time_s = time_s
        self._x = x
        self._position_variance, self._velocity_variance = var_p, var_v
        if k < 0:
            self.missed += 1
            if (
                not self.confirmed  # a tentative track must hit on every scan
                or self.missed > p.max_missed_scans
                or time_s - self.last_hit_s > p.lost_after_s
            ):
                self.reset()
            return -1
        self.hits += 1
        self.missed = 0
        self.last_hit_s = time_s
        if candidate is not None:
            self._last = candidate
        return int(k)
