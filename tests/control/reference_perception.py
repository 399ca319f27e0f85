"""REFERENCE ONLY (test oracle): ``platoon_sumo/control/perception.py`` as it was before
the fast path (numpy on small arrays), kept verbatim so the equivalence tests and
``tools/bench_controllers.py`` can replay recorded observations through it. Do not use
in package code, do not change.

Laser perception for followers: scan segmentation, rear-face fitting and a rear tracker.

Pure numpy, no SUMO. Three stages, each usable on its own:

1. ``segment_scan``: split a scan into clusters of consecutive hits (vectorised). A
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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.config_loader import require, require_positive
from platoon_sumo.sensors.laser import LaserScan

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

_MAX_CORNER_COS = math.cos(math.radians(60.0))
"""The sides of an L-shape must meet at 60 deg or more (90 for a box)."""


# ----------------------------------------------------------------------------- parameters


@dataclass(frozen=True)
class PerceptionParams:
    """Segmentation and rear fitting. Robot scale: ``break_abs_m=0.03, corner_abs_m=0.01``."""

    break_abs_m: float = 0.1
    """Constant part of the break distance between consecutive hits, about 3 noise std
    [m] (robots: 0.03)."""
    break_angle_deg: float = 10.0
    """Most grazing incidence on a surface still kept in one cluster [deg]."""
    max_dropout_gap: int = 2
    """Longest run of NaN dropouts bridged inside one cluster [samples]."""
    min_points: int = 3
    """Clusters with fewer hits are ignored."""
    corner_abs_m: float = 0.08
    """An L-shape needs its corner at least this far off the chord [m] (robots: 0.01) ..."""
    corner_rel: float = 0.05
    """... and at least this fraction of the chord length."""
    max_width_factor: float = 1.6
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

    accel_noise_mps2: float = 4.0
    """Std of the white acceleration driving the constant-velocity model [m/s^2]
    (robots: 1.0)."""
    meas_noise_m: float = 0.1
    """Std of a rear-centre measurement [m] (doubled when the rear is not fully seen)."""
    gate_chi2: float = 13.8
    """Mahalanobis gate on the 2-D innovation (13.8 = 99.9 %)."""
    start_range_max_m: float = 30.0
    """Start gate: a new track starts on a rear at most this far ahead [m] ..."""
    start_lateral_m: float = 1.5
    """... and at most this far left or right of the sensor's axis [m]."""
    init_speed_std_mps: float = 3.0
    """Std of the initial velocity (initialised to the follower's own) [m/s]."""
    confirm_scans: int = 3
    """Consecutive hits before a new track is trusted."""
    max_missed_scans: int = 10
    """The track is lost after this many consecutive scans without a hit ..."""
    lost_after_s: float = 1.0
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


def segment_scan(scan: LaserScan, params: PerceptionParams) -> Segmentation:
    """Split a scan into clusters (see the module docstring); vectorised over samples."""
    r = np.asarray(scan.ranges, dtype=np.float64)
    finite = np.isfinite(r)
    idx = np.flatnonzero(finite)
    if idx.size == 0:
        empty_i = np.zeros(0, dtype=np.intp)
        return Segmentation(np.zeros((0, 2)), empty_i, empty_i, empty_i)
    a = scan.angle_min + idx * scan.angle_increment
    rr = r[idx]
    pts = np.column_stack((rr * np.cos(a), rr * np.sin(a)))
    inf_count = np.cumsum(np.isinf(r))
    step = np.hypot(*np.diff(pts, axis=0).T)
    dphi = np.diff(idx) * abs(scan.angle_increment)
    lam = math.radians(params.break_angle_deg)
    ratio = np.sin(dphi) / np.maximum(np.sin(lam - dphi), 1e-3)
    limit = params.break_abs_m + np.minimum(rr[1:], rr[:-1]) * ratio
    breaks = (
        (inf_count[idx[1:]] != inf_count[idx[:-1]])
        | (np.diff(idx) - 1 > params.max_dropout_gap)
        | (step > limit)
    )
    cut = np.flatnonzero(breaks) + 1
    starts = np.concatenate(([0], cut)).astype(np.intp)
    stops = np.concatenate((cut, [idx.size])).astype(np.intp)
    return Segmentation(pts, idx.astype(np.intp), starts, stops)


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


def _tls_line(points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Total-least-squares line: (a point on it, unit direction)."""
    centre = points.mean(axis=0)
    d = points - centre
    cov = d.T @ d
    _, vecs = np.linalg.eigh(cov)
    return centre, vecs[:, 1]


def _intersect(p: FloatArray, u: FloatArray, q: FloatArray, v: FloatArray) -> FloatArray | None:
    den = u[0] * v[1] - u[1] * v[0]
    if abs(den) < 1e-6:
        return None
    w = q - p
    t = (w[0] * v[1] - w[1] * v[0]) / den
    return np.asarray(p + t * u, dtype=np.float64)


def _project(point: FloatArray, p: FloatArray, u: FloatArray) -> FloatArray:
    return np.asarray(p + float(np.dot(point - p, u)) * u, dtype=np.float64)


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
    k = len(points)
    if k < params.min_points:
        return []
    a, b = points[0], points[-1]
    chord = b - a
    chord_len = float(np.hypot(*chord))
    hint = np.array([math.cos(heading_hint_rad), math.sin(heading_hint_rad)])
    if chord_len > 0 and k >= 5:
        off = np.abs(chord[0] * (points[:, 1] - a[1]) - chord[1] * (points[:, 0] - a[0]))
        off /= chord_len
        j = int(np.argmax(off))
        min_side = 2.0 * params.corner_abs_m
        if (
            off[j] > max(params.corner_abs_m, params.corner_rel * chord_len)
            and 2 <= j <= k - 3
            and float(np.hypot(*(points[j] - a))) >= min_side
            and float(np.hypot(*(b - points[j]))) >= min_side
        ):
            p1, u1 = _tls_line(points[: j + 1])
            p2, u2 = _tls_line(points[j:])
            corner = _intersect(p1, u1, p2, u2)
            # a box's sides meet at a right angle: nearly parallel fits are noise, a line
            if corner is not None and abs(float(np.dot(u1, u2))) < _MAX_CORNER_COS:
                right = (_project(a, p1, u1), corner, first_true, True)
                left = (corner, _project(b, p2, u2), True, last_true)
                options = [right, left]
                if abs(float(np.dot(u1, hint))) > abs(float(np.dot(u2, hint))):
                    options.reverse()
                out = []
                for n, (end_a, end_b, a_true, b_true) in enumerate(options):
                    cand = _rear_candidate(
                        end_a, end_b, a_true, b_true, points, expected_width_m, hint, params,
                        ray_step_rad,
                    )  # fmt: skip
                    if cand is not None:
                        out.append(replace(cand, l_shape=True, alternative=n == 1))
                return out
    p, u = _tls_line(points)
    cand = _rear_candidate(
        _project(a, p, u), _project(b, p, u), first_true, last_true, points,
        expected_width_m, hint, params, ray_step_rad,
    )  # fmt: skip
    return [] if cand is None else [cand]


def _rear_candidate(
    end_a: FloatArray,
    end_b: FloatArray,
    a_true: bool,
    b_true: bool,
    points: FloatArray,
    expected_width_m: float,
    hint: FloatArray,
    params: PerceptionParams,
    ray_step_rad: float,
) -> RearCandidate | None:
    """Candidate for a rear face from its right end ``end_a`` to its left end ``end_b``."""
    span = end_b - end_a
    width = float(np.hypot(*span))
    u_rear = span / width if width > 1e-9 else np.array([-hint[1], hint[0]])
    if ray_step_rad > 0.0:
        normal = np.array([u_rear[1], -u_rear[0]])

        def pad(end: FloatArray) -> float:
            r = float(np.hypot(*end))
            cos_inc = abs(float(np.dot(end, normal))) / max(r, 1e-9)
            return 0.5 * r * ray_step_rad / max(cos_inc, 0.3)

        end_a = end_a - pad(end_a) * u_rear if a_true else end_a
        end_b = end_b + pad(end_b) * u_rear if b_true else end_b
        span = end_b - end_a
        width = float(np.hypot(*span))
    if width > params.max_width_factor * expected_width_m:
        return None
    centre = 0.5 * (end_a + end_b)
    if width < expected_width_m:
        if a_true and not b_true:
            centre = end_a + 0.5 * expected_width_m * u_rear
        elif b_true and not a_true:
            centre = end_b - 0.5 * expected_width_m * u_rear
    normal = np.array([u_rear[1], -u_rear[0]])  # right-hand normal of a right-to-left face
    if float(np.dot(normal, centre)) < 0:
        normal = -normal
    return RearCandidate(
        x_m=float(centre[0]),
        y_m=float(centre[1]),
        width_m=width,
        heading_rad=math.atan2(normal[1], normal[0]),
        complete=bool(a_true and b_true),
        l_shape=False,
        points=points,
    )


def _end_is_true(ranges: FloatArray, inside: int, outside: int) -> bool:
    """Is the cluster end at sample ``inside`` a true edge (the ray beyond reads farther)?"""
    if outside < 0 or outside >= ranges.size:
        return False  # cut by the field of view
    beyond = ranges[outside]
    if math.isnan(beyond):
        return False  # unknown
    return bool(beyond > ranges[inside])  # +inf (nothing) or farther: a true edge


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
    seg = segment_scan(scan, params)
    if len(seg) == 0:
        return []
    keep = (seg.stops - seg.starts) >= params.min_points
    if roi is not None:
        cx, cy, radius = roi
        d2 = (seg.points[:, 0] - cx) ** 2 + (seg.points[:, 1] - cy) ** 2
        keep &= np.minimum.reduceat(d2, seg.starts) <= radius * radius
    ranges = np.asarray(scan.ranges, dtype=np.float64)
    out: list[RearCandidate] = []
    for c in np.flatnonzero(keep):
        lo, hi = int(seg.starts[c]), int(seg.stops[c])
        i_first, i_last = int(seg.index[lo]), int(seg.index[hi - 1])
        out += fit_rear(
            seg.points[lo:hi],
            _end_is_true(ranges, i_first, i_first - 1),
            _end_is_true(ranges, i_last, i_last + 1),
            expected_width_m,
            heading_hint_rad,
            params,
            abs(scan.angle_increment),
        )
    return out


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


class RearTracker:
    """Constant-velocity Kalman filter on one vehicle's rear centre, in the world frame.

    State ``[x, y, vx, vy]`` (m, m/s). Call ``step`` once per new scan.
    """

    def __init__(self, params: TrackerParams | None = None):
        self.params = params or TrackerParams()
        self.reset()

    def reset(self) -> None:
        self.x = np.zeros(4)
        self.P = np.eye(4)
        self.active = False
        self.hits = 0
        self.missed = 0
        self.time_s = 0.0
        self.last_hit_s = -math.inf
        self.last_candidate: RearCandidate | None = None

    @property
    def confirmed(self) -> bool:
        return self.active and self.hits >= self.params.confirm_scans

    @property
    def position(self) -> tuple[float, float]:
        return float(self.x[0]), float(self.x[1])

    @property
    def velocity(self) -> tuple[float, float]:
        return float(self.x[2]), float(self.x[3])

    def predicted(self, time_s: float) -> FloatArray:
        """State extrapolated to ``time_s`` (no covariance, no side effects)."""
        dt = max(time_s - self.time_s, 0.0)
        return np.array([self.x[0] + dt * self.x[2], self.x[1] + dt * self.x[3], *self.x[2:]])

    def heading_hint(self, fallback_rad: float) -> float:
        """Velocity direction when the speed estimate is significant, else ``fallback_rad``."""
        if not self.active:
            return fallback_rad
        speed = math.hypot(self.x[2], self.x[3])
        sigma = math.sqrt(max(self.P[2, 2] + self.P[3, 3], 0.0))
        return math.atan2(self.x[3], self.x[2]) if speed > 2.0 * sigma else fallback_rad

    def _predict(self, time_s: float) -> None:
        dt = max(time_s - self.time_s, 0.0)
        self.time_s = time_s
        if dt == 0.0:
            return
        f = np.eye(4)
        f[0, 2] = f[1, 3] = dt
        q = self.params.accel_noise_mps2**2
        g = np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]]) * q
        qm = np.zeros((4, 4))
        qm[np.ix_([0, 2], [0, 2])] = g
        qm[np.ix_([1, 3], [1, 3])] = g
        self.x = f @ self.x
        self.P = f @ self.P @ f.T + qm

    def _noise(self, cand: RearCandidate) -> float:
        sigma = self.params.meas_noise_m * (1.0 if cand.complete else 2.0)
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
        p = self.params
        if not self.active:
            best = self._start_candidate(candidates)
            if best is not None:
                zx, zy = pose.to_world(best.x_m, best.y_m)
                var_v = p.init_speed_std_mps**2
                self.x = np.array([zx, zy, own_velocity[0], own_velocity[1]])
                self.P = np.diag([self._noise(best)] * 2 + [var_v, var_v])
                self.active, self.hits, self.missed = True, 1, 0
                self.time_s = self.last_hit_s = time_s
                self.last_candidate = best
            return best
        self._predict(time_s)
        best, best_d2 = None, math.inf
        s_pos = self.P[:2, :2]
        for cand in candidates:
            z = np.array(pose.to_world(cand.x_m, cand.y_m))
            nu = z - self.x[:2]
            s = s_pos + np.eye(2) * self._noise(cand)
            d2 = float(nu @ np.linalg.solve(s, nu))
            inside = d2 <= p.gate_chi2 or float(np.hypot(*nu)) <= gate_floor_m
            if inside and d2 < best_d2:
                best, best_d2 = cand, d2
        if best is None:
            self.missed += 1
            if (
                not self.confirmed  # a tentative track must hit on every scan
                or self.missed > p.max_missed_scans
                or time_s - self.last_hit_s > p.lost_after_s
            ):
                self.reset()
            return None
        z = np.array(pose.to_world(best.x_m, best.y_m))
        h = np.zeros((2, 4))
        h[0, 0] = h[1, 1] = 1.0
        s = self.P[:2, :2] + np.eye(2) * self._noise(best)
        gain = self.P @ h.T @ np.linalg.inv(s)
        self.x = self.x + gain @ (z - self.x[:2])
        self.P = (np.eye(4) - gain @ h) @ self.P
        self.P = 0.5 * (self.P + self.P.T)
        self.hits += 1
        self.missed = 0
        self.last_hit_s = time_s
        self.last_candidate = best
        return best

    def _start_candidate(self, candidates: list[RearCandidate]) -> RearCandidate | None:
        p = self.params
        best, best_bearing = None, math.inf
        for cand in candidates:
            in_gate = 0.0 < cand.x_m <= p.start_range_max_m and abs(cand.y_m) <= p.start_lateral_m
            in_gate = in_gate and not cand.alternative
            if in_gate and abs(cand.bearing_rad) < best_bearing:
                best, best_bearing = cand, abs(cand.bearing_rad)
        return best
