"""Summaries on hand-built trajectories with known answers (docs/metrics.md)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from platoon_sumo.events import EVENT_COLUMNS, WALL, Event, EventKind
from platoon_sumo.metrics import summarise_trajectories
from platoon_sumo.metrics.stats import (
    PlatoonStats,
    RunStats,
    peak_error_ratios,
    platoon_summary,
)

DT = 0.1


def platoon_table(
    n_steps: int = 50, gain: float = 0.5, lost: tuple[int, ...] = (10, 11)
) -> pd.DataFrame:
    """Three members on a straight road. The leader's acceleration is a(t) = sin(t); each
    follower's is `gain` times its predecessor's, sample by sample, so every l2 gain is
    exactly `gain`. Gaps and desired gaps are set to give known spacing errors; p.2's
    scans miss p.1 at the steps `lost`."""
    rows = []
    for k in range(n_steps):
        t = k * DT
        a0 = math.sin(t)
        for i in range(3):
            accel = a0 * gain**i
            speed = 10.0 + accel  # a speed signal with the same gain structure
            row = dict(
                time_s=t, vehicle_id=f"p.{i}", platoon_id="p", member_index=i,
                role="leader" if i == 0 else "follower", x_m=100.0 - 20.0 * i + k,
                y_m=0.0, speed_mps=speed, accel_mps2=accel,
                jerk_mps3=None if k == 0 else (accel - math.sin(t - DT) * gain**i) / DT,
                lateral_deviation_m=None, predecessor_rays=None, supervisor=None,
            )  # fmt: skip
            if i > 0:
                error = (1.0 if k % 2 else -1.0) * i  # |e| = i: rms i, peak i
                row.update(
                    predecessor_id=f"p.{i - 1}", desired_gap_m=15.0,
                    gap_to_predecessor_m=15.0 + error, ttc_s=4.0 + i + k,
                    time_gap_s=1.5 + k * 0.01, lateral_deviation_m=0.1 * i,
                    predecessor_rays=0 if (i == 2 and k in lost) else 5,
                    predecessor_in_view=0 if (i == 2 and k in lost) else 1,
                )  # fmt: skip
            rows.append(row)
    return pd.DataFrame(rows)


def test_vehicle_summaries_have_the_known_values():
    stats = summarise_trajectories(platoon_table(), planned={"p": 3})
    v = {s["vehicle_id"]: s for s in stats.vehicle_summaries()}
    for i in (1, 2):
        s = v[f"p.{i}"]
        assert s["rms_spacing_error_m"] == pytest.approx(i)
        assert s["max_abs_spacing_error_m"] == pytest.approx(i)
        assert s["min_gap_m"] == pytest.approx(15.0 - i)
        assert s["min_ttc_s"] == pytest.approx(4.0 + i)
        assert s["min_time_gap_s"] == pytest.approx(1.5)
        assert s["rms_lateral_deviation_m"] == pytest.approx(0.1 * i)
        assert s["max_lateral_deviation_m"] == pytest.approx(0.1 * i)
        assert s["accel_l2_gain"] == pytest.approx(0.5)
        assert s["speed_l2_gain"] == pytest.approx(0.5)
        assert s["saturated_share"] == 0.0
    t = np.arange(50) * DT
    assert v["p.0"]["rms_accel_mps2"] == pytest.approx(np.sqrt(np.mean(np.sin(t) ** 2)))
    jerk = np.diff(np.sin(t)) / DT
    assert v["p.0"]["rms_jerk_mps3"] == pytest.approx(np.sqrt(np.mean(jerk**2)))
    assert v["p.0"]["accel_l2_gain"] is None  # the leader has no predecessor
    assert v["p.1"]["in_view_share"] == 1.0
    assert v["p.2"]["in_view_share"] == pytest.approx(48 / 50)
    assert v["p.1"]["lost_scans"] == 0 and v["p.2"]["lost_scans"] == 2
    assert v["p.0"]["lost_scans"] is None and v["p.0"]["saturated_share"] is None
    # the leader's speed 10 + sin(t) over t = 0 .. 4.9, as p.1 saw it
    assert v["p.1"]["predecessor_speed_std_mps"] == pytest.approx(np.std(np.sin(t)))


def test_platoon_summary_string_stability_and_intactness():
    stats = summarise_trajectories(platoon_table(gain=0.5, lost=()), planned={"p": 3})
    (p,) = stats.platoon_summaries()
    assert p["max_accel_l2_gain"] == pytest.approx(0.5)
    assert p["string_stable"] is True and p["string_stability_verdict"] == "stable"
    assert p["max_saturated_share"] == 0.0
    # peak |e|: 1 for p.1, 2 for p.2
    assert p["max_spacing_error_peak_ratio"] == pytest.approx(2.0)
    assert p["intact_share"] == 1.0
    assert p["splits"] == 0  # splits are events of the loop, not read from the rows
    assert p["min_gap_m"] == pytest.approx(13.0)
    unstable = summarise_trajectories(platoon_table(gain=1.5, lost=())).platoon_summaries()[0]
    assert unstable["max_accel_l2_gain"] == pytest.approx(1.5)
    assert unstable["string_stable"] is False
    assert unstable["string_stability_verdict"] == "unstable"


def test_followers_before_their_first_scan_do_not_break_the_platoon():
    """On a platoon's first step the followers have no scan yet (predecessor_in_view
    empty): not a lost view, so a platoon that then always sees is intact and stable."""
    table = platoon_table(gain=0.5, lost=())
    first = (table.time_s == 0.0) & (table.member_index > 0)
    table.loc[first, ["predecessor_rays", "predecessor_in_view"]] = np.nan
    (p,) = summarise_trajectories(table, planned={"p": 3}).platoon_summaries()
    assert p["intact_share"] == 1.0
    assert p["string_stability_verdict"] == "stable"
    # a follower without a laser at all: no intactness to report
    table.loc[table.member_index > 0, ["predecessor_rays", "predecessor_in_view"]] = np.nan
    (p,) = summarise_trajectories(table, planned={"p": 3}).platoon_summaries()
    assert p["intact_share"] is None


def test_a_platoon_that_split_is_not_string_stable():
    """p.2 misses p.1 on two scans: whatever the gains, the platoon was not intact."""
    (p,) = summarise_trajectories(platoon_table(gain=0.5), planned={"p": 3}).platoon_summaries()
    assert p["intact_share"] == pytest.approx(48 / 50)
    assert p["max_accel_l2_gain"] == pytest.approx(0.5)
    assert p["string_stable"] is None and p["string_stability_verdict"] == "split"
    # a planned member that never drove
    (p,) = summarise_trajectories(platoon_table(lost=()), planned={"p": 4}).platoon_summaries()
    assert p["string_stable"] is None and p["string_stability_verdict"] == "split"


def test_lost_scans_count_from_the_first_scan_even_if_the_predecessor_is_never_seen():
    stats = RunStats()
    for k in range(6):
        stats.add_step(k * DT, dict(
            vehicle_id=["p.0", "p.1"], platoon_id=["p", "p"], member_index=[0, 1],
            role=["leader", "follower"], predecessor_id=[None, "p.0"],
            predecessor_rays=[None, None if k == 0 else 0],  # no scan yet at k = 0
        ))  # fmt: skip
    follower = stats.vehicle_summaries()[1]
    assert follower["in_view_share"] == 0.0 and follower["lost_scans"] == 5
    assert stats.followers()["p"]["p.1"]["lost_scans"] == 5


def test_saturated_share_counts_supervisor_steps_and_steps_at_the_vehicle_limits():
    stats = RunStats(limits={"p": (3.0, 8.0, 25.0)})
    rows = [  # the follower's (acceleration, speed, supervisor state): 4 of 6 saturated
        (1.0, 15.0, None), (3.0, 15.3, None), (-8.0, 14.5, None), (0.5, 15.0, None),
        (0.0, 25.0, None), (0.0, 15.0, "emergency"),
    ]  # fmt: skip
    for k, (accel, speed, supervisor) in enumerate(rows):
        stats.add_step(k * DT, dict(
            vehicle_id=["p.0", "p.1"], platoon_id=["p", "p"], member_index=[0, 1],
            predecessor_id=[None, "p.0"], accel_mps2=[3.0, accel], speed_mps=[15.0, speed],
            supervisor=[None, supervisor],
        ))  # fmt: skip
    leader, follower = stats.vehicle_summaries()
    assert follower["saturated_share"] == pytest.approx(4 / 6)
    assert leader["saturated_share"] is None  # only followers are judged


def test_metrics_window_and_event_counts():
    stats = summarise_trajectories(platoon_table(), start_s=2.0)
    s = {v["vehicle_id"]: v for v in stats.vehicle_summaries()}["p.1"]
    assert s["steps"] == 30  # t = 2.0 .. 4.9
    stats.add_events([
        Event(0.1, EventKind.EMERGENCY_BRAKING, "p.1", platoon_id="p"),
        Event(3.0, EventKind.EMERGENCY_BRAKING, "p.1", platoon_id="p"),
        Event(3.2, EventKind.COLLISION, "p.1", "bg7", "p", at_fault="bg7"),
        Event(3.3, EventKind.WALL_CONTACT, "p.2", WALL, "p", at_fault="p.2"),
        Event(3.4, EventKind.RED_LIGHT, "p.2", "tls", "p", "link 3 r"),
        Event(3.5, EventKind.CUT_IN, "p.2", "bg1", "p"),
        Event(3.6, EventKind.SPLIT, "p.2", "p.1", "p"),
        Event(3.7, EventKind.SPLIT, "p.2", "p.1", "p"),
        Event(3.8, EventKind.SUMO_SPEED_CAP, "p.1", platoon_id="p"),
    ])  # fmt: skip
    s = {v["vehicle_id"]: v for v in stats.vehicle_summaries()}
    assert s["p.1"]["emergency_brakings"] == 2  # events count over the whole run
    assert s["p.1"]["collisions"] == 1 and s["p.2"]["collisions"] == 1
    assert s["p.1"]["collisions_at_fault"] == 0 and s["p.2"]["collisions_at_fault"] == 1
    assert s["p.2"]["red_light_violations"] == 1 and s["p.1"]["red_light_violations"] == 0
    assert s["p.2"]["cut_ins"] == 1 and s["p.1"]["cut_ins"] == 0
    (platoon,) = stats.platoon_summaries()
    assert platoon["splits"] == 2 and platoon["cut_ins"] == 1 and platoon["collisions"] == 2
    assert platoon["collisions_at_fault"] == 1


def test_a_split_before_the_metrics_window_does_not_judge_the_platoon():
    """Members that drifted apart during the warm-up and closed up again are judged on
    the window only; the split still counts among the run's events."""
    stats = summarise_trajectories(platoon_table(lost=()), planned={"p": 3}, start_s=2.0)
    stats.add_events([Event(1.0, EventKind.SPLIT, "p.2", "p.1", "p")])
    (p,) = stats.platoon_summaries()
    assert p["splits"] == 1 and p["string_stability_verdict"] == "stable"
    stats.add_events([Event(2.5, EventKind.SPLIT, "p.2", "p.1", "p")])
    (p,) = stats.platoon_summaries()
    assert p["splits"] == 2 and p["string_stability_verdict"] == "split"


def test_peak_ratios_leave_out_the_remnants_of_a_damped_disturbance():
    peaks = [2.0, 0.05, 0.4, 0.2]  # p.2 damped the disturbance to 2.5 % of p.1's
    members = [{"member_index": i + 1, "max_abs_spacing_error_m": e} for i, e in enumerate(peaks)]
    assert peak_error_ratios(members) == [pytest.approx(0.025), None, pytest.approx(0.5)]


def test_offline_summary_reads_the_events_table():
    events = pd.DataFrame(
        [
            (0.5, "cut_in", "p.1", "bg1", "p", "", ""),
            (0.7, "split", "p.2", "p.1", "p", "", ""),
            (0.9, "collision", "p.2", "bg3", "p", "closing faster", "p.2"),
        ],
        columns=list(EVENT_COLUMNS),
    )
    stats = summarise_trajectories(platoon_table(), events=events)
    (platoon,) = stats.platoon_summaries()
    assert platoon["splits"] == 1 and platoon["cut_ins"] == 1
    assert platoon["collisions"] == 1 and platoon["collisions_at_fault"] == 1
    # a table written before the at_fault column still reads
    old = summarise_trajectories(platoon_table(), events=events.drop(columns="at_fault"))
    assert old.platoon_summaries()[0]["collisions_at_fault"] == 0


def test_gap_measurement_error_compares_with_the_previous_true_gap():
    stats = RunStats()
    for k, (gap, measured) in enumerate([(10.0, None), (11.0, 10.5), (12.0, 11.5)]):
        stats.add_step(k * DT, dict(
            vehicle_id=["p.1"], platoon_id=["p"], member_index=[1], role=["follower"],
            predecessor_id=["p.0"], gap_to_predecessor_m=[gap], measured_gap_m=[measured],
        ))  # fmt: skip
    # measured at the start of steps 1 and 2 vs the true gaps 10 and 11: errors 0.5, 0.5
    assert stats.vehicle_summaries()[0]["rms_gap_measurement_error_m"] == pytest.approx(0.5)


def test_platoon_summary_without_followers_has_no_stability_figure():
    p = platoon_summary(PlatoonStats("solo", 1), [dict(
        vehicle_id="solo.0", member_index=0, accel_l2_gain=None, speed_l2_gain=None,
        max_abs_spacing_error_m=None, rms_spacing_error_m=None, min_gap_m=None, min_ttc_s=None,
        rms_accel_mps2=0.3, rms_jerk_mps3=1.0, max_lateral_deviation_m=None, cut_ins=0,
        collisions=0, collisions_at_fault=0, emergency_brakings=0, red_light_violations=0,
        v2v_sent=None, v2v_received=None, v2v_lost=None,
    )])  # fmt: skip
    assert p["max_accel_l2_gain"] is None and p["string_stable"] is None
    assert p["string_stability_verdict"] == "no followers"
    assert p["intact_share"] is None
