"""Paths stacked for the loop's all-member kernels, against each path's own methods."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from platoon_sumo.loop.paths import PathStack
from platoon_sumo.loop.progress import RouteProgress
from tests.test_path import circle_path, lane_change_path

PATHS = (circle_path(20.0, spacing_m=0.3), lane_change_path(), circle_path(35.0, spacing_m=0.5))


def test_stack_numbers_paths_once_and_restacks_when_one_comes() -> None:
    stack = PathStack()
    assert [stack.number(p) for p in (PATHS[1], PATHS[0], PATHS[1])] == [0, 1, 0]
    xy, starts = stack.stacked("xy", lambda p: p.xy_m)
    np.testing.assert_array_equal(xy[starts[0] : starts[1]], PATHS[1].xy_m)
    np.testing.assert_array_equal(xy[starts[1] : starts[2]], PATHS[0].xy_m)
    assert stack.stacked("xy", lambda p: p.xy_m)[0] is xy  # kept
    assert stack.number(PATHS[2]) == 2
    xy, starts = stack.stacked("xy", lambda p: p.xy_m)
    assert len(starts) == 4
    np.testing.assert_array_equal(xy[starts[2] : starts[3]], PATHS[2].xy_m)


member = st.tuples(
    st.integers(0, len(PATHS) - 1), st.floats(-30.0, 200.0), st.floats(-30.0, 60.0),
    st.floats(-20.0, 300.0), st.floats(0.0, 60.0),
)  # fmt: skip


@settings(max_examples=200, deadline=None)
@given(st.lists(member, min_size=1, max_size=8))
def test_all_members_projected_at_once_as_each_path_projects_them(members) -> None:
    """`RouteProgress`'s one kernel call gives each member's `project_sl`, bit for bit."""
    path_of, x, y, hint, window = (np.array(c) for c in zip(*members, strict=True))
    progress = RouteProgress()
    numbers = np.array([progress._paths.number(PATHS[k]) for k in path_of.tolist()])
    s, lateral = progress._project(numbers, x, y, hint, window)
    for k, (p, xk, yk, hk, wk) in enumerate(members):
        assert (s[k], lateral[k]) == PATHS[p].project_sl(xk, yk, hk, wk)
