"""MAVLink to a ground station (issue 34, :mod:`swarm.mavlink`), with pymavlink as the client
on loopback: ``swarm run --mavlink udpout:...`` makes every UAV a MAVLink system whose
heartbeats and in-area positions the client sees; one reposition the client sends becomes an
operator waypoint of that UAV (acknowledged, recorded as a ``host`` event), the UAV goes
there, and the run folder replays to the same hash.
"""

from __future__ import annotations

import math
import socket
import threading

import pytest

from swarm import Simulation
from swarm.cli import main
from swarm.kernel.hostlog import schedule_recorded_host_changes
from swarm.mavlink import lonlat_to_metres, metres_to_lonlat
from swarm.outputs import read_json
from swarm.testing.invariants import load_run_log

mavutil = pytest.importorskip("pymavlink.mavutil")

GOAL = (26000.0, 27000.0)  # B1 (system 1) starts at (20000, 22000) heading east


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_metres_and_lonlat_round_trip():
    lon, lat = metres_to_lonlat(*GOAL)
    assert lonlat_to_metres(lon, lat) == pytest.approx(GOAL, abs=1e-6)


@pytest.mark.slow
def test_a_ground_station_sees_every_uav_and_moves_one(tmp_path):
    port = _free_udp_port()
    client = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255, dialect="common")
    heartbeats: dict[int, int] = {}
    positions: dict[int, list[tuple[float, float]]] = {}
    acks: list[int] = []
    stop = threading.Event()

    def ground_station():
        sent = False
        while not stop.is_set():
            msg = client.recv_match(blocking=True, timeout=0.05)
            if msg is None:
                continue
            sysid, kind = msg.get_srcSystem(), msg.get_type()
            if kind == "HEARTBEAT":
                heartbeats[sysid] = heartbeats.get(sysid, 0) + 1
            elif kind == "GLOBAL_POSITION_INT":
                positions.setdefault(sysid, []).append(lonlat_to_metres(msg.lon / 1e7, msg.lat / 1e7))
            elif kind == "COMMAND_ACK":
                acks.append(msg.result)
            if not sent and len(heartbeats) == 3:
                lon, lat = metres_to_lonlat(*GOAL)
                client.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_DO_REPOSITION, 0,
                                             -1, 0, 0, math.nan, lat, lon, 100.0)
                sent = True

    station = threading.Thread(target=ground_station, daemon=True)
    station.start()
    out = tmp_path / "run"
    try:
        code = main(["run", "paper-case1", "--duration", "150", "--mavlink", f"udpout:127.0.0.1:{port}",
                     "--pace", "60", "--out", str(out), "--no-figures", "--quiet"])
    finally:
        stop.set()
        station.join(timeout=5)
        client.close()
    assert code == 0
    assert set(heartbeats) == {1, 2, 3} and min(heartbeats.values()) >= 100  # one per tick, UDP on loopback
    for sysid, pts in positions.items():
        assert all(0.0 <= x <= 50000.0 and 0.0 <= y <= 50000.0 for x, y in pts), sysid
    assert acks == [mavutil.mavlink.MAV_RESULT_ACCEPTED]
    scenario, events = load_run_log(out)
    hosts = [e for e in events if e.kind == "host"]
    assert [(e.change, e.args["uav"]) for e in hosts] == [("set_waypoint", "B1")]
    assert (hosts[0].args["x"], hosts[0].args["y"]) == pytest.approx(GOAL, abs=2.0)  # (COMMAND_LONG: float32 degrees)
    b1 = [(e.x, e.y) for e in events if e.kind == "pose" and e.uav == 0 and e.t > hosts[0].t]
    assert min(math.hypot(x - GOAL[0], y - GOAL[1]) for x, y in b1) < 1000.0  # it went there
    with Simulation(scenario) as replay:
        assert schedule_recorded_host_changes(replay, events) == 1
        again = replay.run()
    assert again.metrics["event_log_sha256"] == read_json(out / "metrics.json")["event_log_sha256"]
