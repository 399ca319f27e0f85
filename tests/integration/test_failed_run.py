"""A controller that raises in the middle of a real run: the rows up to that step are
on disk, the run is marked failed, and no summary passes it off as complete."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
import yaml

from platoon_sumo.cli import main

ROOT = Path(__file__).resolve().parents[2]
PLUGINS = ROOT / "tests" / "plugins"
FAIL_AT_S = 3.0


def scenario() -> dict:
    return {
        "simulation": {"step_s": 0.1, "end_s": 20.0, "seed": 3},
        "network": {"net_file": str(ROOT / "networks" / "straight" / "straight.net.xml")},
        "platoons": [
            {
                "id": "p",
                "route": {"edges": ["WE"]},
                "members": 3,
                "spacing_m": 8.0,
                "depart_pos_m": 60.0,
                "actuation": "lane",
                "vehicle": {"model": "bicycle", "length_m": 4.5, "width_m": 1.8},
                "leader": {"type": "route_following"},
                "follower": {
                    "type": "failing_controller:FailsAt",
                    "params": {"fail_at_s": FAIL_AT_S},
                },
            }
        ],
    }


def test_a_controller_raising_mid_run_keeps_every_row_and_marks_the_run_failed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.syspath_prepend(str(PLUGINS))
    path = tmp_path / "fails.yaml"
    path.write_text(yaml.safe_dump(scenario(), sort_keys=False), encoding="utf-8")
    out = tmp_path / "out"

    code = main(["run", str(path), "--out", str(out), "--quiet"])

    _, err = capfd.readouterr()
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err
    assert "failing_controller.FailsAt" in err and "'p.1'" in err and "t=3.00 s" in err
    assert "ZeroDivisionError" in err
    assert "ZeroDivisionError" in (out / "FAILED.txt").read_text()
    assert not (out / "summary.json").exists()

    rows = pd.read_csv(out / "trajectories.csv")
    # every step the loop finished is on disk, for every member, up to the failing one
    # (the controllers decide at t = 3.0 s on the world after the step that ended there)
    assert rows["time_s"].max() == pytest.approx(FAIL_AT_S)
    per_step = rows.groupby("time_s")["vehicle_id"].apply(lambda ids: sorted(ids))
    first = float(per_step.index.min())
    steps = round((FAIL_AT_S - first) / 0.1) + 1
    assert len(per_step) == steps  # no step missing
    assert list(per_step.iloc[-1]) == ["p.0", "p.1", "p.2"]
    events = pd.read_csv(out / "events.csv")
    assert set(events["kind"]) >= {"departed"}
