"""What SUMO measures itself: travel times, emissions and the effect on the other traffic.

Nothing here recomputes a SUMO quantity; it asks SUMO for its outputs (options and an
additional file for `edgeData`), then reads and aggregates them:

- tripinfo (`--tripinfo-output`, with the emissions device `--device.emissions.probability
  1` so every trip carries `emissions_*_abs`): travel time, time loss, waiting time,
  fuel, CO2 of every vehicle, ours and human-driven;
- personinfo (`--personinfo-output`): the persons' (and containers') trips, in their
  own file, so they never count as vehicle trips;
- summary (`--summary-output`): network-wide running/halting vehicles, mean speed, mean
  waiting and travel time per step;
- edgeData (an `<edgeData>` in an additional file): per-edge traffic measures per
  interval (speed, density, time loss, waiting time, entered vehicles).

SUMO writes each as CSV (`;`-separated, columns prefixed with the element name) because
the file names end in `.csv`.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

import pandas as pd

SUMO_SUMMARY_FILE = "sumo_summary.csv"
PERSONINFO_FILE = "personinfo.csv"
EDGEDATA_FILE = "edgedata.csv"
EDGEDATA_ADDITIONAL = "edgedata.add.xml"
#: SUMO vehicle classes that are not human-driven road vehicles: reported apart
#: (`other_trips`), never in the human-traffic figures.
OTHER_TRAFFIC_CLASSES = frozenset({
    "pedestrian", "bicycle", "scooter", "wheelchair", "tram", "rail_urban", "rail",
    "rail_electric", "rail_fast", "subway", "cable_car", "ship", "aircraft", "drone",
    "container",
})  # fmt: skip
#: SUMO reports emissions in mg (fuel and gases) and Wh (electricity).
MG_PER_KG = 1e6


def sumo_output_args(directory: Path) -> tuple[str, ...]:
    """Extra SUMO options: emissions device, the network summary and the persons' trips
    (which SUMO would otherwise write into tripinfo, as rows of other columns)."""
    return (
        "--device.emissions.probability", "1",
        "--summary-output", str(directory / SUMO_SUMMARY_FILE),
        "--personinfo-output", str(directory / PERSONINFO_FILE),
    )  # fmt: skip


def write_edgedata_additional(inputs: Path, directory: Path, period_s: float) -> Path:
    """An additional file asking SUMO for edgeData every `period_s` into `directory`."""
    inputs.mkdir(parents=True, exist_ok=True)
    path = inputs / EDGEDATA_ADDITIONAL
    out = (directory / EDGEDATA_FILE).resolve()
    path.write_text(
        "<additional>\n"
        f'    <edgeData id="platoon_sumo" file="{out.as_posix()}" period="{period_s:g}"/>\n'
        "</additional>\n",
        encoding="utf-8",
    )
    return path


def read_sumo_csv(path: Path, prefix: str) -> pd.DataFrame:
    """A SUMO CSV output with `prefix_` dropped from its column names; empty if missing."""
    if not path.is_file() or path.stat().st_size <= 1:
        return pd.DataFrame()
    frame = pd.read_csv(path, sep=";")
    frame.columns = [str(c).removeprefix(prefix) for c in frame.columns]
    return frame


def read_tripinfo(path: Path) -> pd.DataFrame:
    """SUMO's tripinfo as a table; `tripinfo_` dropped, `emissions_` kept."""
    return read_sumo_csv(path, "tripinfo_")


def _mean(series: pd.Series) -> float | None:
    values = pd.to_numeric(series, errors="coerce").dropna()
    return float(values.mean()) if len(values) else None


def _sum(series: pd.Series) -> float | None:
    values = pd.to_numeric(series, errors="coerce").dropna()
    return float(values.sum()) if len(values) else None


def trip_metrics(trips: pd.DataFrame) -> dict[str, dict[str, Any]]:
    """{vehicle id: travel and emission figures} from tripinfo (SUMO's units converted:
    mg -> g)."""
    out: dict[str, dict[str, Any]] = {}
    if trips.empty:
        return out
    for row in trips.to_dict("records"):
        arrived = float(row.get("arrival", -1)) >= 0
        out[str(row["id"])] = {
            "travel_time_s": float(row["duration"]) if arrived else None,
            "route_length_m": _float(row.get("routeLength")),
            "time_loss_s": _float(row.get("timeLoss")),
            "waiting_time_s": _float(row.get("waitingTime")),
            "fuel_g": _grams(row.get("emissions_fuel_abs")),
            "co2_g": _grams(row.get("emissions_CO2_abs")),
            "electricity_wh": _float(row.get("emissions_electricity_abs")),
        }
    return out


def _float(value: Any) -> float | None:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return None if math.isnan(number) else number


def _grams(value: Any) -> float | None:
    mg = _float(value)
    return None if mg is None else mg / 1000.0


def emissions_totals(trips: pd.DataFrame, ids: Collection[str]) -> dict[str, float | None]:
    """Fuel [kg] and CO2 [kg] of the given vehicles (SUMO's emission model)."""
    if trips.empty or "emissions_CO2_abs" not in trips:
        return {"fuel_kg": None, "co2_kg": None}
    mine = trips[trips["id"].astype(str).isin(set(ids))]
    fuel, co2 = _sum(mine["emissions_fuel_abs"]), _sum(mine["emissions_CO2_abs"])
    return {
        "fuel_kg": None if fuel is None else fuel / MG_PER_KG,
        "co2_kg": None if co2 is None else co2 / MG_PER_KG,
    }


def traffic_effect(
    trips: pd.DataFrame,
    platoon_ids: Collection[str],
    summary: pd.DataFrame,
    edgedata: pd.DataFrame,
    route_edges: Collection[str],
    vehicle_classes: Mapping[str, str] | None = None,
) -> dict[str, Any]:
    """The other traffic as SUMO measured it: human-driven trips, network summary, and
    the edges the platoons drive on. Trips of vehicle types whose class (from
    `vehicle_classes`, type -> SUMO vClass) is in `OTHER_TRAFFIC_CLASSES` (bicycles,
    trams, trains, ...) are counted apart, by class, in `other_trips`."""
    others = trips[~trips["id"].astype(str).isin(set(platoon_ids))] if not trips.empty else trips
    other_trips: dict[str, int] = {}
    if len(others) and vehicle_classes and "vType" in others:
        vclass = others["vType"].astype(str).map(lambda t: vehicle_classes.get(t, ""))
        non_car = vclass.isin(OTHER_TRAFFIC_CLASSES)
        other_trips = {str(k): int(v) for k, v in sorted(vclass[non_car].value_counts().items())}
        others = others[~non_car]
    done = others[pd.to_numeric(others["arrival"], errors="coerce") >= 0] if len(others) else others
    result: dict[str, Any] = {
        "human_trips": len(others),
        "human_trips_finished": len(done),
        "human_mean_time_loss_s": _mean(done["timeLoss"]) if len(done) else None,
        "human_mean_waiting_time_s": _mean(done["waitingTime"]) if len(done) else None,
        "human_mean_travel_time_s": _mean(done["duration"]) if len(done) else None,
        "human_total_time_loss_s": _sum(others["timeLoss"]) if len(others) else None,
        **{f"human_{k}": v for k, v in emissions_totals(others, set(
            others["id"].astype(str)) if len(others) else set()).items()},
    }  # fmt: skip
    result["other_trips"] = other_trips
    result.update(network_summary(summary))
    result.update(edge_summary(edgedata, route_edges))
    return result


def person_summary(persons: pd.DataFrame) -> dict[str, Any]:
    """Persons (and containers) SUMO moved: how many, how many finished (a duration
    >= 0), their mean travel time and time loss."""
    if persons.empty or "id" not in persons:
        return {"persons": 0, "persons_finished": 0, "person_mean_travel_time_s": None,
                "person_mean_time_loss_s": None}  # fmt: skip
    duration = pd.to_numeric(persons["duration"], errors="coerce")
    done = persons[duration >= 0]
    return {
        "persons": len(persons),
        "persons_finished": len(done),
        "person_mean_travel_time_s": _mean(done["duration"]) if len(done) else None,
        "person_mean_time_loss_s": _mean(done["timeLoss"]) if len(done) else None,
    }


def network_summary(summary: pd.DataFrame) -> dict[str, Any]:
    """From SUMO's summary output: means over the run's steps, and the last step."""
    if summary.empty:
        keys = ("network_mean_speed_mps", "network_max_halting", "network_mean_waiting_time_s",
                "network_mean_travel_time_s")  # fmt: skip
        return dict.fromkeys(keys)
    speed = pd.to_numeric(summary["meanSpeed"], errors="coerce")
    last = summary.iloc[-1]
    return {
        "network_mean_speed_mps": _mean(speed[speed >= 0]),
        "network_max_halting": int(pd.to_numeric(summary["halting"]).max()),
        "network_mean_waiting_time_s": _float(last["meanWaitingTime"]),
        "network_mean_travel_time_s": _float(last["meanTravelTime"]),
    }


def edge_summary(edgedata: pd.DataFrame, route_edges: Collection[str]) -> dict[str, Any]:
    """edgeData on the platoons' route edges: sampled-time weighted mean speed, total
    time loss and waiting time [s], vehicles entered."""
    keys = ("route_edges_mean_speed_mps", "route_edges_time_loss_s",
            "route_edges_waiting_time_s", "route_edges_entered")  # fmt: skip
    if edgedata.empty or "edge_id" not in edgedata:
        return dict.fromkeys(keys)
    rows = edgedata[edgedata["edge_id"].astype(str).isin(set(route_edges))]
    sampled = pd.to_numeric(rows["edge_sampledSeconds"], errors="coerce").fillna(0.0)
    speed = pd.to_numeric(rows["edge_speed"], errors="coerce")
    ok = speed.notna() & (sampled > 0)
    weight = float(sampled[ok].sum())
    return {
        keys[0]: float((speed[ok] * sampled[ok]).sum() / weight) if weight > 0 else None,
        keys[1]: _sum(rows["edge_timeLoss"]) if len(rows) else None,
        keys[2]: _sum(rows["edge_waitingTime"]) if len(rows) else None,
        keys[3]: int(pd.to_numeric(rows["edge_entered"], errors="coerce").fillna(0).sum()),
    }


def read_run_outputs(
    directory: Path,
) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """tripinfo, summary, edgeData and personinfo tables of a results folder (empty if
    absent)."""
    return (
        read_tripinfo(directory / "tripinfo.csv"),
        read_sumo_csv(directory / SUMO_SUMMARY_FILE, "step_"),
        read_sumo_csv(directory / EDGEDATA_FILE, ""),
        read_sumo_csv(directory / PERSONINFO_FILE, "personinfo_"),
    )


def join_trips(
    vehicles: list[dict[str, Any]], trips: Mapping[str, Mapping[str, Any]]
) -> list[dict[str, Any]]:
    """Per-vehicle summaries with SUMO's travel and emission figures added."""
    empty = dict.fromkeys(("travel_time_s", "route_length_m", "time_loss_s", "waiting_time_s",
                           "fuel_g", "co2_g", "electricity_wh"))  # fmt: skip
    return [{**v, **trips.get(v["vehicle_id"], empty)} for v in vehicles]
