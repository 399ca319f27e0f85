"""Standoffs at unsignalised junctions. SUMO's right of way can go round in a circle:
on rand1_priority (seed 43) the cars on one approach yielded to a platoon's leader,
which yielded to a car on a second approach, which yielded to the cars on the first;
with teleports off nobody moved again. A platoon car that SUMO holds at an
unsignalised link, while every vehicle it yields to stands still as well, takes the
junction after a while, as a human driver would (SUMO still keeps it behind vehicles
inside the junction)."""

from __future__ import annotations

from platoon_sumo.events import EventKind
from platoon_sumo.loop.context import StepContext
from platoon_sumo.loop.progress import at_light, link_ahead

#: A platoon car standing (below `STILL_MPS` [m/s]) this long [s] within `AT_LINK_M`
#: [m] of a closed unsignalised link takes the junction once every vehicle it yields
#: to has stood for `FOES_STILL_S` [s].
STANDOFF_S, STILL_MPS, AT_LINK_M, FOES_STILL_S = 20.0, 0.1, 3.0, 5.0
#: SUMO link states of unsignalised junctions where a car may have to yield: minor,
#: equal, stop sign, all-way stop.
UNSIGNALISED_YIELD = frozenset("m=sw")


class Standoffs:
    def __init__(self) -> None:
        self._since: dict[str, float] = {}
        """Per member: when it began to stand at a closed unsignalised link [s]."""
        self._taking: dict[str, str] = {}
        """Per member taking a junction: the lane it took it from."""

    def __call__(self, ctx: StepContext) -> None:
        world, now = ctx.world, ctx.world.time_s
        for vid in [v for v in (*self._since, *self._taking) if ctx.fleet.get(v) is None]:
            self._since.pop(vid, None)
            self._taking.pop(vid, None)
        for m in ctx.fleet:
            i = world.index.get(m.id)
            if i is None or not m.actuator.sumo_drives:
                continue
            lane = world.lane_ids[i]
            taken_from = self._taking.get(m.id)
            if taken_from is not None:
                if lane != taken_from and not lane.startswith(":"):  # across: yield again
                    ctx.backend.take_right_of_way(m.id, False)
                    del self._taking[m.id]
                continue
            end_m = m.link_distance_m
            link = None
            if (
                end_m is not None
                and end_m <= AT_LINK_M
                and world.speed_mps[i] < STILL_MPS
                and not at_light(m, end_m)
            ):
                # SUMO's link query only for a car standing at it, and not at a light: a
                # light's link shows the light's state, never an unsignalised yield
                link = link_ahead(ctx, m)
            if link is None or link.state not in UNSIGNALISED_YIELD or not link.must_yield:
                self._since.pop(m.id, None)
                continue
            since = self._since.setdefault(m.id, now)
            if now - since < STANDOFF_S:
                continue
            foes = ctx.backend.junction_yields(m.id)
            if not foes or any(still_s < FOES_STILL_S for _, still_s in foes):
                continue
            ctx.backend.take_right_of_way(m.id, True)
            self._taking[m.id] = lane
            del self._since[m.id]
            names = ", ".join(sorted({f for f, _ in foes}))  # the first of each stream
            ctx.emit(
                EventKind.STANDOFF, m, other=foes[0][0],
                detail=f"stood {now - since:.0f} s at '{lane}', yielding to {names}",
            )  # fmt: skip
