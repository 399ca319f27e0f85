"""Red-light bookkeeping: which changes of the signal ahead mean a stop line was crossed."""

from __future__ import annotations

from platoon_sumo.loop.progress import crossed_stop_line
from platoon_sumo.world import SignalAhead


def test_the_line_within_the_distance_just_travelled_was_crossed():
    red = SignalAhead("tls", 1, "r", 0.8)
    assert crossed_stop_line(red, None, travelled_m=1.1)
    assert crossed_stop_line(red, SignalAhead("next_tls", 0, "G", 180.0), travelled_m=1.1)


def test_the_same_light_still_ahead_was_not_crossed():
    assert not crossed_stop_line(
        SignalAhead("tls", 1, "r", 0.8), SignalAhead("tls", 1, "r", 0.1), travelled_m=0.7
    )


def test_a_lane_change_that_puts_another_link_of_the_light_ahead_is_no_crossing():
    # 17 m before a red light the vehicle moves to the next lane, whose link has index 2
    before = SignalAhead("tls", 1, "r", 17.5)
    after = SignalAhead("tls", 2, "r", 16.6)
    assert not crossed_stop_line(before, after, travelled_m=0.9)
    # ... and a vehicle standing at the line while the link ahead changes has not crossed
    assert not crossed_stop_line(SignalAhead("tls", 1, "r", 0.5), after, travelled_m=0.0)
