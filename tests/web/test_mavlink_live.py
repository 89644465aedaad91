"""Ground stations against `lotsen run` at wall-clock pace (issue 40): pymavlink as a ground
station, unsigned and signed, and a scripted MAVProxy session, all on one run of the stack
(module-scoped: the run starts once, ~30 s on this machine), each on its own `--mavlink
udpout:` endpoint. The tests run in file order and continue the same boat's story.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time
from pathlib import Path

import pymap3d
import pytest

from tests.web.mavlink_gcs import Boat, GroundStation, free_udp_port

pytestmark = pytest.mark.live

MAVPROXY = "1.8.75"  # installed for these tests only, without its GUI dependencies (conftest below)
HARBOUR = (4.0, 20.0)  # the demo config's harbour (north, east)
#: the short live route (lotsen.stack.soak.SHORT_ROUTE) relative to the harbour, yaw 360 = north
NODES = [(6.0, 0.0, 360.0), (12.0, 4.0, 60.0), (18.0, 10.0, 45.0), (26.0, 10.0, 360.0)]
AREA = [(-4.0, -20.0), (36.0, -20.0), (36.0, 20.0), (-4.0, 20.0)]
ARM, SET_MODE, RTL = 400, 176, 20
ACCEPTED, TEMPORARILY_REJECTED, DENIED = 0, 1, 2


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    ports = [free_udp_port() for _ in range(3)]  # signed pymavlink, unsigned pymavlink, MAVProxy
    work = tmp_path_factory.mktemp("mavlink-live")
    signed, unsigned = GroundStation(ports[0]), GroundStation(ports[1], system=254)
    boat = Boat(work, ports)
    state: dict = {"boat": boat, "signed": signed, "unsigned": unsigned, "mavproxy_port": ports[2], "work": work}
    try:
        hb = signed.wait(lambda m: m.get_type() == "HEARTBEAT" and m.custom_mode != 16, 150)  # 16: INITIALISING
        assert hb is not None, "no HEARTBEAT with a mode from the boat:\n" + "\n".join(boat.output[-30:])
        yield state
    finally:
        signed.close()
        unsigned.close()
        code = boat.stop()
        print("\n".join(boat.output[-15:]))
        assert code == 0, boat.output[-20:]
        assert not [ln for ln in boat.output if "Traceback" in ln or "control loop silent" in ln]


def _install_mavproxy() -> None:
    """MAVProxy for this test only: `pip install --no-deps` (its GUI dependencies, wxPython, OpenCV,
    VTK, are not needed by the console modules used here, and are heavy)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        if version("MAVProxy") == MAVPROXY:
            return
    except PackageNotFoundError:
        pass
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", f"MAVProxy=={MAVPROXY}"], check=True,
                   timeout=300)


def _geo(home, n: float, e: float) -> tuple[float, float]:
    lat, lon, _ = pymap3d.ned2geodetic(n, e, 0.0, home[0], home[1], 0.0)
    return float(lat), float(lon)


def test_the_boat_is_an_ardupilot_rover_with_a_whole_parameter_list(run):
    gcs: GroundStation = run["unsigned"]
    hb = gcs.wait(lambda m: m.get_type() == "HEARTBEAT", 10, since=time.monotonic())
    assert (hb.type, hb.autopilot) == (11, 3)  # MAV_TYPE_SURFACE_BOAT, ArduPilot
    assert hb.custom_mode == 0 and hb.get_srcSystem() == 1  # MANUAL, Rover's number
    t0 = time.monotonic()
    gcs.send(lambda mav: mav.param_request_list_send(1, 1))
    first = gcs.wait(lambda m: m.get_type() == "PARAM_VALUE", 10, since=t0)
    assert first is not None
    time.sleep(1.0)
    got = {m.param_id: m for t, m in list(gcs.log) if t >= t0 and m.get_type() == "PARAM_VALUE"}
    assert len(got) == first.param_count and {m.param_index for m in got.values()} == set(range(first.param_count))
    assert all(len(name) <= 16 for name in got)
    assert {"WP_SPEED", "PLN_SPEED_MAX", "MDL_M11", "FS_LINK_TMO", "FS_GCS_TMO"} <= set(got)
    for name in ("GPS_RAW_INT", "GLOBAL_POSITION_INT", "ATTITUDE", "SYS_STATUS", "VFR_HUD", "HOME_POSITION"):
        assert gcs.wait(lambda m, n=name: m.get_type() == n, 10) is not None, name
    run["home"] = gcs.wait(lambda m: m.get_type() == "HOME_POSITION", 1)


def test_an_unsigned_ground_station_sees_everything_and_changes_nothing(run):
    gcs: GroundStation = run["unsigned"]
    ack, texts = gcs.command(ARM, 1)
    assert ack is not None and ack.result == DENIED
    assert any("arm refused" in t and "not signed" in t for t in texts), texts
    ack, texts = gcs.command(SET_MODE, 1, 10)  # AUTO
    assert ack.result == DENIED
    home = run["home"]
    lat, lon = home.latitude * 1e-7, home.longitude * 1e-7
    mack = gcs.upload([(16, 0, 0, 0, 0, 0, lat, lon, 0), (16, 3, 0, 0, 0, 0, *_geo((lat, lon), 6, 0), 0)])
    assert mack is not None and mack.type == 14  # MAV_MISSION_DENIED
    t0 = time.monotonic()
    before = gcs.wait(lambda m: m.get_type() == "PARAM_VALUE" and m.param_id == "PLN_SPEED_MAX", 5)
    gcs.send(lambda mav: mav.param_set_send(1, 1, b"PLN_SPEED_MAX", 0.3, 9))
    after = gcs.wait(lambda m: m.get_type() == "PARAM_VALUE" and m.param_id == "PLN_SPEED_MAX", 5, since=t0)
    assert after.param_value == pytest.approx(before.param_value)  # unchanged
    assert any("PLN_SPEED_MAX not set" in t for t in gcs.texts(since=t0))


def test_a_signed_ground_station_uploads_arms_runs_auto_returns_and_drives(run):
    gcs: GroundStation = run["signed"]
    gcs.sign(run["boat"].token)
    time.sleep(1.5)  # its signed heartbeat takes the free pilot seat
    # arming before the ESCs are ready is refused with ArduPilot's "PreArm:" text
    ack, texts = gcs.command(ARM, 1)
    assert ack is not None and ack.result == TEMPORARILY_REJECTED, (ack, texts)
    assert any(t.startswith("PreArm:") and "ESC" in t for t in texts), texts
    # mission (home + speed + 4 waypoints) and fence, uploaded and read back
    home = run["home"]
    h = (home.latitude * 1e-7, home.longitude * 1e-7)
    mission = [(16, 0, 0, 0, 0, 0, *h, 0), (178, 2, 1, 0.5, -1, 0, 0, 0, 0)]
    mission += [(16, 3, 0, 0, 0, yaw, *_geo(h, n, e), 0) for n, e, yaw in NODES]
    ack = gcs.upload(mission)
    assert ack is not None and ack.type == 0, (ack, gcs.texts()[-5:])
    fence = [(5001, 0, len(AREA), 0, 0, 0, *_geo(h, n, e), 0) for n, e in AREA]
    ack = gcs.upload(fence, mission_type=1)
    assert ack is not None and ack.type == 0, (ack, gcs.texts()[-5:])
    for items, kind in ((mission, 0), (fence, 1)):
        back = gcs.download(kind)
        assert back is not None and len(back) == len(items)
        for sent, got in zip(items, back):
            assert (got.command, got.frame) == (sent[0], sent[1])
            assert [got.param1, got.param2, got.param3, got.param4] == pytest.approx(list(sent[2:6]))
            if sent[0] != 178:
                assert (got.x, got.y) == (int(round(sent[6] * 1e7)), int(round(sent[7] * 1e7)))
    # the ESCs get ready: arm, AUTO, the boat reaches the first waypoint
    deadline = time.monotonic() + 30
    while True:
        ack, texts = gcs.command(ARM, 1)
        if ack is not None and ack.result == ACCEPTED or time.monotonic() > deadline:
            break
        time.sleep(1.0)
    assert ack is not None and ack.result == ACCEPTED, texts
    t0 = time.monotonic()
    ack, texts = gcs.command(SET_MODE, 1, 10)
    assert ack.result == ACCEPTED, texts
    assert gcs.wait(lambda m: m.get_type() == "HEARTBEAT" and m.custom_mode == 10 and m.base_mode & 128, 5, t0)
    reached = gcs.wait(lambda m: m.get_type() == "MISSION_ITEM_REACHED", 45, since=t0)
    assert reached is not None and reached.seq == 2, gcs.texts(since=t0)[-5:]  # item 2: the first waypoint
    # RTL, then LOITER (lotsen's HOLD), then MANUAL and drive ahead with MANUAL_CONTROL
    ack, texts = gcs.command(RTL)
    assert ack.result == ACCEPTED, texts
    assert gcs.wait(lambda m: m.get_type() == "HEARTBEAT" and m.custom_mode == 11, 5, time.monotonic() - 0.5)
    ack, _ = gcs.command(SET_MODE, 1, 5)
    assert ack.result == ACCEPTED
    ack, _ = gcs.command(SET_MODE, 1, 0)
    assert ack.result == ACCEPTED
    time.sleep(2.0)  # the station keeping's last push fades
    start = gcs.wait(lambda m: m.get_type() == "GLOBAL_POSITION_INT", 2, time.monotonic())
    for _ in range(30):  # 3 s at 10 Hz, full ahead
        gcs.send(lambda mav: mav.manual_control_send(1, 1000, 0, 500, 0, 0))
        time.sleep(0.1)
    end = gcs.wait(lambda m: m.get_type() == "GLOBAL_POSITION_INT", 2, time.monotonic())
    moved = math.hypot(end.lat - start.lat, (end.lon - start.lon) * math.cos(math.radians(h[0]))) * 1.11e-2
    assert moved > 0.5, f"moved {moved:.2f} m"
    ack, _ = gcs.command(ARM, 0)  # disarm: the next ground station arms for itself
    assert ack.result == ACCEPTED
    # silence: no heartbeat, nothing -> the boat's link failsafe, seen by every ground station
    gcs.heartbeats = False
    t0 = time.monotonic()
    text = run["unsigned"].wait(lambda m: m.get_type() == "STATUSTEXT" and "link_lost" in m.text, 10, since=t0)
    assert text is not None, run["unsigned"].texts(since=t0)
    assert time.monotonic() - t0 >= 2.5  # not before the ground station's 3 s timeout


def test_a_scripted_mavproxy_session_uploads_arms_and_reaches_a_waypoint(run, tmp_path):
    """MAVProxy (its console commands through stdin): the signing passphrase, `wp load` of a QGC
    WPL 110 file, `arm throttle`, `mode auto`; the boat reaches the first waypoint."""
    home = run["home"]
    h = (home.latitude * 1e-7, home.longitude * 1e-7)
    pos = run["signed"].wait(lambda m: m.get_type() == "GLOBAL_POSITION_INT", 2, time.monotonic())
    here = (pos.lat * 1e-7, pos.lon * 1e-7)  # the route starts where the boat is (the harbour = home)
    north, east, _ = pymap3d.geodetic2ned(here[0], here[1], 0, h[0], h[1], 0)
    # towards the middle of the basin (20 m north of the harbour), inside the fence uploaded above
    bearing = math.atan2(0.0 - east, 20.0 - north)
    rows = [(0, 1, 0, 16, 0, 0, 0, 0, *here, 0, 1)]
    for k, d in enumerate((5.0, 9.0), start=1):
        rows.append((k, 0, 3, 16, 0, 0, 0, 0, *_geo(h, north + d * math.cos(bearing), east + d * math.sin(bearing)),
                     0, 1))
    _install_mavproxy()
    wpl = tmp_path / "mission.waypoints"
    wpl.write_text("QGC WPL 110\n" + "\n".join("\t".join(str(v) for v in r) for r in rows) + "\n")
    token = run["boat"].token
    proc = subprocess.Popen([sys.executable, "-m", "MAVProxy.mavproxy", f"--master=udpin:127.0.0.1:{run['mavproxy_port']}",
                             "--no-state", "--nodtr", "--source-system=253"], cwd=tmp_path, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**os.environ, "MAVLINK20": "1"})
    lines: list[str] = []
    import threading

    threading.Thread(target=lambda: [lines.append(ln.rstrip()) for ln in proc.stdout], daemon=True).start()

    def say(cmd: str) -> None:
        proc.stdin.write(cmd + "\n")
        proc.stdin.flush()

    def seen(pred, timeout_s: float) -> bool:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if any(pred(ln) for ln in list(lines)):
                return True
            time.sleep(0.2)
        return False

    try:
        assert seen(lambda ln: "online system 1" in ln or "MANUAL>" in ln or "Mode MANUAL" in ln, 30), lines[-20:]
        say(f"signing key {token}")
        time.sleep(2.0)
        say(f"wp load {wpl}")
        assert seen(lambda ln: "Sent all 3 waypoints" in ln or "Loaded 3 waypoint" in ln, 20), lines[-20:]
        assert seen(lambda ln: "MISSION_ACK" in ln and "ACCEPTED" in ln or "Sent all" in ln, 20), lines[-20:]
        assert not seen(lambda ln: ln.strip() == "ARMED", 0.5), "the boat must start disarmed"
        say("arm throttle")
        assert seen(lambda ln: "Got COMMAND_ACK: COMPONENT_ARM_DISARM: ACCEPTED" in ln, 15), lines[-25:]
        say("mode auto")
        assert seen(lambda ln: "AUTO>" in ln or "Mode AUTO" in ln, 15), lines[-25:]
        assert seen(lambda ln: "Reached waypoint #1" in ln, 40), lines[-25:]
        say("mode loiter")
        assert seen(lambda ln: "LOITER>" in ln or "Mode LOITER" in ln, 15), lines[-25:]
    finally:
        try:
            say("disarm")
            time.sleep(1.0)
            proc.terminate()
            proc.wait(10)
        except Exception:  # noqa: BLE001
            proc.kill()
        print("\n".join(lines[-40:]))
