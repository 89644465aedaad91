"""The page's RC line: the telemetry frame carries the receiver's state (takeover, e-stop, link)."""

from lotsen.messages import RcOverride, Topic
from lotsen.web.telemetry import TelemetryState


def test_frame_carries_the_rc_state():
    tel = TelemetryState()
    link = {"pilot": False, "clients": 0}
    assert "rc" not in tel.frame(0.0, link)
    tel.update(Topic.RC, RcOverride(stamp_s=1.0, active=True, link="failsafe"))
    assert tel.frame(1.0, link)["rc"] == {"t": 1.0, "active": True, "estop": False, "link": "failsafe"}
    tel.update(Topic.RC, RcOverride(stamp_s=2.0, active=False, estop=True))
    rc = tel.frame(2.0, link)["rc"]
    assert rc["link"] == "ok" and rc["estop"] and not rc["active"]
