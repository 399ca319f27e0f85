"""What `loop.progress.at_light` relies on, read from the real SUMO: where the next
light on a car's route lies exactly at the end of its lane, SUMO's link at that end
exists and shows the light's state, so the stages need not ask SUMO for the link.
The network mixes lights with priority and right-before-left junctions."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import libsumo

from platoon_sumo.loop.standoff import UNSIGNALISED_YIELD
from platoon_sumo.sumo.backend import SumoBackend, SumoOptions, sumo_home
from platoon_sumo.world import LinkAhead
from tests.helpers import REPO

NET = REPO / "networks" / "drt_city" / "drt_city.net.xml.gz"


def test_a_light_at_the_end_of_the_lane_is_the_link_there(tmp_path):
    trips = tmp_path / "trips.xml"
    script = Path(sumo_home()) / "tools" / "randomTrips.py"
    subprocess.run(
        [sys.executable, str(script), "-n", str(NET), "-o", str(trips), "--end", "150",
         "--period", "0.5", "--seed", "1", "--min-distance", "500"],
        check=True, capture_output=True, env={**os.environ, "SUMO_HOME": sumo_home()},
    )  # fmt: skip
    backend = SumoBackend(SumoOptions(str(NET), 0.1, 1, route_files=(str(trips),)))
    backend.start()
    at_light = other_links = 0
    try:
        for _ in range(1500):
            backend.step()
            ids = list(libsumo.vehicle.getIDList())
            backend.snapshot(ids, 0.0)
            contexts = backend.route_contexts(ids, [200.0] * len(ids), [False] * len(ids))
            for vid, (signal, _, end) in zip(ids, contexts, strict=True):
                if signal is None or not isinstance(end, float):
                    continue
                if signal.distance_m != end:
                    other_links += backend.link_ahead(vid, end) is not None
                    continue
                link = backend.link_ahead(vid, end)
                assert isinstance(link, LinkAhead), (vid, signal)
                assert link.state == signal.state, (vid, link, signal)
                assert link.state not in UNSIGNALISED_YIELD
                at_light += 1
    finally:
        backend.close()
    assert at_light > 500 and other_links > 500  # cars met lights and other junctions
