"""Split / re-formation / cut-in bookkeeping on hand-made observation sequences."""

from __future__ import annotations

from platoon_sumo.platoon import LinkMonitor, predecessor_ids


class M:
    def __init__(self, vid: str, platoon: str, index: int):
        self.id, self.platoon_id, self.index = vid, platoon, index


def feed(monitor: LinkMonitor, linked: list[bool], intruders=None, dt=0.5):
    intruders = intruders or [None] * len(linked)
    kinds = []
    for k, (ok, who) in enumerate(zip(linked, intruders, strict=True)):
        kinds += [e.kind for e in monitor.observe(k * dt, "p", "p.1", "p.0", ok, who)]
    return kinds


def test_start_up_is_formation_not_reformation():
    assert feed(LinkMonitor(hold_s=1.0), [False, False, True, True, True, True]) == []


def test_a_short_loss_is_not_a_split_but_a_held_one_is_and_reforms():
    assert feed(LinkMonitor(hold_s=1.0), [True] * 4 + [False] + [True] * 4) == []
    kinds = feed(LinkMonitor(hold_s=1.0), [True] * 4 + [False] * 4 + [True] * 4)
    assert kinds == ["split", "reformation"]


def test_each_intruder_counts_once():
    linked = [True] * 8
    intruders = [None, "bg1", "bg1", "bg1", None, "bg2", "bg2", "bg1"]
    assert feed(LinkMonitor(), linked, intruders) == ["cut_in", "cut_in", "cut_in"]


def test_predecessors_skip_members_that_left():
    members = [M("a.0", "a", 0), M("a.2", "a", 2), M("b.1", "b", 1), M("b.0", "b", 0)]
    assert predecessor_ids(members) == {"a.0": None, "a.2": "a.0", "b.0": None, "b.1": "b.0"}
