"""Platoon metrics on hand-built trajectories with known answers."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from platoon_sumo.metrics import follower_metrics


def table(rows: list[dict]) -> pd.DataFrame:
    columns = ["time_s", "vehicle_id", "platoon_id", "x_m", "y_m", "predecessor_id",
               "gap_to_predecessor_m", "desired_gap_m", "predecessor_rays"]  # fmt: skip
    return pd.DataFrame(rows, columns=columns)


def test_follower_metrics_on_a_straight_platoon_with_an_offset_follower():
    rows = []
    for k in range(10):
        t = float(k)
        rows.append(dict(time_s=t, vehicle_id="p.0", platoon_id="p", x_m=10.0 + k, y_m=0.0))
        # follower 0.3 m to the left of the leader's line, gap alternating 5 and 7 m (desired 6)
        rows.append(dict(time_s=t, vehicle_id="p.1", platoon_id="p", x_m=4.0 + k, y_m=0.3,
                         predecessor_id="p.0", gap_to_predecessor_m=5.0 if k % 2 else 7.0,
                         desired_gap_m=6.0,
                         predecessor_rays=0 if k in (0, 1, 5) else 12))  # fmt: skip
    m = follower_metrics(table(rows))["p"]["p.1"]
    assert m["steps"] == 10
    # first seen at k = 2; afterwards lost once (k = 5) in 8 scans (the in-view share)
    assert m["in_view_share"] == pytest.approx(7 / 8)
    assert m["lost_scans"] == 3  # from its first scan: k = 0, 1 (never yet seen) and 5
    assert m["min_gap_m"] == 5.0
    assert m["rms_spacing_error_m"] == pytest.approx(1.0)
    # the leader's path spans x 10..19: only follower points with 10 < x < 19 are beside it
    expected = [0.3 for k in range(10) if 10.0 < 4.0 + k < 19.0]
    assert m["max_lateral_deviation_m"] == pytest.approx(max(expected))
    assert m["rms_lateral_deviation_m"] == pytest.approx(np.sqrt(np.mean(np.square(expected))))


def test_leader_has_no_follower_metrics_and_missing_scans_give_none():
    rows = [dict(time_s=0.0, vehicle_id="p.0", platoon_id="p", x_m=0.0, y_m=0.0),
            dict(time_s=0.0, vehicle_id="p.1", platoon_id="p", x_m=-5.0, y_m=0.0,
                 predecessor_id="p.0", gap_to_predecessor_m=4.0)]  # fmt: skip
    m = follower_metrics(table(rows))
    assert list(m["p"]) == ["p.1"]
    assert m["p"]["p.1"]["in_view_share"] is None
    assert m["p"]["p.1"]["rms_spacing_error_m"] is None


def test_run_totals_are_correctly_rounded_so_every_python_writes_the_same_digits():
    # the built-in sum adds floats naively before Python 3.12 and compensated since:
    # the summary's totals and means differed in their last digits between the two
    from platoon_sumo.metrics.tables import overall

    platoons = [{"fuel_kg": 0.1, "co2_kg": 0.1, "intact_share": 0.1} for _ in range(10)]
    totals = overall(platoons)
    assert totals["fuel_kg"] == totals["co2_kg"] == 1.0  # naively 0.9999999999999999
    assert totals["mean_intact_share"] == 0.1
