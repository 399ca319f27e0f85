"""Controllers: the protocol, the registry, and the built-in families."""

from platoon_sumo.control import cacc as _cacc  # noqa: F401 (registers)
from platoon_sumo.control import laser_follower as _laser_follower  # noqa: F401 (registers)
from platoon_sumo.control import paper as _paper  # noqa: F401 (registers)
from platoon_sumo.control import path_cacc as _path_cacc  # noqa: F401 (registers)
from platoon_sumo.control import route_following as _route_following  # noqa: F401 (registers)
from platoon_sumo.control import speed_profile as _speed_profile  # noqa: F401 (registers)
from platoon_sumo.control import sumo_driver as _sumo_driver  # noqa: F401 (registers)
from platoon_sumo.control.base import (
    CONTROLLERS,
    Command,
    Controller,
    GapPolicy,
    Observation,
    ObservationColumns,
    ObservationRows,
    Telemetry,
)

__all__ = [
    "CONTROLLERS",
    "Command",
    "Controller",
    "GapPolicy",
    "Observation",
    "ObservationColumns",
    "ObservationRows",
    "Telemetry",
]
