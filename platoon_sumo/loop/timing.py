"""Where a run's CPU time goes: each stage, SUMO's step, the step record and each hook.

Opt-in (`platoon-sumo run --timings`): every part's end reads the thread's CPU clock
(about 0.6 µs a read, some 30 reads a step). The loop hands its parts to `lap` in order;
the time between two laps is the later part's. `table()` gives the totals with each
part's share and its cost per step and per platoon vehicle-step.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import pandas as pd

#: Columns of `StageTimings.table` (and of a run's `timings.csv`).
TIMING_COLUMNS = (
    "part", "kind", "cpu_s", "share", "us_per_step", "us_per_platoon_vehicle_step",
)  # fmt: skip

#: What a part is, in `TIMING_COLUMNS`' "kind".
BEFORE_SUMO, SUMO, AFTER_SUMO, RECORD, HOOK, OUTSIDE = (
    "stage before SUMO's step", "SUMO's step", "stage after SUMO's step", "step record", "hook",
    "outside the step loop",
)  # fmt: skip


class StageTimings:
    """CPU seconds of the loop's parts, by name, summed over the run's steps."""

    def __init__(self, clock: Callable[[], float] = time.thread_time) -> None:
        self._clock = clock
        self._last = 0.0
        self.cpu_s: dict[tuple[str, str], float] = {}
        """By (part, kind), in the order the parts first ran."""
        self.steps = 0
        self.vehicle_steps = 0
        """Platoon vehicles summed over the steps (each vehicle once a step)."""

    def start(self) -> None:
        """A step begins: nothing before this counts."""
        self._last = self._clock()

    def lap(self, part: str, kind: str) -> None:
        """`part` has just ended: the time since the last lap (or `start`) is its."""
        now = self._clock()
        self.add(part, kind, now - self._last)
        self._last = now

    def add(self, part: str, kind: str, cpu_s: float) -> None:
        key = (part, kind)
        self.cpu_s[key] = self.cpu_s.get(key, 0.0) + cpu_s

    def end_step(self, platoon_vehicles: int) -> None:
        self.steps += 1
        self.vehicle_steps += platoon_vehicles

    def table(self) -> pd.DataFrame:
        """One row per part, dearest first (`TIMING_COLUMNS`): its share of all the
        parts' CPU time, its cost per step and per platoon vehicle-step (NaN when no
        platoon vehicle was in the network)."""
        total = sum(self.cpu_s.values())
        rows = [
            (
                part,
                kind,
                cpu,
                cpu / total if total > 0 else float("nan"),
                cpu / self.steps * 1e6 if self.steps else float("nan"),
                cpu / self.vehicle_steps * 1e6 if self.vehicle_steps else float("nan"),
            )
            for (part, kind), cpu in self.cpu_s.items()
        ]
        frame = pd.DataFrame(rows, columns=list(TIMING_COLUMNS)).round(
            {"cpu_s": 6, "share": 4, "us_per_step": 2, "us_per_platoon_vehicle_step": 2}
        )
        return frame.sort_values("cpu_s", ascending=False, kind="stable").reset_index(drop=True)


def headline(table: pd.DataFrame, parts: int = 5) -> str:
    """The dearest parts' shares, and the loop's own cost (every part of the step but
    SUMO's) per platoon vehicle-step, in one line."""
    dearest = ", ".join(
        f"{row.part} {100 * row.share:.0f} %" for row in table.head(parts).itertuples()
    )
    in_loop = table[~table["kind"].isin([SUMO, OUTSIDE])]
    per_vehicle = in_loop["us_per_platoon_vehicle_step"].sum(min_count=1)
    ours = (
        ""
        if pd.isna(per_vehicle)
        else f"; the loop's own {per_vehicle:.0f} µs per platoon vehicle-step"
    )
    return f"CPU by part: {dearest}{ours}"
