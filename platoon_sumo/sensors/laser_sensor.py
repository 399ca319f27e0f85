"""The planar laser scanner as a registered sensor model ("laser")."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from platoon_sumo.sensors.base import SENSORS, SensingBatch
from platoon_sumo.sensors.laser import LaserConfig, LaserScan, sensor_poses
from platoon_sumo.sensors.raycast import scan_many


@SENSORS.register("laser")
class LaserSensor:
    """Exact ray casting against the footprints and walls (see `raycast.py`); each scan
    carries the count of rays that returned from the vehicle's predecessor."""

    Params: ClassVar[type[LaserConfig]] = LaserConfig

    def __init__(self, params: LaserConfig):
        self.config = params

    @property
    def period_s(self) -> float:
        return 1.0 / self.config.rate_hz

    def observe(self, batch: SensingBatch) -> list[LaserScan]:
        laser = self.config
        origins, headings = sensor_poses(batch.front_x_m, batch.front_y_m, batch.yaw_rad, laser)
        ranges, hits = scan_many(
            origins, headings, laser, rectangles=batch.footprints,
            segments=batch.static_segments, exclude=batch.own_index, rng=batch.rng,
            return_hits=True,
        )  # fmt: skip
        # rays returning from the predecessor: a finite range (closer than range_min
        # reads -inf, no range) labelled with its row; counted for all scans at once
        pred = batch.predecessor_index
        on_pred = np.count_nonzero((hits == pred[:, None]) & np.isfinite(ranges), axis=1)
        rows = zip(
            origins.tolist(), headings.tolist(), pred.tolist(), on_pred.tolist(), strict=True
        )
        return [
            LaserScan.unchecked(
                laser, ranges[k], ox, oy, heading, batch.time_s, hits[k], on if p >= 0 else None
            )
            for k, ((ox, oy), heading, p, on) in enumerate(rows)
        ]
