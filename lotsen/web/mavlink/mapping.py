"""lotsen's state in ArduPilot Rover's terms, and MAVLink's requests in lotsen's (pure: numbers
from MAVLink's common.xml / ardupilotmega.xml, no pymavlink import). docs/mavlink.md has the table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# identity
MAV_TYPE_SURFACE_BOAT = 11
MAV_TYPE_GCS = 6
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
# MAV_MODE_FLAG
CUSTOM_MODE_ENABLED = 1
TEST_ENABLED = 2
AUTO_ENABLED = 4
GUIDED_ENABLED = 8
STABILIZE_ENABLED = 16
MANUAL_INPUT_ENABLED = 64
SAFETY_ARMED = 128
# MAV_STATE
STATE_STANDBY, STATE_ACTIVE, STATE_CRITICAL, STATE_EMERGENCY = 3, 4, 5, 6
# MAV_SEVERITY
SEVERITY = {"critical": 2, "error": 3, "warning": 4, "notice": 5, "info": 6}
# MAV_RESULT
ACCEPTED, TEMPORARILY_REJECTED, DENIED, UNSUPPORTED, FAILED = 0, 1, 2, 3, 4

#: ArduPilot Rover's mode numbers (Rover's mode enum)
ROVER_MODES = {"MANUAL": 0, "ACRO": 1, "STEERING": 3, "HOLD": 4, "LOITER": 5, "FOLLOW": 6, "SIMPLE": 7,
               "DOCK": 8, "CIRCLE": 9, "AUTO": 10, "RTL": 11, "SMART_RTL": 12, "GUIDED": 15, "INITIALISING": 16}
ROVER_NAMES = {v: k for k, v in ROVER_MODES.items()}

#: lotsen mode -> the Rover mode a ground station shows. HOLD keeps station: Rover's LOITER; the
#: modes Rover has no number for are reported as the nearest one and named in a STATUSTEXT.
REPORTED_MODE = {"MANUAL": "MANUAL", "AUTO": "AUTO", "HOLD": "LOITER", "RETURN": "RTL",
                 "ESTOP": "HOLD",  # thrusters neutral, as Rover's HOLD (motors stopped)
                 "RC": "MANUAL",  # a human drives, by the RC transmitter
                 "CALIBRATE": "GUIDED", "EXPERIMENT": "GUIDED"}  # the computer drives a manoeuvre
WITHOUT_ROVER_NUMBER = ("ESTOP", "RC", "CALIBRATE", "EXPERIMENT")

#: Rover mode requested -> lotsen's operator action (Rover's HOLD drifts with the motors off; lotsen
#: has no drifting mode, its HOLD keeps station, which is the safe reading of "stop here")
REQUESTED_ACTION = {0: "manual", 4: "hold", 5: "hold", 10: "auto", 11: "return", 12: "return"}

# MAV_CMD of commands
CMD_NAV_RETURN_TO_LAUNCH = 20
CMD_DO_SET_MODE = 176
CMD_DO_CHANGE_SPEED = 178
CMD_DO_FLIGHTTERMINATION = 185
CMD_DO_PAUSE_CONTINUE = 193
CMD_PREFLIGHT_CALIBRATION = 241
CMD_MISSION_START = 300
CMD_COMPONENT_ARM_DISARM = 400
CMD_GET_HOME_POSITION = 410
CMD_SET_MESSAGE_INTERVAL = 511
CMD_REQUEST_MESSAGE = 512
CMD_REQUEST_PROTOCOL_VERSION = 519
CMD_REQUEST_AUTOPILOT_CAPABILITIES = 520
CMD_LOGGING_START = 2510
CMD_LOGGING_STOP = 2511
CMD_DO_SET_MISSION_CURRENT = 224
CMD_DO_START_MAG_CAL = 42424
CMD_DO_ACCEPT_MAG_CAL = 42425
CMD_DO_CANCEL_MAG_CAL = 42426
FORCE_DISARM_MAGIC = 21196  # param2 of ARM_DISARM: ArduPilot's "force" (disarm: emergency stop)

COMMAND_NAMES = {20: "RETURN_TO_LAUNCH", 176: "DO_SET_MODE", 178: "DO_CHANGE_SPEED", 185: "DO_FLIGHTTERMINATION",
                 193: "DO_PAUSE_CONTINUE", 241: "PREFLIGHT_CALIBRATION", 300: "MISSION_START",
                 400: "COMPONENT_ARM_DISARM", 2510: "LOGGING_START", 2511: "LOGGING_STOP",
                 42424: "DO_START_MAG_CAL", 42425: "DO_ACCEPT_MAG_CAL", 42426: "DO_CANCEL_MAG_CAL",
                 224: "DO_SET_MISSION_CURRENT"}


@dataclass(frozen=True)
class Request:
    """What a MAVLink command asks of lotsen: an operator action (lotsen.messages.OPERATOR_ACTIONS),
    or a refusal with its reason (`unsupported`: MAV_RESULT_UNSUPPORTED rather than DENIED)."""

    action: str = ""
    refusal: str = ""
    unsupported: bool = False


def command_request(command: int, p: tuple[float, ...]) -> Request | None:
    """The operator action of a state-changing MAVLink command; None for commands that are not
    actions (requests for messages, rates: handled by the endpoint)."""
    if command == CMD_COMPONENT_ARM_DISARM:
        if p[0] >= 0.5:
            if int(p[1]) == FORCE_DISARM_MAGIC:
                return Request(refusal="force-arm skips the pre-arm checks: not offered over MAVLink "
                                       "(prearm_override in the launch config is the expert's switch)")
            return Request("arm")
        return Request("estop" if int(p[1]) == FORCE_DISARM_MAGIC else "disarm")
    if command == CMD_DO_SET_MODE:
        return mode_request(int(p[0]), int(p[1]))
    if command == CMD_MISSION_START:
        return Request("auto")
    if command == CMD_NAV_RETURN_TO_LAUNCH:
        return Request("return")
    if command == CMD_DO_PAUSE_CONTINUE:
        return Request("hold" if p[0] < 0.5 else "auto")
    if command == CMD_DO_FLIGHTTERMINATION:
        return Request("estop" if p[0] >= 0.5 else "reset_estop")
    if command == CMD_PREFLIGHT_CALIBRATION:
        if p[1] >= 0.5:
            return Request("calibrate_mag")
        return Request(refusal="only the magnetometer is calibrated from a ground station (param 2 = 1); "
                               "the gyro, accelerometer and barometer need no calibration here", unsupported=True)
    if command == CMD_DO_START_MAG_CAL:
        return Request("calibrate_mag")
    if command == CMD_DO_ACCEPT_MAG_CAL:
        return Request("mag_accept")
    if command == CMD_DO_CANCEL_MAG_CAL:
        return Request("mag_reject")
    if command == CMD_LOGGING_START:
        return Request("logging_on")
    if command == CMD_LOGGING_STOP:
        return Request("logging_off")
    if command == CMD_DO_SET_MISSION_CURRENT:
        return Request(refusal="lotsen follows its planned path from the start; it does not jump to a waypoint "
                               "(upload a mission that starts there)", unsupported=True)
    return None


def mode_request(base_mode: int, custom_mode: int) -> Request:
    if not base_mode & CUSTOM_MODE_ENABLED:
        return Request(refusal=f"base mode {base_mode} without the custom-mode flag: lotsen takes Rover's mode "
                               "numbers (MANUAL 0, HOLD 4, LOITER 5, AUTO 10, RTL 11)", unsupported=True)
    action = REQUESTED_ACTION.get(custom_mode)
    if action is None:
        name = ROVER_NAMES.get(custom_mode, f"mode {custom_mode}")
        return Request(refusal=f"{name}: lotsen has no such mode (MANUAL, HOLD/LOITER, AUTO, RTL)",
                       unsupported=True)
    return Request(action)


def expected(action: str, mode: str, armed: bool) -> bool:
    """Does the supervisor's state show that `action` was carried out?"""
    target = {"auto": "AUTO", "hold": "HOLD", "return": "RETURN", "manual": "MANUAL", "estop": "ESTOP",
              "calibrate_mag": "CALIBRATE"}.get(action)
    if target is not None:
        return mode == target
    if action == "arm":
        return armed
    if action == "disarm":
        return not armed
    if action == "reset_estop":
        return mode != "ESTOP"
    return True  # logging, magnetometer review: nothing in the status to wait for


def heartbeat_fields(mode: str | None, armed: bool, failsafes: tuple[str, ...] = ()) -> tuple[int, int, int]:
    """(base_mode, custom_mode, system_status) of lotsen's supervisor state; None: not reported yet."""
    if mode is None:
        return CUSTOM_MODE_ENABLED, ROVER_MODES["INITIALISING"], 0  # MAV_STATE_UNINIT
    reported = REPORTED_MODE.get(mode, "HOLD")
    base = CUSTOM_MODE_ENABLED | STABILIZE_ENABLED | MANUAL_INPUT_ENABLED
    if reported in ("AUTO", "RTL", "GUIDED", "LOITER"):
        base |= AUTO_ENABLED | GUIDED_ENABLED
    if armed:
        base |= SAFETY_ARMED
    status = STATE_EMERGENCY if mode == "ESTOP" else STATE_CRITICAL if failsafes else \
        STATE_ACTIVE if armed else STATE_STANDBY
    return base, ROVER_MODES[reported], status


def statustext_chunks(text: str, size: int = 50) -> list[str]:
    """A text in STATUSTEXT pieces of `size` bytes (MAVLink 2 reassembles them by id and chunk_seq);
    UTF-8 is cut on character boundaries."""
    data = text.encode("utf-8")
    out, start = [], 0
    while start < len(data):
        end = min(start + size, len(data))
        while end < len(data) and (data[end] & 0xC0) == 0x80:
            end -= 1
        out.append(data[start:end].decode("utf-8"))
        start = end
    return out or [""]


def ground_velocity(u_mps: float, v_mps: float, heading_rad: float) -> tuple[float, float]:
    """Body velocities (surge, sway) as north / east over ground."""
    c, s = math.cos(heading_rad), math.sin(heading_rad)
    return u_mps * c - v_mps * s, u_mps * s + v_mps * c
