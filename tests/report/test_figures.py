"""The report's figures, drawn from synthetic tables: platoons told apart on the map,
and panels without data saying so (issue 15)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from platoon_sumo.report import figures

PLATOONS = {"east": 3, "north": 2}  # platoon id -> members


def trajectories(platoons: dict[str, int] = PLATOONS, steps: int = 20) -> pd.DataFrame:
    """Straight parallel paths, one platoon per row of the grid, 5 m between members."""
    rows = []
    for k, (pid, members) in enumerate(platoons.items()):
        for i in range(members):
            for t in range(steps):
                rows.append({
                    "time_s": 0.1 * t, "vehicle_id": f"{pid}.{i}", "platoon_id": pid,
                    "member_index": i, "role": "leader" if i == 0 else "follower",
                    "x_m": 1.0 * t - 5.0 * i, "y_m": 20.0 * k, "speed_mps": 10.0,
                    "accel_mps2": 0.1 * np.sin(t), "route_s_m": 1.0 * t - 5.0 * i,
                    "spacing_error_m": np.nan if i == 0 else 0.01 * t, "supervisor": "",
                })  # fmt: skip
    return pd.DataFrame(rows)


def test_each_platoon_has_its_own_colours_and_a_legend_entry():
    traj = trajectories()
    fig = figures.network_map_figure(traj, None)
    ax = fig.axes[0]
    colours: dict[str, set[tuple[float, ...]]] = {pid: set() for pid in PLATOONS}
    for line in ax.get_lines():
        y_m = float(np.asarray(line.get_ydata())[0])
        pid = list(PLATOONS)[round(y_m / 20.0)]  # the row of its platoon
        colours[pid].add(tuple(np.round(line.get_color(), 6)))
    assert all(colours.values())
    assert not set.intersection(*colours.values())  # no colour shared between platoons
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert len(legend) == len(PLATOONS)
    for pid, text in zip(sorted(PLATOONS), legend, strict=True):
        assert f"platoon {pid}" in text and f"leader {pid}.0" in text


def test_the_leader_is_drawn_thicker_than_its_followers():
    traj = trajectories()
    ax = figures.network_map_figure(traj, None).axes[0]
    paths = [line for line in ax.get_lines() if len(line.get_xdata()) > 1]
    leader_lines = [line.get_linewidth() for line in paths if line.get_xdata()[0] == 0.0]
    follower_lines = [line.get_linewidth() for line in paths if line.get_xdata()[0] < 0.0]
    assert min(leader_lines) > max(follower_lines)


def test_platoon_colours_shade_members_of_one_hue():
    colours = figures.platoon_colors(trajectories())
    assert list(colours) == sorted(PLATOONS)
    for pid, members in colours.items():
        assert list(members) == [f"{pid}.{i}" for i in range(PLATOONS[pid])]
        brightness = [sum(c) for c in members.values()]
        assert brightness == sorted(brightness)  # paler down the platoon


# -- panels without data say so ---------------------------------------------------------


def vehicle_table(traj: pd.DataFrame) -> pd.DataFrame:
    """Per-member metrics as the run writes them: a leader has no spacing error or gain."""
    members = traj.groupby("vehicle_id").first().reset_index()
    follower = members["member_index"] > 0
    return pd.DataFrame({
        "vehicle_id": members["vehicle_id"], "platoon_id": members["platoon_id"],
        "member_index": members["member_index"], "rms_accel_mps2": 0.2,
        "max_abs_spacing_error_m": np.where(follower, 0.5, np.nan),
        "rms_spacing_error_m": np.where(follower, 0.3, np.nan),
        "accel_l2_gain": np.where(follower, 0.9, np.nan),
    })  # fmt: skip


def texts(ax) -> list[str]:
    return [t.get_text() for t in ax.texts]


def assert_not_available(ax) -> None:
    """A centred "n/a: why" note, nothing drawn, no value ticks."""
    notes = [t for t in ax.texts if t.get_text().startswith("n/a:")]
    assert len(notes) == 1, texts(ax)
    assert notes[0].get_position() == (0.5, 0.5) and notes[0].get_transform() == ax.transAxes
    assert notes[0].get_text().strip() != "n/a:"  # says why
    assert not ax.patches and not ax.get_lines()
    assert len(ax.get_yticks()) == 0


def test_compare_bars_of_one_car_runs_say_n_a_instead_of_bars_of_zero():
    lone = trajectories({"solo": 1})
    table = pd.DataFrame({"run": ["a", "b"], "max_rms_spacing_error_m": [np.nan, np.nan],
                          "max_rms_accel_mps2": [0.2, 0.3]})  # fmt: skip
    assert len(lone) and table["max_rms_spacing_error_m"].isna().all()
    metrics = (("max_rms_spacing_error_m", "RMS spacing error [m]"), ("min_gap_m", "min gap [m]"),
               ("max_rms_accel_mps2", "RMS accel. [m/s²]"))  # fmt: skip
    fig = figures.compare_bars_figure(table, metrics)
    empty_a, empty_b, filled = fig.axes
    for ax in (empty_a, empty_b):  # all NaN, and a column the table lacks
        assert_not_available(ax)
        assert len(ax.get_xticks()) == 0
    assert len(filled.patches) == len(table) and not any("n/a" in t for t in texts(filled))


def test_a_run_without_the_metric_gets_n_a_where_its_bar_would_be():
    table = pd.DataFrame({"run": ["a", "b", "c"], "min_gap_m": [4.0, np.nan, 6.0]})
    (ax,) = figures.compare_bars_figure(table, (("min_gap_m", "min gap [m]"),)).axes
    missing = table["min_gap_m"].isna().to_numpy()
    notes = [t for t in ax.texts if t.get_text() == "n/a"]
    assert [t.get_position()[0] for t in notes] == list(np.flatnonzero(missing))
    heights = [p.get_height() for p in ax.patches]
    assert np.array_equal(np.isnan(heights), missing)  # no bar of zero


def test_string_stability_of_a_lone_leader_says_n_a_along_the_platoon():
    traj = trajectories({"solo": 1})
    fig = figures.string_stability_figure(traj, vehicle_table(traj), "solo")
    accel, along = fig.axes
    assert len(accel.get_lines()) == 1
    assert_not_available(along)


def test_string_stability_with_followers_draws_their_bars():
    traj = trajectories()
    fig = figures.string_stability_figure(traj, vehicle_table(traj), "east")
    _, along = fig.axes
    assert len(along.patches) == 2 * PLATOONS["east"]
    assert sum(t.startswith("\u03b3=") for t in texts(along)) == PLATOONS["east"] - 1


def test_spacing_panel_of_a_lone_leader_says_n_a_and_keeps_the_shared_time_axis():
    traj = trajectories({"solo": 1})
    speed, spacing = figures.spacing_and_speed_figure(traj, "solo").axes
    assert_not_available(spacing)
    assert len(spacing.get_xticks()) > 0  # the speed panel's time axis
    assert len(speed.get_lines()) == 1


def test_compare_along_one_car_runs_says_n_a_in_both_panels():
    traj = trajectories({"solo": 1})
    runs = [("a", vehicle_table(traj)), ("b", vehicle_table(traj))]
    for ax in figures.compare_along_figure(runs).axes:
        assert_not_available(ax)


def test_compare_along_draws_the_runs_with_followers():
    traj = trajectories()
    gain, spacing = figures.compare_along_figure([("a", vehicle_table(traj))]).axes
    assert len(gain.get_lines()) > len(PLATOONS)  # the runs' lines and the gain-1 line
    assert len(spacing.get_lines()) == len(PLATOONS)
