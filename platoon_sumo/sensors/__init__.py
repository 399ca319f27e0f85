"""Sensors: the planar laser scanner (configuration, exact batched ray casting, plots)."""

from platoon_sumo.sensors.laser import LASER_PRESETS, LaserConfig, LaserScan, sensor_poses
from platoon_sumo.sensors.plot import plot_scan
from platoon_sumo.sensors.raycast import apply_noise, cast_rays, scan_many

__all__ = [
    "LASER_PRESETS",
    "LaserConfig",
    "LaserScan",
    "apply_noise",
    "cast_rays",
    "plot_scan",
    "scan_many",
    "sensor_poses",
]
