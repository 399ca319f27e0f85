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
