"""`sumo_driver`: SUMO's own car-following model drives a member, the loop records it.

Closed loop through SUMO on the straight road: a speed-profile leader cruises at 14 m/s,
then brakes to a stop and stays. Each follower's gap to its predecessor is checked
against the model's own equilibrium formula at the steady speed (IDM: (s0 + v T) /
sqrt(1 - (v / v0)^delta); Krauss: s0 + v tau, where its safe speed equals the leader's
speed) and against s0 (SUMO's minGap) at standstill. Two IDM runs that differ only in
`delta` and a Krauss run must each land on their own formula: the model and its
parameters reach SUMO.
"""

from __future__ import annotations

import json
import math
import textwrap
from pathlib import Path

import pandas as pd
import pytest

from platoon_sumo.config_loader import load_dataclass
from platoon_sumo.control.sumo_driver import SumoDriver, SumoDriverParams, sumo_models
from platoon_sumo.errors import ScenarioError
from platoon_sumo.runner import load_plan, run
from tests.helpers import REPO

CRUISE_MPS, V0_MPS, S0_M, T_S = 14.0, 20.0, 2.0, 1.2
BRAKE_AT_S = 100.0


def test_models_and_attributes_come_from_sumos_schema() -> None:
    models = sumo_models()
    assert {"Krauss", "IDM", "EIDM", "ACC", "CACC", "W99"} <= set(models)
    assert {"delta", "stepping"} <= set(models["IDM"])
    assert "speedControlGainCACC" in models["CACC"]
    assert "speedControlGainCACC" not in models["ACC"]


def test_params_become_the_vehicle_type_request() -> None:
    params = load_dataclass(
        SumoDriverParams,
        {"car_follow_model": "CACC", "tau_s": 0.6, "parameters": {"speedControlGainCACC": -0.5}},
        "x.yaml",
    )
    cf = SumoDriver.sumo_car_following(params)
    assert (cf.model, cf.tau_s, cf.min_gap_m) == ("CACC", 0.6, None)
    assert dict(cf.attributes) == {"speedControlGainCACC": "-0.5"}
    with pytest.raises(ScenarioError, match=r"x.yaml: car_follow_model: unknown value 'Kraus'"):
        load_dataclass(SumoDriverParams, {"car_follow_model": "Kraus"}, "x.yaml")


def _scenario(folder: Path, name: str, follower: str) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(
        textwrap.dedent(f"""\
        simulation: {{step_s: 0.1, end_s: {BRAKE_AT_S + 25.0}, seed: 1}}
        network: {{net_file: {REPO / "networks/straight/straight.net.xml"}}}
        platoons:
          - id: p
            route: {{edges: [WE]}}
            members: 4
            spacing_m: 10.0
            depart_pos_m: 120.0
            actuation: lane
            vehicle: {{max_speed_mps: {V0_MPS}, max_accel_mps2: 2.0, max_decel_mps2: 4.5,
                       min_gap_m: 2.5, sumo_tau_s: 0.1, sumo_speed_factor: 1.0}}
            leader:
              type: speed_profile
              params: {{profile: brake, cruise_speed_mps: {CRUISE_MPS}, start_s: {BRAKE_AT_S},
                        low_speed_mps: 0.0, decel_mps2: 2.0, hold_s: 1000.0}}
            follower: {follower}
        outputs: {{directory: {folder / name}, metrics_start_s: 0.0}}
        """)
    )
    return path


def _sumo_driver(model: str, extra: str = "") -> str:
    params = f"car_follow_model: {model}, tau_s: {T_S}, min_gap_m: {S0_M}{extra}"
    return f"{{type: sumo_driver, params: {{{params}}}}}"


FOLLOWERS = {
    "idm": _sumo_driver("IDM"),
    "idm_delta2": _sumo_driver("IDM", ", parameters: {delta: 2}"),
    "krauss": _sumo_driver("Krauss"),
}


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("sumo_driver")
    for name, follower in FOLLOWERS.items():
        run(load_plan(_scenario(folder, name, follower)))
    return {name: folder / name for name in FOLLOWERS}


def _gaps_at(out: Path, time_s: float) -> list[float]:
    t = pd.read_csv(out / "trajectories.csv")
    row = t[((t.time_s - time_s).abs() < 1e-6) & (t.member_index > 0)]
    assert len(row) == 3
    return row.sort_values("member_index").gap_to_predecessor_m.tolist()


def _idm_gap(delta: float) -> float:
    return (S0_M + CRUISE_MPS * T_S) / math.sqrt(1.0 - (CRUISE_MPS / V0_MPS) ** delta)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "expected_m"),
    [("idm", _idm_gap(4.0)), ("idm_delta2", _idm_gap(2.0)), ("krauss", S0_M + CRUISE_MPS * T_S)],
)
def test_each_follower_keeps_its_models_gap(
    runs: dict[str, Path], name: str, expected_m: float
) -> None:
    # the three formulas lie metres apart (21.6, 26.3 and 18.8 m): each run meets its own
    for gap in _gaps_at(runs[name], BRAKE_AT_S - 0.1):
        assert gap == pytest.approx(expected_m, abs=0.1)
    for gap in _gaps_at(runs[name], BRAKE_AT_S + 24.9):  # all standing: s0
        assert gap == pytest.approx(S0_M, abs=0.05)


@pytest.mark.slow
def test_sumo_driven_members_are_recorded_and_measured(runs: dict[str, Path]) -> None:
    out = runs["idm"]
    t = pd.read_csv(out / "trajectories.csv")
    followers = t[t.member_index > 0]
    assert set(followers.vehicle_id) == {"p.1", "p.2", "p.3"}
    assert set(followers.controller_mode.dropna()) == {"sumo_IDM"}
    assert followers.lane_id.eq("WE_0").all()  # SUMO keeps the lane
    assert followers.predecessor_id.notna().all() and followers.ahead_gap_m.notna().all()
    assert followers.spacing_error_m.isna().all()  # SUMO's models declare no policy
    # the supervisor only checks: it found nothing to object to on this drive
    assert followers.supervisor.isna().all()
    (platoon,) = pd.read_csv(out / "platoons.csv").to_dict("records")
    assert platoon["members"] == 4 and platoon["splits"] == 0 and platoon["collisions"] == 0
    assert platoon["min_gap_m"] == pytest.approx(S0_M, abs=0.05)
    vehicles = pd.read_csv(out / "vehicles.csv")
    assert {"p.1", "p.2", "p.3"} <= set(vehicles.vehicle_id)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["collisions"] == 0 and summary["sumo_collisions_with_platoons"] == 0
    types = (out / "inputs" / "car_following_types.add.xml").read_text()
    assert 'id="platoon_p_follower_model" carFollowModel="IDM"' in types
