"""What the loop asks of SUMO: the `Backend` protocol.

`platoon_sumo.sumo.backend.SumoBackend` is the real one (the only libsumo user); tests of
single stages use a fake. Every call is batched over vehicles where SUMO allows it.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.actuation import ActuationPort
from platoon_sumo.world import LinkAhead, SignalAhead, VehicleAhead, WorldSnapshot

FloatArray = NDArray[np.float64]

#: (vehicle id, front position along the lane [m], speed [m/s], length [m])
LaneOccupant = tuple[str, float, float, float]
#: The route context of one vehicle: next light, SUMO's leader, the link ahead (or, not
#: read, the distance to its lane's end [m]: `Backend.route_contexts`).
RouteContext = tuple[SignalAhead | None, VehicleAhead | None, LinkAhead | float | None]
#: (vehicle id, lane id, front bumper x, y [m], seconds standing still)
StandingVehicle = tuple[str, str, float, float, float]


class Backend(ActuationPort, Protocol):
    """The loop's SUMO: the actuators' part (`ActuationPort`) and the rest."""

    @property
    def time_s(self) -> float: ...

    def step(self) -> None: ...

    def snapshot(self, vehicle_ids: Sequence[str], radius_m: float) -> WorldSnapshot:
        """The given vehicles and every vehicle whose front bumper is within `radius_m`
        of one of theirs (a footprint reaches a length behind its front bumper)."""
        ...

    def vehicle_count(self) -> int: ...

    def standing_vehicles(self, min_wait_s: float) -> list[StandingVehicle]:
        """Vehicles that have stood still for at least `min_wait_s`, neither at a stop of
        their schedule nor within 250 m of a red light ahead: (id, lane, x, y, seconds)."""
        ...

    def largest_vehicle_m(self) -> float:
        """Largest length + width [m] of any vehicle type in the simulation."""
        ...

    def add_vehicle(
        self,
        vehicle_id: str,
        edges: Sequence[str],
        type_id: str,
        depart_lane: int,
        depart_pos_m: float,
        sumo_drives: bool,
        steers: bool = False,
    ) -> None: ...

    def lane_is_free(self, lane_id: str, from_m: float, to_m: float) -> bool: ...

    def lane_occupants(self, lane_id: str) -> list[LaneOccupant]: ...

    def next_junction_lane(self, vehicle_id: str) -> str:
        """The lane the vehicle enters at the end of its current lane (a junction's
        internal lane, or the next lane); "" at its route's end."""
        ...

    def lane_shape(self, lane_id: str) -> FloatArray: ...

    def lane_width(self, lane_id: str) -> float: ...

    def departed_ids(self) -> tuple[str, ...]: ...

    def arrived_ids(self) -> tuple[str, ...]: ...

    def removed_elsewhere(self) -> tuple[str, ...]: ...

    def teleported_ids(self) -> tuple[str, ...]: ...

    def sumo_collisions(self) -> Iterable[tuple[str, str, str]]: ...

    def route_contexts(
        self, vehicle_ids: Sequence[str], horizons_m: Sequence[float], read_links: Sequence[bool]
    ) -> list[RouteContext]:
        """Per vehicle: (next traffic light on its route, the nearest vehicle ahead on its
        lanes within its horizon, the junction link at the end of its lane if that end is
        within its horizon), as SUMO sees them after the last step. Where `read_links` is
        False, the third is the distance to the lane's end instead of the link (None
        where the end is not within the horizon or the vehicle is in a junction)."""
        ...

    def link_ahead(self, vehicle_id: str, distance_m: float) -> LinkAhead | None:
        """The junction link at the end of the vehicle's lane, `distance_m` ahead (None
        at its route's end), as SUMO sees it after the last step."""
        ...

    def junction_yields(self, vehicle_id: str) -> list[tuple[str, float]]:
        """(id, seconds standing still) of the vehicles SUMO's right of way makes this
        one yield to at the junction ahead: the nearest of each conflicting stream."""
        ...

    def take_right_of_way(self, vehicle_id: str, take: bool) -> None:
        """Let SUMO drive the vehicle into junctions without yielding (`take`; it still
        keeps its distance to vehicles inside), or yield again."""
        ...

    def sideways_waits(
        self, vehicle_ids: Sequence[str], leaders: Sequence[VehicleAhead | None]
    ) -> dict[str, tuple[str, float]]:
        """Which of these vehicles (with SUMO's leader of each) must stay behind a car
        SUMO is to move sideways across its path (a lane change it waits to make, a car
        inside a junction beside the lane it goes on to), with that car's id and the gap
        to its back along the lanes [m]."""
        ...

    def remove(self, vehicle_id: str, arrived: bool) -> None:
        """Take a platoon vehicle out: as an arrival (tripinfo), or vaporised."""
        ...
