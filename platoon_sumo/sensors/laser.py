"""Laser scanner configuration and the scan message it produces.

The message mirrors ROS ``sensor_msgs/LaserScan`` so controllers written against ROS
(as in the paper) read the same fields, and follows REP 117 for out-of-range readings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from platoon_sumo.config_loader import FieldError
from platoon_sumo.errors import did_you_mean
from platoon_sumo.frozen import frozen_from_dict

#: Most rays a scanner may have (a UTM-30LX has 1081; each ray costs memory and time).
MAX_SAMPLES = 20_000
#: Longest range a scanner may have [m].
MAX_RANGE_M = 1000.0
#: Highest scan rate [Hz].
MAX_RATE_HZ = 1000.0

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class LaserConfig:
    """A planar laser scanner and where it sits on the vehicle.

    Angles are in the sensor frame, counter-clockwise from the sensor's forward axis.
    The mount pose is relative to the vehicle's FRONT BUMPER CENTRE (the point SUMO
    reports), x forward, y left, so a default sensor sits on the bumper looking ahead.
    """

    angle_min_rad: float
    angle_max_rad: float
    samples: int
    range_min_m: float
    range_max_m: float
    noise_std_m: float = 0.0
    dropout_prob: float = 0.0
    rate_hz: float = 40.0
    mount_x_m: float = 0.0
    mount_y_m: float = 0.0
    mount_yaw_rad: float = 0.0

    def __post_init__(self) -> None:
        def bad(name: str, expected: str) -> FieldError:
            value = getattr(self, name)
            return FieldError(name, f"LaserConfig.{name}: expected {expected}, got {value!r}")

        for name in (
            "angle_min_rad",
            "angle_max_rad",
            "range_min_m",
            "range_max_m",
            "noise_std_m",
            "dropout_prob",
            "rate_hz",
            "mount_x_m",
            "mount_y_m",
            "mount_yaw_rad",
        ):
            if not math.isfinite(getattr(self, name)):
                raise bad(name, "a finite number")
        if isinstance(self.samples, bool) or not isinstance(self.samples, (int, np.integer)):
            raise bad("samples", "an integer >= 2")
        if self.samples < 2:
            raise bad("samples", "an integer >= 2")
        if self.samples > MAX_SAMPLES:
            raise bad("samples", f"an integer <= {MAX_SAMPLES}")
        if self.angle_max_rad <= self.angle_min_rad:
            raise bad("angle_max_rad", f"> angle_min_rad ({self.angle_min_rad})")
        if self.angle_max_rad - self.angle_min_rad > 2.0 * math.pi:
            raise bad("angle_max_rad", f"angle_max_rad - angle_min_rad <= 2*pi ({2 * math.pi})")
        if self.range_min_m < 0.0:
            raise bad("range_min_m", ">= 0")
        if self.range_max_m <= self.range_min_m:
            raise bad("range_max_m", f"> range_min_m ({self.range_min_m})")
        if self.noise_std_m < 0.0:
            raise bad("noise_std_m", ">= 0")
        if not 0.0 <= self.dropout_prob < 1.0:
            raise bad("dropout_prob", "a probability in [0, 1)")
        if self.range_max_m > MAX_RANGE_M:
            raise bad("range_max_m", f"<= {MAX_RANGE_M:g} m")
        if self.rate_hz <= 0.0:
            raise bad("rate_hz", "> 0")
        if self.rate_hz > MAX_RATE_HZ:
            raise bad("rate_hz", f"<= {MAX_RATE_HZ:g} Hz")

    @property
    def angle_increment_rad(self) -> float:
        """Angle between consecutive rays."""
        return (self.angle_max_rad - self.angle_min_rad) / (self.samples - 1)

    @property
    def angles_rad(self) -> FloatArray:
        """Ray i points at ``angle_min + i * angle_increment`` (both ends included)."""
        i = np.arange(self.samples, dtype=np.float64)
        return self.angle_min_rad + i * self.angle_increment_rad

    @property
    def scan_time_s(self) -> float:
        """Time between two scans."""
        return 1.0 / self.rate_hz

    @classmethod
    def preset(cls, name: str, **overrides: float) -> LaserConfig:
        """A named preset, optionally with some fields replaced (e.g. ``noise_std_m``)."""
        try:
            base = LASER_PRESETS[name]
        except KeyError:
            hint = did_you_mean(name, LASER_PRESETS)
            raise ValueError(
                f"unknown laser preset {name!r}; expected one of {sorted(LASER_PRESETS)}"
                + (f" ({hint})" if hint else "")
            ) from None
        if not overrides:
            return base
        fields = {f: getattr(base, f) for f in base.__dataclass_fields__}
        unknown = set(overrides) - set(fields)
        if unknown:
            raise ValueError(f"unknown LaserConfig field(s) {sorted(unknown)}")
        fields.update(overrides)
        return cls(**fields)


_DEG = math.pi / 180.0

#: Scanners of the paper (leader / follower, both on a Hokuyo UTM-30LX) and the
#: UTM-30LX itself (270 deg, 0.25 deg steps, 25 ms per scan) as a car-scale sensor.
#: "lidar_120m" is a single-layer automotive lidar of the class used for ACC and
#: platooning research (110 deg, 0.25 deg steps, 120 m, 25 Hz): the UTM-30LX's 30 m
#: lose a predecessor at a 1.2 s time gap above about 20 m/s.
#: Presets are noiseless so runs are reproducible; the UTM-30LX datasheet accuracy is
#: about +-30 mm, i.e. ``LaserConfig.preset("utm30lx", noise_std_m=0.01)``.
LASER_PRESETS: dict[str, LaserConfig] = {
    "paper_leader": LaserConfig(-90.0 * _DEG, 90.0 * _DEG, 720, 0.30, 3.0),
    "paper_follower": LaserConfig(-11.5 * _DEG, 11.5 * _DEG, 720, 0.30, 1.0),
    "utm30lx": LaserConfig(-135.0 * _DEG, 135.0 * _DEG, 1081, 0.1, 30.0, rate_hz=40.0),
    "lidar_120m": LaserConfig(-55.0 * _DEG, 55.0 * _DEG, 441, 0.3, 120.0, rate_hz=25.0),
}


def sensor_poses(
    front_x_m: ArrayLike, front_y_m: ArrayLike, yaw_rad: ArrayLike, config: LaserConfig
) -> tuple[FloatArray, FloatArray]:
    """World poses of sensors mounted per ``config`` on vehicles at the given bumper poses.

    Returns ``(origins (K, 2), headings (K,))`` ready for ``scan_many``.
    """
    x = np.atleast_1d(np.asarray(front_x_m, dtype=np.float64))
    y = np.atleast_1d(np.asarray(front_y_m, dtype=np.float64))
    yaw = np.atleast_1d(np.asarray(yaw_rad, dtype=np.float64))
    c, s = np.cos(yaw), np.sin(yaw)
    origins = np.column_stack(
        (
            x + c * config.mount_x_m - s * config.mount_y_m,
            y + s * config.mount_x_m + c * config.mount_y_m,
        )
    )
    return origins, yaw + config.mount_yaw_rad


@dataclass(frozen=True)
class LaserScan:
    """One scan, with the fields of ROS ``sensor_msgs/LaserScan`` plus the sensor pose.

    ``ranges`` follows REP 117: ``+inf`` when nothing is hit within ``range_max``,
    ``-inf`` when the first surface hit is closer than ``range_min``, finite values in
    ``[range_min, range_max]`` otherwise. A dropout (no return, e.g. a dark or glossy
    surface) is ``NaN``. The synthetic scan is instantaneous: ``time_increment`` is 0.
    Intensities are omitted.
    """

    angle_min: float
    angle_max: float
    angle_increment: float
    time_increment: float
    scan_time: float
    range_min: float
    range_max: float
    ranges: FloatArray = field(repr=False)
    origin_x_m: float
    origin_y_m: float
    heading_rad: float
    stamp_s: float = 0.0
    hit_labels: IntArray | None = field(default=None, repr=False)
    """Ground truth per ray (not part of the ROS message): the row of the footprint
    array the scan was cast against whose surface the reading comes from; rows past the
    footprints are wall segments; -1 where nothing returned (``+inf`` or a dropout)."""
    predecessor_rays: int | None = None
    """Ground truth: rays that returned from the vehicle's platoon predecessor (None
    without one)."""

    @classmethod
    def from_ranges(
        cls,
        config: LaserConfig,
        ranges: ArrayLike,
        origin: ArrayLike,
        heading_rad: float,
        stamp_s: float = 0.0,
        hit_labels: IntArray | None = None,
        predecessor_rays: int | None = None,
    ) -> LaserScan:
        """Wrap a row of ``cast_rays``/``scan_many`` output with its metadata."""
        r = np.asarray(ranges, dtype=np.float64)
        if r.shape != (config.samples,):
            raise ValueError(f"ranges: expected shape ({config.samples},), got {r.shape}")
        ox, oy = (float(v) for v in np.asarray(origin, dtype=np.float64).reshape(2))
        return cls.unchecked(
            config, r, ox, oy, float(heading_rad), float(stamp_s), hit_labels, predecessor_rays
        )

    @classmethod
    def unchecked(
        cls,
        config: LaserConfig,
        ranges: FloatArray,
        origin_x_m: float,
        origin_y_m: float,
        heading_rad: float,
        stamp_s: float,
        hit_labels: IntArray | None,
        predecessor_rays: int | None,
    ) -> LaserScan:
        """``from_ranges`` without its checks and conversions, for the sensor's hot path:
        `ranges` is a float64 row of ``config.samples`` readings, the rest plain floats."""
        return frozen_from_dict(cls, {
            "angle_min": config.angle_min_rad,
            "angle_max": config.angle_max_rad,
            "angle_increment": config.angle_increment_rad,
            "time_increment": 0.0,
            "scan_time": config.scan_time_s,
            "range_min": config.range_min_m,
            "range_max": config.range_max_m,
            "ranges": ranges,
            "origin_x_m": origin_x_m,
            "origin_y_m": origin_y_m,
            "heading_rad": heading_rad,
            "stamp_s": stamp_s,
            "hit_labels": hit_labels,
            "predecessor_rays": predecessor_rays,
        })  # fmt: skip

    @property
    def angles(self) -> FloatArray:
        """Sensor-frame angle of each ray [rad]."""
        i = np.arange(self.ranges.size, dtype=np.float64)
        return self.angle_min + i * self.angle_increment

    def points_world(self) -> FloatArray:
        """Hit points (valid readings only) in world coordinates, shape (H, 2) [m]."""
        valid = np.isfinite(self.ranges)
        a = self.heading_rad + self.angles[valid]
        r = self.ranges[valid]
        points = np.column_stack((self.origin_x_m + r * np.cos(a), self.origin_y_m + r * np.sin(a)))
        return points.astype(np.float64, copy=False)
