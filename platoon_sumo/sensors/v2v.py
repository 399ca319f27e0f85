"""Vehicle-to-vehicle messages and the channel that carries them ("v2v" sensor).

Each equipped vehicle broadcasts a beacon (its state and the acceleration its last
command asked for); every other equipped vehicle in range may receive it, after the
channel's delay, unless it is lost. A controller finds its inbox in
`observation.sensors[name]` (name "v2v" by default) and its predecessor's latest
message with `inbox.from_member(obs.platoon_id, obs.index - 1)`.

The channel is a sensor model so that it needs no loop edit: the Sense stage calls it
every step with all vehicles equipped with the same parameters, and keeps the one
instance for the whole run, so it holds the messages in flight, the bursty links' states
and every vehicle's counters. Vehicles equipped with different parameters are different
channels: they do not hear each other.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from types import MappingProxyType
from typing import ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

from platoon_sumo.config_loader import bounded, check_bounds, require, require_choice
from platoon_sumo.sensors.base import SENSORS, IntArray, SensingBatch

_EPS_S = 1e-9
"""Slack on time comparisons (steps are sums of floats)."""


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
    """Messages addressed to it (sent by a vehicle in range) that were lost so far,
    counted when they would have arrived."""

    def from_member(self, platoon_id: str, index: int) -> V2VMessage | None:
        """The newest message from member `index` of `platoon_id`, or None."""
        for message in self.latest.values():
            if message.platoon_id == platoon_id and message.index == index:
                return message
        return None


LossModel = Literal["independent", "gilbert_elliott"]
_LOSS_MODELS: tuple[LossModel, ...] = ("independent", "gilbert_elliott")
_GILBERT_ELLIOTT_KEYS = ("p_good_to_bad", "p_bad_to_good", "loss_in_good", "loss_in_bad")


@dataclass(frozen=True)
class V2VParams:
    """The channel's beacon rate, delay, loss and range.

    Loss is decided per message and receiver. `independent`: each is lost with
    `loss_probability`. `gilbert_elliott`: each (sender, receiver) link is a two-state
    Markov chain, advanced once per message the link carries; a message is lost with
    `loss_in_good` or `loss_in_bad` by the link's state, then the state changes with
    `p_good_to_bad` / `p_bad_to_good`. A new link starts in the bad state with its
    stationary probability `pi_bad = p_good_to_bad / (p_good_to_bad + p_bad_to_good)`, so
    the mean loss rate, from the first message on, is
    `pi_bad * loss_in_bad + (1 - pi_bad) * loss_in_good`, and a link stays bad for
    `1 / p_bad_to_good` messages on average (the mean burst of losses when
    `loss_in_bad = 1` and `loss_in_good = 0`). The chain counts messages, not seconds: a
    burst lasts `1 / (p_bad_to_good * beacon_hz)` s on average.
    """

    beacon_hz: float = bounded(10.0, gt=0, le=1000)
    """Beacons per second of each vehicle: one when at least `1 / beacon_hz` s have
    passed since its last one (beacons fall on steps: at 0.1 s steps, 3 Hz sends every
    0.4 s)."""
    delay_s: float = bounded(0.0, ge=0, le=60)
    """A message sent at t arrives at the first step at or after t + delay_s; 0: in the
    same step (the receiver's controller sees the sender's position and speed of this
    step, and the acceleration the sender's previous command asked for)."""
    loss_probability: float = bounded(0.0, ge=0, le=1)
    """`independent` loss: chance that one message to one receiver is lost. 0 draws no
    random numbers, so an ideal channel leaves the rest of a seeded run unchanged."""
    loss_model: LossModel = "independent"
    """`independent` (`loss_probability`) or `gilbert_elliott` (bursty: the four keys
    below)."""
    p_good_to_bad: float = bounded(0.05, ge=0, le=1)
    """`gilbert_elliott`: chance per message that a good link turns bad."""
    p_bad_to_good: float = bounded(0.5, gt=0, le=1)
    """`gilbert_elliott`: chance per message that a bad link recovers (1 / mean burst
    length in messages)."""
    loss_in_good: float = bounded(0.0, ge=0, le=1)
    """`gilbert_elliott`: loss probability of a message on a good link."""
    loss_in_bad: float = bounded(1.0, ge=0, le=1)
    """`gilbert_elliott`: loss probability of a message on a bad link."""
    range_m: float = bounded(300.0, gt=0, le=100_000, allow_inf=True)
    """Farthest receiver, front bumper to front bumper in a straight line when the
    message is sent [m]. Vehicles farther away are not addressed: their missing message
    is not counted as lost. `.inf`: no limit."""
    forget_after_s: float = bounded(10.0, gt=0, le=3600)
    """A vehicle absent from the channel this long (it left the run) is forgotten: its
    messages leave every inbox and its counters and links are dropped, so memory stays
    bounded on long runs [s]. Must exceed `delay_s`."""

    def __post_init__(self) -> None:
        require_choice(self.loss_model, _LOSS_MODELS, "loss_model")
        check_bounds(self)
        require(
            self.forget_after_s > self.delay_s, "forget_after_s",
            f"must be > delay_s ({self.delay_s} s): a message in flight outlives its "
            "receiver's record otherwise",
        )  # fmt: skip
        if self.loss_model == "gilbert_elliott":
            require(
                self.loss_probability == 0.0, "loss_probability",
                "is the independent model's: with loss_model gilbert_elliott set "
                "loss_in_good / loss_in_bad instead",
            )  # fmt: skip
            return
        defaults = {f.name: f.default for f in fields(self)}
        for key in _GILBERT_ELLIOTT_KEYS:
            require(
                getattr(self, key) == defaults[key], key,
                "is only used with loss_model gilbert_elliott",
                "add `loss_model: gilbert_elliott`",
            )  # fmt: skip

    @property
    def bad_share(self) -> float:
        """Stationary probability that a Gilbert-Elliott link is bad."""
        return self.p_good_to_bad / (self.p_good_to_bad + self.p_bad_to_good)


@dataclass(frozen=True)
class _Flight:
    """The messages one step's beacons put on the air, decided at sending."""

    due_s: float
    messages: tuple[V2VMessage, ...]
    sender: IntArray
    """Per addressed (sender, receiver) pair: its message in `messages` ..."""
    receiver: IntArray
    """... the receiver's slot ..."""
    lost: NDArray[np.bool_]
    """... and whether the channel loses it."""


_SENT, _RECEIVED, _LOST = range(3)


@SENSORS.register("v2v")
class V2VChannel:
    """A broadcast channel among the vehicles that carry it with the same parameters.
    Each vehicle's message is its `V2VInbox`: the latest message of every sender heard,
    the senders heard this step, and its sent / received / lost counts (the `v2v_*`
    columns of vehicles.csv).

    A beacon carries the sender's state read after the previous SUMO step (the state its
    controller decides on this step) and the acceleration its previous command asked
    for: with `delay_s` 0 a follower sees its predecessor's position and speed of this
    step, and a desired acceleration up to one step old. Lost messages are counted when
    they would have arrived, so `received_total + lost_total` are the messages addressed
    to the vehicle that are due by now.

    Every vehicle has a slot in per-slot arrays (counters, beacon times, Gilbert-Elliott
    link states as slot x slot matrices); slots of forgotten vehicles are reused. Random
    numbers come from the run's generator in batch order, as many whatever the outcomes:
    one per addressed message (none when `loss_probability` is 0), or with
    Gilbert-Elliott two per addressed message and one per new link.
    """

    Params: ClassVar[type[V2VParams]] = V2VParams

    def __init__(self, params: V2VParams) -> None:
        self.params = params
        self._slot_of: dict[str, int] = {}
        self._free: list[int] = []
        self._ids: list[str | None] = []
        self._latest: list[Mapping[str, V2VMessage]] = []
        self._last_seen_s = np.empty(0)
        self._last_beacon_s = np.empty(0)
        self._counts = np.zeros((0, 3), dtype=np.int64)
        self._link_known = np.zeros((0, 0), dtype=bool)
        self._link_bad = np.zeros((0, 0), dtype=bool)
        self._flights: deque[_Flight] = deque()

    @property
    def period_s(self) -> float:
        """0: called every step; the channel decides who beacons."""
        return 0.0

    def observe(self, batch: SensingBatch) -> list[V2VInbox]:
        ids = batch.vehicle_ids
        if len(set(ids)) != len(ids):
            raise ValueError(
                "a vehicle has two sensors with this channel's parameters: give them "
                "different parameters or keep one"
            )
        now = batch.time_s
        slots = np.array([self._slot(vid) for vid in ids], dtype=np.int64)
        self._last_seen_s[slots] = now
        self._send(batch, slots)
        arrived = self._deliver(now)
        self._forget(now)
        empty: tuple[str, ...] = ()
        counts = self._counts[slots].tolist()
        return [
            V2VInbox(now, self._latest[slot], arrived.get(slot, empty), sent, received, lost)
            for slot, (sent, received, lost) in zip(slots.tolist(), counts, strict=True)
        ]

    # ------------------------------------------------------------------ sending

    def _send(self, batch: SensingBatch, slots: IntArray) -> None:
        """Beacons of the due vehicles, addressed to everyone in range, their fate drawn."""
        now = batch.time_s
        due = now - self._last_beacon_s[slots] >= 1.0 / self.params.beacon_hz - _EPS_S
        senders = np.flatnonzero(due)
        if len(senders) == 0:
            return
        self._last_beacon_s[slots[senders]] = now
        self._counts[slots[senders], _SENT] += 1
        x, y = batch.front_x_m, batch.front_y_m
        messages = tuple(
            V2VMessage(
                sender_id=batch.vehicle_ids[k],
                platoon_id=batch.platoon_ids[k],
                index=int(batch.member_index[k]),
                sent_s=now,
                front_x_m=float(x[k]),
                front_y_m=float(y[k]),
                speed_mps=float(batch.speed_mps[k]),
                accel_mps2=float(batch.accel_mps2[k]),
                desired_accel_mps2=float(batch.desired_accel_mps2[k]),
            )
            for k in senders.tolist()
        )
        distance_sq = (x[senders, None] - x[None, :]) ** 2 + (y[senders, None] - y[None, :]) ** 2
        addressed = distance_sq <= self.params.range_m**2
        addressed[np.arange(len(senders)), senders] = False
        sender, receiver = np.nonzero(addressed)  # row-major: batch order, deterministic
        sender_slot, receiver_slot = slots[senders[sender]], slots[receiver]
        lost = self._lose(sender_slot, receiver_slot, batch.rng)
        due_s = now + self.params.delay_s
        self._flights.append(_Flight(due_s, messages, sender, receiver_slot, lost))

    def _lose(
        self, sender: IntArray, receiver: IntArray, rng: np.random.Generator
    ) -> NDArray[np.bool_]:
        """Which of these messages (one per link) the channel loses."""
        p = self.params
        n = len(sender)
        if p.loss_model == "independent":
            if p.loss_probability == 0.0:
                return np.zeros(n, dtype=bool)
            return rng.random(n) < p.loss_probability
        fresh = ~self._link_known[sender, receiver]
        if fresh.any():
            starts_bad = rng.random(int(fresh.sum())) < p.bad_share
            self._link_bad[sender[fresh], receiver[fresh]] = starts_bad
            self._link_known[sender[fresh], receiver[fresh]] = True
        u = rng.random((n, 2))
        bad = self._link_bad[sender, receiver]
        lost = u[:, 0] < np.where(bad, p.loss_in_bad, p.loss_in_good)
        flips = u[:, 1] < np.where(bad, p.p_bad_to_good, p.p_good_to_bad)
        self._link_bad[sender, receiver] = bad ^ flips
        return lost

    # ------------------------------------------------------------------ receiving

    def _deliver(self, now: float) -> dict[int, tuple[str, ...]]:
        """Apply every flight due by `now`; the senders heard now, by receiver slot."""
        updates: dict[int, dict[str, V2VMessage]] = {}
        flights = self._flights
        while flights and flights[0].due_s <= now + _EPS_S:
            flight = flights.popleft()
            np.add.at(self._counts[:, _LOST], flight.receiver[flight.lost], 1)
            ok = ~flight.lost
            np.add.at(self._counts[:, _RECEIVED], flight.receiver[ok], 1)
            messages = flight.messages
            heard = zip(flight.sender[ok].tolist(), flight.receiver[ok].tolist(), strict=True)
            for k, slot in heard:
                message = messages[k]
                updates.setdefault(slot, {})[message.sender_id] = message
        for slot, new in updates.items():  # copy on write: inboxes handed out stay as they were
            self._latest[slot] = MappingProxyType({**self._latest[slot], **new})
        return {slot: tuple(new) for slot, new in updates.items()}

    # ------------------------------------------------------------------ vehicles

    def _slot(self, vehicle_id: str) -> int:
        slot = self._slot_of.get(vehicle_id)
        if slot is not None:
            return slot
        if not self._free:
            self._grow()
        slot = self._free.pop()
        self._slot_of[vehicle_id] = slot
        self._ids[slot] = vehicle_id
        return slot

    def _grow(self) -> None:
        """Double the slot arrays (new slots are free)."""
        old = len(self._ids)
        new = max(8, 2 * old)
        self._ids += [None] * (new - old)
        self._latest += [MappingProxyType({})] * (new - old)
        self._last_seen_s = np.concatenate([self._last_seen_s, np.full(new - old, math.nan)])
        self._last_beacon_s = np.concatenate([self._last_beacon_s, np.full(new - old, -math.inf)])
        self._counts = np.vstack([self._counts, np.zeros((new - old, 3), dtype=np.int64)])
        if self.params.loss_model == "gilbert_elliott":
            for name in ("_link_known", "_link_bad"):
                grown = np.zeros((new, new), dtype=bool)
                grown[:old, :old] = getattr(self, name)
                setattr(self, name, grown)
        self._free += range(new - 1, old - 1, -1)  # pop() hands out the lowest first

    def _forget(self, now: float) -> None:
        """Drop the vehicles absent for longer than `forget_after_s`."""
        gone = np.flatnonzero(now - self._last_seen_s > self.params.forget_after_s + _EPS_S)
        if len(gone) == 0:
            return
        names = set()
        for slot in gone.tolist():
            vid = self._ids[slot]
            assert vid is not None
            names.add(vid)
            del self._slot_of[vid]
            self._ids[slot] = None
            self._latest[slot] = MappingProxyType({})
            self._free.append(slot)
        self._last_seen_s[gone] = math.nan
        self._last_beacon_s[gone] = -math.inf
        self._counts[gone] = 0
        if self.params.loss_model == "gilbert_elliott":
            self._link_known[gone, :] = False
            self._link_known[:, gone] = False
        for slot in self._slot_of.values():
            latest = self._latest[slot]
            if not names.isdisjoint(latest):
                kept = {k: m for k, m in latest.items() if k not in names}
                self._latest[slot] = MappingProxyType(kept)
