"""Speed bounds every careful driver obeys, shared by controllers and the supervisor.

Pure functions of the situation, so a controller can plan with them comfortably and
the supervisor can enforce them as a last resort with the same arithmetic.
"""

from __future__ import annotations

import math

from platoon_sumo.kernels.supervision import safe_following_speed, stop_speed_limit
from platoon_sumo.world import SignalAhead

__all__ = ["safe_following_speed", "signal_speed_limit", "stop_speed_limit"]


def signal_speed_limit(
    signal: SignalAhead | None,
    speed_mps: float,
    dt_s: float,
    comfort_decel_mps2: float,
    yellow_max_decel_mps2: float,
    stop_margin_m: float,
) -> float:
    """Highest speed that still stops `stop_margin_m` before a red or yellow stop line
    (`stop_speed_limit`); `inf` where there is no light or it shows no stop."""
    if signal is None or not signal.is_stop:
        return math.inf
    return stop_speed_limit(
        signal.distance_m, signal.state == "y", speed_mps, dt_s, comfort_decel_mps2,
        yellow_max_decel_mps2, stop_margin_m,
    )  # fmt: skip
