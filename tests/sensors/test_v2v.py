"""The V2V channel ("v2v" sensor) on hand-built sensing batches: delay, beacon rate,
independent and Gilbert-Elliott loss against their formulas, range, determinism and
bounded memory; and its parameters as scenario keys."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from platoon_sumo.config_loader import FieldError, load_dataclass
from platoon_sumo.errors import ScenarioError
from platoon_sumo.loop.context import empty_world
from platoon_sumo.scenario import SENSORS
from platoon_sumo.sensors.base import SensingBatch
from platoon_sumo.sensors.v2v import V2VChannel, V2VInbox, V2VParams

DT = 0.1


def batch(
    time_s: float,
    ids: Sequence[str],
    x: Sequence[float],
    rng: np.random.Generator,
    y: Sequence[float] | None = None,
) -> SensingBatch:
    """Vehicles `ids` of platoon "p" (member index = position in `ids`) at front bumpers
    (x, y); each one's speed is 10 + its x / 100 and its desired acceleration its x / 1000,
    so a message tells when it was sent."""
    n = len(ids)
    xs = np.asarray(x, dtype=np.float64)
    ys = np.zeros(n) if y is None else np.asarray(y, dtype=np.float64)
    none = np.full(n, -1, dtype=np.int64)
    return SensingBatch(
        time_s=time_s, vehicle_ids=tuple(ids), front_x_m=xs, front_y_m=ys,
        yaw_rad=np.zeros(n), speed_mps=10.0 + xs / 100.0, own_index=none,
        predecessor_index=none, vehicle_ahead=(None,) * n, world=empty_world(time_s),
        footprints=np.empty((0, 5)), static_segments=None, rng=rng,
        platoon_ids=("p",) * n, member_index=np.arange(n, dtype=np.int64),
        accel_mps2=np.zeros(n), desired_accel_mps2=xs / 1000.0,
    )  # fmt: skip


def run_channel(
    params: V2VParams, steps: int, n: int = 2, spacing_m: float = 10.0, seed: int = 1
) -> list[list[V2VInbox]]:
    """`n` vehicles in a row, still, observed for `steps` steps: the inboxes per step."""
    channel, rng = V2VChannel(params), np.random.default_rng(seed)
    ids = [f"p.{k}" for k in range(n)]
    x = [k * spacing_m for k in range(n)]
    return [channel.observe(batch(round(k * DT, 6), ids, x, rng)) for k in range(steps)]


def test_the_channel_is_a_registered_sensor_called_every_step():
    assert SENSORS.get("v2v") is V2VChannel
    assert V2VChannel(V2VParams()).period_s == 0.0


def test_with_no_delay_the_receiver_gets_the_senders_state_of_this_step():
    channel, rng = V2VChannel(V2VParams()), np.random.default_rng(0)
    for k, lead_x in enumerate((50.0, 51.0, 52.5)):
        inboxes = channel.observe(batch(k * DT, ["p.0", "p.1"], [lead_x, 30.0], rng))
        follower = inboxes[1]
        message = follower.from_member("p", 0)
        assert message is not None and follower.received_now == ("p.0",)
        assert message.sent_s == k * DT and message.front_x_m == lead_x
        assert message.speed_mps == 10.0 + lead_x / 100.0
        assert message.desired_accel_mps2 == lead_x / 1000.0
        assert follower.from_member("p", 1) is None  # not its own
        assert inboxes[0].from_member("p", 1) is not None  # everyone hears everyone


@settings(max_examples=40, deadline=None)
@given(delay_steps=st.floats(0.0, 2.5), dt=st.sampled_from([0.05, 0.1, 0.25]))
def test_a_message_arrives_at_the_first_step_at_or_after_its_delay(delay_steps, dt):
    delay_s = round(delay_steps * dt, 6)
    channel, rng = V2VChannel(V2VParams(beacon_hz=0.1, delay_s=delay_s)), np.random.default_rng(0)
    first_step = math.ceil(delay_s / dt - 1e-9)
    for k in range(first_step + 3):
        time_s = round(k * dt, 6)
        lead_x = 50.0 + k  # the message sent at t=0 says x=50
        inbox = channel.observe(batch(time_s, ["p.0", "p.1"], [lead_x, 30.0], rng))[1]
        message = inbox.from_member("p", 0)
        if k < first_step:
            assert message is None and inbox.received_now == () and inbox.received_total == 0
        else:
            assert message is not None and message.sent_s == 0.0 and message.front_x_m == 50.0
            assert time_s >= delay_s - 1e-9
            assert inbox.received_now == (("p.0",) if k == first_step else ())
            assert inbox.received_total == 1


@settings(max_examples=40, deadline=None)
@given(beacon_hz=st.floats(0.2, 20.0), steps=st.integers(1, 200))
def test_beacons_go_out_once_their_period_has_passed(beacon_hz, steps):
    inboxes = run_channel(V2VParams(beacon_hz=beacon_hz), steps)
    every = max(1, math.ceil(1.0 / beacon_hz / DT - 1e-6))  # steps between two beacons
    expected = math.ceil(steps / every)
    assert inboxes[-1][0].sent_total == expected == inboxes[-1][1].received_total
    sent_at = [k for k, step in enumerate(inboxes) if step[1].received_now]
    assert sent_at == list(range(0, steps, every))


def test_ten_hertz_beacons_at_ten_hertz_steps_go_out_every_step():
    inboxes = run_channel(V2VParams(beacon_hz=10.0), 100)
    assert [i.sent_total for i in inboxes[-1]] == [100, 100]


def binomial_bound(n: int, p: float, sigmas: float = 5.0) -> float:
    return sigmas * math.sqrt(n * p * (1.0 - p))


def test_independent_loss_rate_is_within_binomial_bounds():
    inboxes = run_channel(V2VParams(loss_probability=0.1), steps=200, n=11)
    last = inboxes[-1]
    addressed = 200 * 10 * 11  # every vehicle hears the 10 others, every step
    lost = sum(i.lost_total for i in last)
    assert sum(i.received_total for i in last) + lost == addressed
    assert abs(lost - 0.1 * addressed) < binomial_bound(addressed, 0.1)
    assert all(i.sent_total == 200 for i in last)


def loss_sequences(inboxes: list[list[V2VInbox]], n: int) -> np.ndarray:
    """lost[link, step] for every (sender, receiver) link, each beaconing every step."""
    rows = []
    for receiver in range(n):
        for sender in range(n):
            if sender != receiver:
                heard = [f"p.{sender}" in step[receiver].received_now for step in inboxes]
                rows.append(~np.array(heard))
    return np.array(rows)


def burst_lengths(lost: np.ndarray) -> list[int]:
    """Lengths of the runs of consecutive losses of every link."""
    out = []
    for row in lost:
        padded = np.concatenate([[0], row.astype(np.int8), [0]])
        edges = np.flatnonzero(np.diff(padded))
        out += (edges[1::2] - edges[::2]).tolist()
    return out


def test_gilbert_elliott_loss_matches_the_stationary_rate_and_comes_in_bursts():
    p_gb, p_bg = 0.05, 0.25
    params = V2VParams(loss_model="gilbert_elliott", p_good_to_bad=p_gb, p_bad_to_good=p_bg)
    n, steps = 5, 2000
    lost = loss_sequences(run_channel(params, steps, n), n)
    messages = lost.size  # 20 links x 2000 messages
    bad = p_gb / (p_gb + p_bg)
    assert params.bad_share == pytest.approx(bad)
    # the loss indicator is the link's state: a two-state chain whose sample mean has
    # variance pi(1-pi)(1+lambda)/(1-lambda)/N, lambda = 1 - p_gb - p_bg
    lam = 1.0 - p_gb - p_bg
    sigma = math.sqrt(bad * (1.0 - bad) * (1.0 + lam) / (1.0 - lam) / messages)
    assert abs(lost.mean() - bad) < 5.0 * sigma
    bursts = burst_lengths(lost)
    # burst lengths are geometric: mean 1/p_bg, variance (1-p_bg)/p_bg^2
    spread = math.sqrt((1.0 - p_bg) / p_bg**2 / len(bursts))
    assert abs(np.mean(bursts) - 1.0 / p_bg) < 5.0 * spread
    # independent loss at the same rate has bursts of 1 / (1 - p) = 1.2 messages
    independent = loss_sequences(run_channel(V2VParams(loss_probability=bad), steps, n), n)
    assert np.mean(burst_lengths(independent)) < 1.3 < 1.0 / p_bg - 5.0 * spread


def test_gilbert_elliott_loss_in_both_states_follows_the_formula():
    params = V2VParams(
        loss_model="gilbert_elliott", p_good_to_bad=0.1, p_bad_to_good=0.3,
        loss_in_good=0.05, loss_in_bad=0.6,
    )  # fmt: skip
    expected = 0.25 * 0.6 + 0.75 * 0.05  # pi_bad = 0.1 / 0.4
    last = run_channel(params, steps=2000, n=5)[-1]
    lost = sum(i.lost_total for i in last)
    addressed = 2000 * 20
    assert sum(i.received_total for i in last) + lost == addressed
    # loss given the state is independent; the states are correlated: bound their share
    lam = 1.0 - 0.4
    state_sigma = math.sqrt(0.25 * 0.75 * (1 + lam) / (1 - lam) / addressed)
    sigma = math.hypot((0.6 - 0.05) * state_sigma, math.sqrt(expected / addressed))
    assert abs(lost / addressed - expected) < 5.0 * sigma


def test_receivers_out_of_range_are_not_addressed_and_not_counted_lost():
    params = V2VParams(range_m=300.0, loss_probability=1.0)
    channel, rng = V2VChannel(params), np.random.default_rng(0)
    # a at the origin; b 300 m away in a straight line (just in range); c 200 m beyond b,
    # 449 m from a
    inboxes = channel.observe(batch(0.0, ["a", "b", "c"], [0.0, 180.0, 380.0], rng,
                                    y=[0.0, 240.0, 240.0]))  # fmt: skip
    assert [i.lost_total for i in inboxes] == [1, 2, 1]  # a-b and b-c are links, a-c not
    assert [i.sent_total for i in inboxes] == [1, 1, 1]
    ideal = V2VChannel(V2VParams(range_m=300.0))
    heard = ideal.observe(batch(0.0, ["a", "b", "c"], [0.0, 180.0, 380.0], rng,
                                y=[0.0, 240.0, 240.0]))  # fmt: skip
    assert [set(i.latest) for i in heard] == [{"b"}, {"a", "c"}, {"b"}]
    assert [i.lost_total for i in heard] == [0, 0, 0]


def test_an_ideal_channel_draws_no_random_numbers():
    rng = np.random.default_rng(5)
    channel = V2VChannel(V2VParams())
    for k in range(10):
        channel.observe(batch(k * DT, ["a", "b", "c"], [0.0, 10.0, 20.0], rng))
    assert rng.random() == np.random.default_rng(5).random()


CHANNELS = st.builds(
    V2VParams,
    beacon_hz=st.sampled_from([2.0, 5.0, 10.0]),
    delay_s=st.sampled_from([0.0, 0.1, 0.25]),
    range_m=st.sampled_from([30.0, 300.0]),
    loss_probability=st.sampled_from([0.0, 0.3]),
)
BURSTY = st.builds(
    V2VParams,
    loss_model=st.just("gilbert_elliott"),
    delay_s=st.sampled_from([0.0, 0.2]),
    p_good_to_bad=st.floats(0.0, 1.0),
    p_bad_to_good=st.floats(0.01, 1.0),
    range_m=st.sampled_from([30.0, math.inf]),
)


def moving_run(params: V2VParams, seed: int, presence: list[list[bool]]) -> list[list[V2VInbox]]:
    """Vehicles driving apart at different speeds, present in the steps `presence` says."""
    channel, rng = V2VChannel(params), np.random.default_rng(seed)
    out = []
    for k, present in enumerate(presence):
        ids = [f"p.{i}" for i, here in enumerate(present) if here]
        x = [i * (5.0 + k * 0.5) for i, here in enumerate(present) if here]
        out.append(channel.observe(batch(round(k * DT, 6), ids, x, rng)))
    return out


PRESENCE = st.lists(st.lists(st.booleans(), min_size=4, max_size=4), min_size=1, max_size=40)


@settings(max_examples=30, deadline=None)
@given(params=st.one_of(CHANNELS, BURSTY), seed=st.integers(0, 2**32 - 1), presence=PRESENCE)
def test_the_same_seed_gives_the_same_inboxes(params, seed, presence):
    first = moving_run(params, seed, presence)
    assert moving_run(params, seed, presence) == first
    for step in first:
        for inbox in step:
            assert inbox.received_total + inbox.lost_total <= 40 * 3
            for message in inbox.latest.values():
                assert message.sent_s <= inbox.time_s - params.delay_s + 1e-9


def test_another_seed_gives_other_losses():
    params = V2VParams(loss_probability=0.5)
    one = run_channel(params, 50, n=4, seed=1)[-1]
    other = run_channel(params, 50, n=4, seed=2)[-1]
    assert [i.lost_total for i in one] != [i.lost_total for i in other]


def test_vehicles_that_left_are_forgotten_and_memory_stays_bounded():
    params = V2VParams(forget_after_s=1.0, loss_model="gilbert_elliott")
    channel, rng = V2VChannel(params), np.random.default_rng(0)
    # a stream of vehicles: each one present for 2 s, a new one every 0.5 s, 200 s
    for k in range(2000):
        time_s = round(k * DT, 6)
        ids = [f"v{j}" for j in range(max(0, k // 5 - 3), k // 5 + 1)]
        x = [float(j) for j in range(len(ids))]
        inboxes = channel.observe(batch(time_s, ids, x, rng))
        heard = set().union(*(i.latest for i in inboxes))
        # v<j> is last seen at step 5j + 19: its messages go once it is absent > 1 s
        assert all(k <= 5 * int(s[1:]) + 29 for s in heard)
    # private state, checked for its size: 4 present, 2 gone but not yet forgotten
    assert len(channel._slot_of) <= 6
    assert len(channel._ids) <= 8


def test_a_vehicle_seen_again_starts_afresh():
    params = V2VParams(forget_after_s=0.5)
    channel, rng = V2VChannel(params), np.random.default_rng(0)
    for k in range(5):
        channel.observe(batch(k * DT, ["a", "b"], [0.0, 5.0], rng))
    for k in range(5, 12):  # b gone 0.7 s
        (only_a,) = channel.observe(batch(k * DT, ["a"], [0.0], rng))
    assert "b" not in only_a.latest
    a, b = channel.observe(batch(1.2, ["a", "b"], [0.0, 5.0], rng))
    assert b.sent_total == 1 and b.received_total == 1
    assert a.sent_total == 13 and a.received_total == 6


def test_a_vehicle_with_the_channel_twice_is_refused():
    channel, rng = V2VChannel(V2VParams()), np.random.default_rng(0)
    with pytest.raises(ValueError, match="two sensors"):
        channel.observe(batch(0.0, ["a", "a"], [0.0, 0.0], rng))


@pytest.mark.parametrize(
    ("params", "key", "words"),
    [
        ({"delay": 0.1}, "params.delay", "unknown key"),
        ({"beacon_hz": 0}, "params.beacon_hz", "must be in (0, 1000] Hz"),
        ({"loss_probability": 1.5}, "params.loss_probability", "must be in [0, 1]"),
        ({"loss_model": "bursty"}, "params.loss_model", "expected one of"),
        ({"p_bad_to_good": 0.2}, "params.p_bad_to_good", "only used with loss_model"),
        ({"loss_model": "gilbert_elliott", "loss_probability": 0.1},
         "params.loss_probability", "loss_in_good"),
        ({"delay_s": 2.0, "forget_after_s": 1.0}, "params.forget_after_s", "must be > delay_s"),
    ],
)  # fmt: skip
def test_parameters_are_checked_like_scenario_keys(params, key, words):
    with pytest.raises(ScenarioError) as error:
        load_dataclass(V2VParams, params, "s.yaml", "params")
    assert error.value.key_path == key
    assert words in str(error.value)


def test_range_may_be_unlimited():
    params = load_dataclass(V2VParams, {"range_m": math.inf}, "s.yaml", "params")
    assert params.range_m == math.inf
    with pytest.raises(FieldError):
        V2VParams(loss_model="bursty")  # type: ignore[arg-type]
