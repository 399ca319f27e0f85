"""Step hooks that write a run's tables: the platoon trajectories, in bounded chunks.

Columns of trajectories.csv (one row per platoon vehicle per step, after the step):

| column | unit | meaning |
|---|---|---|
| time_s | s | simulation time |
| vehicle_id, platoon_id | | `<platoon>.<index>` and the platoon's id |
| member_index, role | | 0 = leader; `leader` / `follower` |
| x_m, y_m | m | front bumper centre (SUMO's reference point), network coordinates |
| yaw_rad | rad | heading, counter-clockwise from +x |
| speed_mps, accel_mps2 | m/s, m/s² | vehicle model's speed and its change over the step |
| cmd_speed_mps, cmd_yaw_rate_radps | m/s, rad/s | the controller's command this step |
| route_s_m | m | front bumper's distance along the route's centre-line |
| lateral_offset_m | m | front bumper's offset from the route centre-line (left +) |
| lane_width_m | m | width of the lane the route uses there |
| lane_id | | lane SUMO maps the vehicle to |
| signal_tls, signal_state | | next traffic light on the route and its link state |
| signal_distance_m | m | distance from the front bumper to that light's stop line |
| ahead_id, ahead_gap_m | -, m | nearest vehicle ahead on the route lanes; bumper-to-bumper gap |
| predecessor_id | | platoon member ahead (empty for the first member in the network) |
| gap_to_predecessor_m | m | front-bumper centre to predecessor's rear-bumper centre (truth) |
| desired_gap_m | m | the follower controller's spacing policy at its speed (if it has one) |
| predecessor_rays | | rays of this step's scan returning from the predecessor (empty: no scan) |
| supervisor | | what the supervisor enforced over the command: `signal`, `emergency`, or empty |
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from platoon_sumo.cosim import CoSimulation, PlatoonVehicle, StepRecord

TRAJECTORY_COLUMNS = (
    "time_s", "vehicle_id", "platoon_id", "member_index", "role", "x_m", "y_m", "yaw_rad",
    "speed_mps", "accel_mps2", "cmd_speed_mps", "cmd_yaw_rate_radps", "route_s_m",
    "lateral_offset_m", "lane_width_m", "lane_id", "signal_tls", "signal_state",
    "signal_distance_m", "ahead_id", "ahead_gap_m", "predecessor_id", "gap_to_predecessor_m",
    "desired_gap_m", "predecessor_rays", "supervisor",
)  # fmt: skip


class TrajectoryRecorder:
    """Appends one row per platoon vehicle per step; flushes every `chunk_rows` rows."""

    def __init__(self, path: Path, chunk_rows: int = 20_000):
        self.path = path
        self.chunk_rows = chunk_rows
        self._rows: list[tuple[Any, ...]] = []
        self.rows_written = 0

    def on_start(self, sim: CoSimulation) -> None:
        with self.path.open("w", newline="") as f:
            csv.writer(f).writerow(TRAJECTORY_COLUMNS)

    def on_step(self, sim: CoSimulation, record: StepRecord) -> None:
        world = record.world
        for v in record.vehicles:
            fx, fy = v.front_bumper()
            i = world.index.get(v.id)
            signal, ahead = v.signal, v.vehicle_ahead
            self._rows.append(
                (
                    round(record.time_s, 6), v.id, v.plan.platoon_id, v.plan.index, v.plan.role,
                    fx, fy, float(v.state.yaw_rad[0]), float(v.state.speed_mps[0]), v.accel_mps2,
                    v.command.speed_mps if math.isfinite(v.command.speed_mps) else "",
                    v.command.yaw_rate_radps, v.route_s_m, v.lateral_offset_m,
                    float(v.path.lane_width_m[min(int(v.route_s_m // v.path.spacing_m),
                                                  len(v.path.lane_width_m) - 1)]),
                    world.lane_ids[i] if i is not None else "",
                    signal.tls_id if signal else "", signal.state if signal else "",
                    signal.distance_m if signal else "",
                    ahead.vehicle_id if ahead else "", ahead.gap_m if ahead else "",
                    v.predecessor_id or "", _blank(v.gap_to_predecessor_m),
                    _blank(desired_gap(v)), _blank(v.predecessor_rays), v.supervisor_state,
                )
            )  # fmt: skip
        if len(self._rows) >= self.chunk_rows:
            self.flush()

    def flush(self) -> None:
        if self._rows:
            with self.path.open("a", newline="") as f:
                csv.writer(f).writerows(self._rows)
            self.rows_written += len(self._rows)
            self._rows.clear()

    def on_end(self, sim: CoSimulation) -> None:
        self.flush()


def desired_gap(v: PlatoonVehicle) -> float | None:
    """The follower controller's spacing policy at the vehicle's speed, if it declares one."""
    policy = getattr(v.controller, "desired_gap_m", None)
    if v.predecessor_id is None or not callable(policy):
        return None
    return float(policy(float(v.state.speed_mps[0])))


def _blank(value: float | int | None) -> float | int | str:
    return "" if value is None else value
