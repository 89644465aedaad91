"""The MAVLink 2 endpoint of the web process: QGroundControl, Mission Planner, MAVProxy, Cockpit
and MAVROS see the boat as an ArduPilot Rover (docs/mavlink.md).

It is another client of the supervisor beside the page, in the same process: the same bus (the
state the page shows, at the same time), the same pilot seat and control handler (a signed ground
station is a pilot session; nothing reaches the helm but the pilot), the same planner worker
(uploaded missions are planned like the page's routes). pymavlink is imported by the endpoint
only (`lotsen.web.mavlink.endpoint`), so a run without `--mavlink` does not carry it.
"""
