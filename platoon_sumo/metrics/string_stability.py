"""String stability of a disturbed platoon: gains from each member to the next, and a verdict.

A platoon is string stable when no follower amplifies what the member ahead passes on:
`|H_i(jω)| <= 1` at every frequency, where `H_i` maps member `i-1`'s speed (equally its
acceleration, or for `i >= 2` its spacing error) to member `i`'s; for linear followers
this is l2 string stability, `‖y_i‖₂ <= ‖y_(i-1)‖₂` for every disturbance (Ploeg et al.
2014, "Lp string stability of cascaded systems"; Naus et al. 2010, "String-stable CACC
design and experimental validation"). From one run's series it is estimated where the
leader excites the platoon:

- a tonal leader (a sinusoid): both signals are projected on `e^(-jωt)` at the tone's
  frequency over the whole periods of the record's second half, which gives the
  steady-state gain of a linear follower once its transient has died out (`tone_gain`);
- a broadband leader (a chirp, random speed, braking): Welch's cross-spectral estimate
  `H = P_xy / P_xx` (Hann segments of an eighth of the record, half overlapping) at the
  frequencies where the leader's speed holds at least `MIN_BAND_POWER` of its peak
  power (`welch_gains`).

These need whole series, so they run after the run on the trajectory table
(`tables.frequency_responses`), not online as `RunStats`' sums do: Welch's segments
overlap and are windowed, and whether the leader is tonal, and at which frequency, is
known only once its whole signal is in. Only the platoons judged stable or unstable
are read (`tables.NEEDS_RESPONSE`).

`assess` turns a platoon's counts and its followers' gains into `string_stable`
(true, false, or None when unknown) and a verdict (`VERDICTS`); definitions in
docs/metrics.md.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

#: The leader's speed must vary by at least this (standard deviation over the metrics
#: window, m/s) for its platoon to be judged: below it there is nothing to amplify.
MIN_DISTURBANCE_MPS = 0.1
#: A follower whose command was overridden or clipped on more than this share of its
#: steps is saturated: its gains measure the limits, not its control law.
MAX_SATURATED_SHARE = 0.05
#: A disturbed follower whose every gain is below this did not follow (it stood still).
MIN_FOLLOWING_GAIN = 0.01
#: A leader is tonal when a single sinusoid explains at least this share of the variance
#: of its speed.
MIN_TONE_SHARE = 0.9
#: Welch bins where the leader's speed has less than this share of its peak power are
#: not reported (too little input to estimate a gain from).
MIN_BAND_POWER = 0.01
#: A gain is estimated only where the member ahead's signal keeps at least this share of
#: the amplitude it has at the head of the chain (the leader's speed and acceleration,
#: the first follower's spacing error) at that frequency: a disturbance damped 0.33 per
#: member is 0.4 % of the leader's after five, and the ratio of two such remnants
#: measures rounding and noise (gains of 4 from a stable platoon), not the control law.
MIN_INPUT_SHARE = 0.05
#: Welch segments are this share of the record (15 half-overlapping segments).
WELCH_SEGMENTS = 8
#: Shortest record (samples) for a Welch estimate: segments of 16 samples.
MIN_WELCH_SAMPLES = 16 * WELCH_SEGMENTS

STABLE, UNSTABLE, SPLIT, SATURATED = "stable", "unstable", "split", "saturated"
NO_DISTURBANCE, NO_FOLLOWERS, MARGINAL = "no disturbance", "no followers", "marginal"
VERDICTS = (STABLE, UNSTABLE, MARGINAL, SPLIT, SATURATED, NO_DISTURBANCE, NO_FOLLOWERS)
#: Gains at most this far above 1 are "marginal", neither stable nor unstable: the
#: frequency responses are estimated to within 2 % of exactly simulated platoons
#: (tests/metrics/test_frequency_response.py), and the l2 gain of a follower that
#: repeats its predecessor's motion is 1 up to the edges of a finite window (a constant
#: time gap platoon stopping at signals: speed gains 0.99-1.001).
GAIN_TOLERANCE = 0.02


@dataclass(frozen=True)
class Excitation:
    """How the leader excites its platoon: where the gains are estimated."""

    kind: Literal["sinusoid", "broadband"]
    frequencies_hz: np.ndarray
    """The tone, or the Welch bins the leader excites."""
    segment: int = 0
    """Welch segment length [samples] (broadband): bin k is at k / (segment dt)."""
    bins: np.ndarray | None = None
    """The indices of `frequencies_hz` on that grid (broadband)."""


def excitation(leader_speed: np.ndarray, dt_s: float) -> Excitation | None:
    """The excitation of a platoon from its leader's speed on a uniform grid; None when
    it hardly varies (`MIN_DISTURBANCE_MPS`) or is too short to say."""
    x = np.asarray(leader_speed, dtype=np.float64)
    if len(x) < MIN_WELCH_SAMPLES or float(np.std(x)) < MIN_DISTURBANCE_MPS:
        return None
    frequency, share = tone(x, dt_s)
    if share >= MIN_TONE_SHARE:
        return Excitation("sinusoid", np.array([frequency]))
    segment = len(x) // WELCH_SEGMENTS
    freqs, pxx, _ = _spectra(x, x, dt_s, segment)
    bins = np.flatnonzero(pxx >= MIN_BAND_POWER * pxx[1:].max())
    bins = bins[bins > 0]  # never the mean
    return Excitation("broadband", freqs[bins], segment, bins)


def tone(x: np.ndarray, dt_s: float) -> tuple[float, float]:
    """(frequency [Hz], share of the variance of `x` a sinusoid at it explains): the
    strongest line of the spectrum, refined to the sinusoid that fits `x` best (least
    squares: exact for a pure tone, where the peak of the spectrum is biased by its
    mirror image at the negative frequency)."""
    x = np.asarray(x, dtype=np.float64) - np.mean(x)
    n = len(x)
    variance = float(x @ x)
    if n < 4 or variance <= 0.0:
        return math.nan, 0.0
    pad = 16 * n  # 1/16 of the record's resolution: the line's main lobe is 32 bins wide
    k = int(np.argmax(np.abs(np.fft.rfft(x, pad))[1:])) + 1
    step = 1.0 / (pad * dt_s)
    t = np.arange(n) * dt_s

    def explained(f: float) -> float:
        w = 2.0 * math.pi * f * t
        basis = np.column_stack([np.sin(w), np.cos(w), np.ones(n)])
        residual = x - basis @ np.linalg.lstsq(basis, x, rcond=None)[0]
        return 1.0 - float(residual @ residual) / variance

    lo, hi = max(k - 2, 0) * step, (k + 2) * step
    golden = (math.sqrt(5.0) - 1.0) / 2.0
    for _ in range(50):  # golden-section search inside the main lobe
        a, b = hi - golden * (hi - lo), lo + golden * (hi - lo)
        if explained(a) > explained(b):
            hi = b
        else:
            lo = a
    frequency = (lo + hi) / 2.0
    return frequency, explained(frequency)


def tone_gain(x: np.ndarray, y: np.ndarray, dt_s: float, frequency_hz: float) -> complex | None:
    """`Y/X` at `frequency_hz`: both (means removed) projected on `e^(-jωt)` over the
    whole periods that end the record after a transient of half the record, and at least
    one period; None without a whole period or without input at the frequency."""
    n = min(len(x), len(y))
    window = _tone_window(n, dt_s, frequency_hz)
    if window is None:
        return None
    m, basis = window
    xs = np.asarray(x[n - m : n], dtype=np.float64)
    ys = np.asarray(y[n - m : n], dtype=np.float64)
    xs, ys = xs - xs.mean(), ys - ys.mean()
    big_x = complex(xs @ basis)
    if abs(big_x) <= 1e-9 * float(np.abs(xs).sum()):
        return None
    return complex(ys @ basis) / big_x


def _tone_window(n: int, dt_s: float, frequency_hz: float) -> tuple[int, np.ndarray] | None:
    """(m, e^(-jωt) over m samples): the whole periods that end an n-sample record after a
    transient of half the record, and at least one period; None without a whole period."""
    period_steps = 1.0 / (frequency_hz * dt_s)
    transient = max(n / 2.0, period_steps)
    periods = math.floor((n - transient) / period_steps + 1e-9)
    if periods < 1:
        return None
    m = round(periods * period_steps)
    return m, np.exp(-2j * math.pi * frequency_hz * dt_s * np.arange(m))


def _spectra(
    x: np.ndarray, y: np.ndarray, dt_s: float, segment: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frequencies, P_xx, P_xy): Welch's averaged spectra (Hann window, half overlap,
    each segment's mean removed), up to a common factor that the ratio cancels."""
    window = np.hanning(segment)

    def transforms(s: np.ndarray) -> np.ndarray:
        segs = np.lib.stride_tricks.sliding_window_view(np.asarray(s, np.float64), segment)
        segs = segs[:: max(segment // 2, 1)]
        return np.fft.rfft((segs - segs.mean(axis=1, keepdims=True)) * window, axis=1)

    big_x, big_y = transforms(x), transforms(y)
    pxx = (np.abs(big_x) ** 2).sum(axis=0)
    return np.fft.rfftfreq(segment, dt_s), pxx, (np.conj(big_x) * big_y).sum(axis=0)


def welch_gains(
    x: np.ndarray, y: np.ndarray, dt_s: float, segment: int
) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies [Hz], |P_xy / P_xx|) on the grid of `segment`-sample segments; NaN
    where `x` has less than `MIN_BAND_POWER` of its peak power (too little input)."""
    freqs, pxx, pxy = _spectra(x, y, dt_s, segment)
    enough = pxx >= MIN_BAND_POWER * pxx[1:].max()
    with np.errstate(divide="ignore", invalid="ignore"):
        return freqs, np.where(enough & (pxx > 0.0), np.abs(pxy) / pxx, math.nan)


def amplitudes(x: np.ndarray, dt_s: float, exc: Excitation) -> np.ndarray:
    """The amplitude of `x` at each of the excitation's frequencies (NaN where the record
    is too short): the tone's over the whole periods `tone_gain` uses, the square root of
    the Welch power per segment otherwise (comparable between signals, not calibrated)."""
    x = np.asarray(x, dtype=np.float64)
    if exc.bins is None:
        window = _tone_window(len(x), dt_s, float(exc.frequencies_hz[0]))
        if window is None:
            return np.array([math.nan])
        xs, basis = x[len(x) - len(window[1]) :], window[1]
        return np.array([2.0 * abs(complex((xs - xs.mean()) @ basis)) / len(basis)])
    if len(x) < max(exc.segment, MIN_WELCH_SAMPLES):
        return np.full(len(exc.bins), math.nan)
    _, pxx, _ = _spectra(x, x, dt_s, exc.segment)
    segments = 1 + (len(x) - exc.segment) // max(exc.segment // 2, 1)
    return np.sqrt(pxx[exc.bins] / segments)


def gains(
    x: np.ndarray,
    y: np.ndarray,
    dt_s: float,
    exc: Excitation,
    head_amplitudes: np.ndarray | None = None,
) -> list[float | None]:
    """|H| from `x` (the member ahead) to `y` at each of the excitation's frequencies;
    None where it cannot be estimated (record too short, too little input there, or,
    given the chain head's `amplitudes`, less than `MIN_INPUT_SHARE` of them)."""
    if exc.bins is None:  # a sinusoid
        h = tone_gain(x, y, dt_s, float(exc.frequencies_hz[0]))
        found = [None if h is None else abs(h)]
    else:
        n = min(len(x), len(y))
        if n < max(exc.segment, MIN_WELCH_SAMPLES):
            return [None] * len(exc.bins)
        gain = welch_gains(x[:n], y[:n], dt_s, exc.segment)[1][exc.bins]
        found = [None if math.isnan(g) else float(g) for g in gain]
    if head_amplitudes is None:
        return found
    own = amplitudes(x, dt_s, exc)
    return [
        g if a >= MIN_INPUT_SHARE * h else None  # NaN compares False: not estimated
        for g, a, h in zip(found, own, head_amplitudes, strict=True)
    ]


def norm_ratios(previous: np.ndarray, own: np.ndarray) -> tuple[float | None, float | None]:
    """(‖own‖₂ / ‖previous‖₂, ‖own‖∞ / ‖previous‖∞) of two signals on the same grid;
    None where the previous signal is zero."""
    p = np.asarray(previous, dtype=np.float64)
    o = np.asarray(own, dtype=np.float64)
    l2 = math.sqrt(float(o @ o) / float(p @ p)) if float(p @ p) > 0.0 else None
    top = float(np.max(np.abs(p))) if len(p) else 0.0
    linf = float(np.max(np.abs(o))) / top if top > 0.0 else None
    return l2, linf


def follower_gain(m: Mapping[str, Any]) -> float | None:
    """The largest of a follower's gains from the member ahead: acceleration and speed l2
    gains, the frequency response's worst gain and the spacing errors' l2 ratio."""
    keys = ("accel_l2_gain", "speed_l2_gain", "frequency_gain", "spacing_error_l2_ratio")
    values = [float(m[k]) for k in keys if m.get(k) is not None]
    return max(values) if values else None


def assess(
    members: Sequence[Mapping[str, Any]], planned: int, splits: int,
    intact_share: float | None,
) -> dict[str, Any]:  # fmt: skip
    """`string_stable` and `string_stability_verdict` of a platoon, in this order:

    - "no followers": no member had a predecessor in the metrics window;
    - "split": a `split` event, a member that never drove, a follower's scan without its
      predecessor (`lost_scans`; and, where every follower scans, `intact_share < 1`),
      or, under a disturbance, a follower that did not follow (`MIN_FOLLOWING_GAIN`);
    - "no disturbance": the first follower's predecessor (the leader) varied its speed
      by less than `MIN_DISTURBANCE_MPS` (standard deviation) over their common window;
    - "unstable": a follower saturated on at most `MAX_SATURATED_SHARE` of its steps has
      a gain (`follower_gain`) above 1 + `GAIN_TOLERANCE`: it amplifies by its own
      control law (followers whose predecessor's speed kept less than `MIN_INPUT_SHARE`
      of the leader's variation are not judged: the disturbance died out before them);
    - "saturated": a follower saturated on more than that share of its steps;
    - "marginal": a gain above 1 but within the tolerance: as close to 1 as the
      estimates can tell;
    - "stable": otherwise (every gain at most 1).

    `string_stable` is True for "stable", False for "unstable", None (unknown) for
    every other verdict."""
    followers = sorted(
        (m for m in members if m.get("saturated_share") is not None),
        key=lambda m: m["member_index"],
    )
    if not followers:
        return _verdict(NO_FOLLOWERS)
    # followers without a laser have no view to lose (their platoon has no intact_share)
    scanning = all(m.get("in_view_share") is not None for m in followers)
    lost_view = any(m.get("lost_scans") for m in followers) or (
        scanning and intact_share is not None and intact_share < 1.0
    )
    if splits or lost_view or len(members) < planned:
        return _verdict(SPLIT)
    disturbance = followers[0].get("predecessor_speed_std_mps")
    if disturbance is None or disturbance < MIN_DISTURBANCE_MPS:
        return _verdict(NO_DISTURBANCE)
    # followers whose predecessor kept less than MIN_INPUT_SHARE of the leader's speed
    # variation: the platoon damped the disturbance before them, their gains are ratios
    # of remnants (rounding, noise) and are not judged
    reached = [
        m
        for m in followers
        if (m.get("predecessor_speed_std_mps") or 0.0) >= MIN_INPUT_SHARE * disturbance
    ]
    if any((g := follower_gain(m)) is not None and g < MIN_FOLLOWING_GAIN for m in reached):
        return _verdict(SPLIT)
    free = [m for m in reached if m["saturated_share"] <= MAX_SATURATED_SHARE]
    free_gains = [follower_gain(m) for m in free]
    if any(g is not None and g > 1.0 + GAIN_TOLERANCE for g in free_gains):
        return _verdict(UNSTABLE)
    if len(free) < len(reached):
        return _verdict(SATURATED)
    if None in free_gains:  # a follower the disturbance did not reach: nothing to judge
        return _verdict(NO_DISTURBANCE)
    if any(g is not None and g > 1.0 for g in free_gains):
        return _verdict(MARGINAL)
    return _verdict(STABLE)


def _verdict(verdict: str) -> dict[str, Any]:
    stable = True if verdict == STABLE else False if verdict == UNSTABLE else None
    return {"string_stable": stable, "string_stability_verdict": verdict}
