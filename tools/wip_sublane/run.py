import json, sys, pathlib, yaml
sys.path.insert(0, "/tmp/slx")
import pandas as pd
from platoon_sumo.runner import load_plan, run
act = sys.argv[1]
scenario = {
    "simulation": {"step_s": 0.1, "end_s": 60.0, "seed": 1, "lateral_resolution_m": 0.4},
    "network": {"net_file": "/work/main/networks/straight/straight.net.xml"},
    "platoons": [{
        "id": "p", "members": 2, "spacing_m": 8.0, "depart_s": 1.0, "actuation": act,
        "route": {"edges": ["WE"]},
        "leader": {"type": "weave:Weave", "params": {"offset_m": float(sys.argv[2]) if len(sys.argv) > 2 else 0.8}},
        "follower": {"type": "laser_follower", "sensor": {"preset": "utm30lx"},
                     "params": {"on_lost": "route_following", "corridor_margin_rel": 1.2}},
    }],
}
p = pathlib.Path(f"/tmp/slx/{act}.yaml"); p.write_text(yaml.safe_dump(scenario))
out = run(load_plan(p), pathlib.Path(f"/tmp/slx/out_{act}")).directory
t = pd.read_csv(out / "trajectories.csv")
s = json.loads((out / "summary.json").read_text())
print(act, s["collisions"], s["platoon_vehicles"])
w = t.pivot_table(index="time_s", columns="vehicle_id", values="lateral_offset_m")
print(w.iloc[::50].to_string())
print(t.pivot_table(index="time_s", columns="vehicle_id", values="lane_id", aggfunc="first").iloc[::50].to_string())
