"""A user's actuation plug-in with a bug: lane actuation that fails at `CRASH_AT_S`.

Loaded as `crashing_actuator:CrashingLane` when the tests put this folder on sys.path.
"""

from __future__ import annotations

from typing import ClassVar

from platoon_sumo.actuation import ActuationBatch, ActuationPort, ActuationResult, LaneActuation

CRASH_AT_S = 1.5


class CrashingLane:
    sumo_drives: ClassVar[bool] = True
    steers: ClassVar[bool] = False

    def __init__(self) -> None:
        self.inner = LaneActuation()
        self.time_s = 0.0

    def apply(self, batch: ActuationBatch, sumo: ActuationPort) -> ActuationResult:
        self.time_s += batch.dt_s
        if self.time_s >= CRASH_AT_S:
            raise KeyError("lane_index")
        return self.inner.apply(batch, sumo)
