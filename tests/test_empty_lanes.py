"""`EmptyLanes` on a made-up lane graph: which junction lanes are known empty from the
lanes that were empty a step before (the world read's use of it is checked against
SUMO in `test_neighbours.py`)."""

from __future__ import annotations

from platoon_sumo.sumo.empty_lanes import EmptyLanes


class _Lanes:
    """libsumo's lane domain for a graph of lanes: links (successor, via), lengths,
    allowed classes."""

    def __init__(self, links, lengths, allowed=None):
        self.links, self.lengths, self.allowed = links, lengths, allowed or {}

    def getLinks(self, lane):
        return [
            (succ, True, True, False, via, "M", "s", 0.0) for succ, via in self.links.get(lane, [])
        ]

    def getLength(self, lane):
        return self.lengths[lane]

    def getAllowed(self, lane):
        return self.allowed.get(lane, ("passenger",))


# road a enters junction J on :J_0_0 (short, 0.5 m), then :J_1_0 (an internal junction
# inside J), to road b; road c enters on :J_2_0 and :J_2_1, one internal edge of two
# lanes, to road d; road e (before a) is 100 m long
LINKS = {
    "e_0": [("a_0", "")],
    "a_0": [("b_0", ":J_0_0")],
    ":J_0_0": [(":J_1_0", "")],
    ":J_1_0": [("b_0", "")],
    "c_0": [("d_0", ":J_2_0"), ("d_1", ":J_2_1")],
    ":J_2_0": [("d_0", "")],
    ":J_2_1": [("d_1", "")],
}
LENGTHS = {
    "e_0": 100.0, "a_0": 0.8, ":J_0_0": 0.5, ":J_1_0": 6.0, "b_0": 50.0, "c_0": 40.0,
    ":J_2_0": 9.0, ":J_2_1": 9.5, "d_0": 50.0, "d_1": 50.0,
}  # fmt: skip
LANES = tuple(LENGTHS)


def _empty_now(lanes, empty_before, lane, drive_m=1.4, classes=frozenset({"passenger"})):
    graph = EmptyLanes(lanes, LANES)
    graph.remember(0, set(empty_before))
    was_empty, _ = graph.known_empty(1, drive_m, classes)
    return lane in was_empty and graph.follows_empty(lane, was_empty)


def test_a_junction_lane_is_empty_when_it_and_every_lane_leading_in_were():
    lanes = _Lanes(LINKS, LENGTHS)
    assert _empty_now(lanes, {":J_2_0", ":J_2_1", "c_0"}, ":J_2_0")
    # a vehicle on the road leading in, or on the lane beside it on the junction edge
    assert not _empty_now(lanes, {":J_2_0", ":J_2_1"}, ":J_2_0")
    assert not _empty_now(lanes, {":J_2_0", "c_0"}, ":J_2_0")
    # nor when it was not known empty itself
    assert not _empty_now(lanes, {":J_2_1", "c_0"}, ":J_2_0")


def test_lanes_shorter_than_a_step_s_drive_let_vehicles_from_further_back_in():
    """:J_1_0 follows :J_0_0 (0.5 m), which follows road a (0.8 m): a vehicle drives
    1.4 m a step, so one on road e, before a, may reach :J_1_0 within the step."""
    lanes = _Lanes(LINKS, LENGTHS)
    near = {":J_1_0", ":J_0_0", "a_0"}
    assert not _empty_now(lanes, near, ":J_1_0", drive_m=1.4)
    assert _empty_now(lanes, near | {"e_0"}, ":J_1_0", drive_m=1.4)
    # a slow network: 0.5 m a step does not cross a (0.8 m) and the slack
    assert _empty_now(lanes, near, ":J_1_0", drive_m=0.5)


def test_roads_and_lanes_open_to_trains_are_always_asked():
    """Vehicles are inserted on roads; a tram may reverse onto a lane, once trams drive."""
    lanes = _Lanes(LINKS, LENGTHS, {":J_2_0": ("passenger", "tram")})
    everything = set(LANES)
    assert not _empty_now(lanes, everything, "b_0")
    assert _empty_now(lanes, everything, ":J_2_0")
    with_trams = frozenset({"passenger", "tram"})
    assert not _empty_now(lanes, everything, ":J_2_0", classes=with_trams)
    assert _empty_now(lanes, everything, ":J_2_1", classes=with_trams)


def test_what_a_read_found_is_forgotten_after_a_step_without_one():
    graph = EmptyLanes(_Lanes(LINKS, LENGTHS), LANES)
    graph.remember(3, set(LANES))
    cars = frozenset({"passenger"})
    assert graph.known_empty(3, 1.4, cars)[0] == set(LANES)  # this step's, read again
    assert graph.known_empty(4, 1.4, cars)[0] == set(LANES)  # the step before
    assert graph.known_empty(5, 1.4, cars)[0] == set()  # a step without a read in between
