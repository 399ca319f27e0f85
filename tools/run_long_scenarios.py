"""Run the real-network scenarios full length and tabulate their safety figures.

Runs `scenarios/city_platoons.yaml` and `scenarios/motorway_platoons.yaml` (each in its
own process: libsumo runs one simulation per process), prints a Markdown table and
writes it, with the command that produced it, to `docs/real_networks.md` (between the
markers there; the rest of that page is kept).

    python tools/run_long_scenarios.py                         # both, full length
    python tools/run_long_scenarios.py --end 300 --no-doc      # a quick look
    python tools/run_long_scenarios.py --only motorway_platoons --jobs 1
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
import traceback
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ("city_platoons", "motorway_platoons")
DOC = ROOT / "docs" / "real_networks.md"
BEGIN, END = "<!-- run_long_scenarios: begin -->", "<!-- run_long_scenarios: end -->"


def run_one(name: str, out_root: str, end_s: float | None) -> dict[str, Any]:
    """One scenario in this (fresh) process; a failure is returned, not raised."""
    from platoon_sumo.runner import load_plan, run

    out = Path(out_root) / name
    try:
        result = run(load_plan(ROOT / "scenarios" / f"{name}.yaml", end_s=end_s), out_dir=out)
        return {"name": name, "out": str(out), "summary": result.summary}
    except Exception as exc:  # report the failure in the table, keep the other run
        return {
            "name": name,
            "out": str(out),
            "error": f"{type(exc).__name__}: {exc}",
            "trace": traceback.format_exc(limit=3),
        }


def row(result: dict[str, Any]) -> list[str]:
    name = result["name"]
    if "error" in result:
        return [name, "FAILED: " + result["error"].replace("|", "/"), *[""] * (len(HEADER) - 2)]
    s = result["summary"]
    pv, av = s["platoon_vehicles"], s["all_vehicles"]
    events = s.get("platoon_events", {})
    collisions = s["collisions"]
    if collisions:
        first = s["collision_events"][:3]
        ids = ", ".join(f"{c['vehicle_a']}/{c['vehicle_b']}@{c['time_s']:.1f}s" for c in first)
        collisions = f"{collisions} ({ids}{', ...' if s['collisions'] > 3 else ''})"
    return [
        name,
        f"{s['simulated_s']:.0f}",
        f"{s['real_time_factor']}",
        str(len({k for k in (s.get("platoons") or {})}) or "-"),
        f"{pv['planned']}",
        f"{pv['arrived']}/{pv['departed']}",
        f"{av['departed'] - pv['departed']}",
        str(collisions),
        str(s["teleports"]),
        str(s["red_light_violations"]),
        str(s.get("emergency_brakings", "-")),
        str(s.get("sumo_speed_caps", "-")),
        f"{s.get('sumo_collisions', '-')} ({s.get('sumo_collisions_with_platoons', '-')})",
        " / ".join(str(events.get(k, "-")) for k in ("splits", "reformations", "cut_ins")),
    ]


HEADER = [
    "scenario", "simulated s", "real-time factor", "platoons", "platoon vehicles",
    "arrived/departed", "SUMO vehicles", "footprint collisions", "teleports",
    "red-light violations", "emergency brakings", "SUMO speed caps",
    "SUMO collision reports (with platoons)",
    "splits / re-formations / cut-ins",
]  # fmt: skip


def table(results: list[dict[str, Any]]) -> str:
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    lines += ["| " + " | ".join(row(r)) + " |" for r in results]
    return "\n".join(lines)


def write_doc(text: str) -> None:
    page = DOC.read_text(encoding="utf-8") if DOC.exists() else f"{BEGIN}\n{END}\n"
    if BEGIN not in page or END not in page:
        page += f"\n{BEGIN}\n{END}\n"
    head, rest = page.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    DOC.write_text(f"{head}{BEGIN}\n{text}\n{END}{tail}", encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=SCENARIOS, action="append", help="run only these")
    ap.add_argument("--end", type=float, default=None, help="override simulation.end_s")
    ap.add_argument("--out", default="results/long", help="results root folder")
    ap.add_argument("--jobs", type=int, default=2, help="scenarios run in parallel")
    ap.add_argument("--no-doc", action="store_true", help=f"do not rewrite {DOC.name}")
    args = ap.parse_args(argv)
    names = args.only or list(SCENARIOS)
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(max(1, min(args.jobs, len(names)))) as pool:
        results = pool.starmap(run_one, [(n, args.out, args.end) for n in names])
    for r in results:
        if "error" in r:
            print(f"{r['name']} failed:\n{r['trace']}", file=sys.stderr)
        else:
            (Path(r["out"]) / "long_run.json").write_text(json.dumps(r["summary"], indent=2))
    text = table(results)
    command = "python tools/run_long_scenarios.py" + " ".join(
        [""] + (argv if argv is not None else sys.argv[1:])
    )
    print(text)
    if not args.no_doc:
        from platoon_sumo.sumo.backend import sumo_version

        write_doc(f"Produced by `{command.strip()}` ({sumo_version()}).\n\n{text}")
    return 0 if all("error" not in r for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
