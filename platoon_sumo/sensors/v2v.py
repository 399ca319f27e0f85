"""Vehicle-to-vehicle messages: what a V2V channel delivers to a controller.

Each equipped vehicle broadcasts a beacon (its state and the acceleration its last
command asked for); every other equipped vehicle in range may receive it, after the
channel's delay, unless it is lost. A controller finds its inbox in
`observation.sensors[name]` (name "v2v" by default) and its predecessor's latest
message with `inbox.from_member(obs.platoon_id, obs.index - 1)`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field


@dataclass(frozen=True)
class V2VMessage:
    """One beacon, as its sender broadcast it at `sent_s`.

    Position and speed are the sender's state when it sent (read after the previous
    SUMO step, the state its own controller decided on); `desired_accel_mps2` is what
    its last command asked for (a CACC's `u`), `accel_mps2` what it achieved over the
    last step."""

    sender_id: str
    platoon_id: str
    index: int
    sent_s: float
    front_x_m: float
    front_y_m: float
    speed_mps: float
    accel_mps2: float
    desired_accel_mps2: float


@dataclass(frozen=True)
class V2VInbox:
    """What one vehicle has received up to `time_s`."""

    time_s: float
    latest: Mapping[str, V2VMessage] = field(default_factory=dict)
    """The newest message received from each sender heard so far, by sender id."""
    received_now: tuple[str, ...] = ()
    """Senders whose message arrived at this step."""
    sent_total: int = 0
    """Beacons this vehicle has sent so far."""
    received_total: int = 0
    """Messages it has received so far."""
    lost_total: int = 0
    """Messages addressed to it (sent by a vehicle in range) that were lost so far."""

    def from_member(self, platoon_id: str, index: int) -> V2VMessage | None:
        """The newest message from member `index` of `platoon_id`, or None."""
        for message in self.latest.values():
            if message.platoon_id == platoon_id and message.index == index:
                return message
        return None
