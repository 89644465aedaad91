"""A ROS 2 node on Zenoh written with `eclipse-zenoh` and `rosbags` only (no lotsen import), following
rmw_zenoh's documented wire format independently of lotsen's implementation. Used by
tests/transport/test_ros2.py as the second process:

1. connects to the boat's loopback endpoint as a Zenoh client (multicast and gossip scouting off) and announces
   itself with rmw_zenoh liveliness tokens (node /shore/shore_tool);
2. discovers the boat's IMU and GNSS publishers from the ROS graph (liveliness tokens, as
   `ros2 topic list` does), subscribes to their data keys and decodes them with rosbags;
3. sends lotsen_msgs/OperatorCommand (types registered from the repository's .msg files): first
   one with a wrong pilot token (client "intruder", action "arm"), then the right one (client
   "shore_tool", action "hold"), repeated until told to stop;
4. meanwhile publishes rosbags-serialized sensor_msgs/Imu and NavSatFix on /rosbot/imu/data_raw
   and /rosbot/gps_chatter (the reverse direction).

argv: endpoint, pilot token, directory of lotsen_msgs .msg files[, action (default hold)]. Prints JSON lines; stops on stdin "stop".
"""

import json
import os
import struct
import sys
import threading
import time
import traceback
from pathlib import Path

import numpy as np
import zenoh
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

DOMAIN = 0
GID = bytes(range(100, 116))  # this node's publisher GID (any 16 bytes unique to the publisher)


def say(**kw):
    print(json.dumps(kw), flush=True)


def dds(ros_type):  # "pkg/msg/T" -> "pkg::msg::dds_::T_"
    pkg, sub, name = ros_type.split("/")
    return f"{pkg}::{sub}::dds_::{name}_"


def attachment(seq):  # rmw_zenoh: int64 seq, int64 ns timestamp (little endian), u8 16, 16 GID bytes
    return struct.pack("<qqB", seq, time.time_ns(), 16) + GID


def main(endpoint, token, msg_dir, action="hold"):
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for f in sorted(Path(msg_dir).glob("*.msg")):
        types.update(get_types_from_msg(f.read_text(), f"lotsen_msgs/msg/{f.stem}"))
    store.register(types)
    T = store.types

    conf = zenoh.Config()
    for key, value in [("mode", "client"), ("scouting/multicast/enabled", False), ("scouting/gossip/enabled", False),
                       ("listen/endpoints", []), ("connect/endpoints", [endpoint])]:
        conf.insert_json5(key, json.dumps(value))
    session = zenoh.open(conf)
    zid = str(session.info.zid())
    lv = session.liveliness()
    tokens = [lv.declare_token(f"@ros2_lv/{DOMAIN}/{zid}/0/0/NN/%/%shore/shore_tool")]
    say(ready=True, modules=sorted(m for m in sys.modules if m == "lotsen" or m.startswith("lotsen.")))

    # 2. the ROS graph: find the boat's publishers
    found = {}
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and len(found) < 2:
        for reply in lv.get(f"@ros2_lv/{DOMAIN}/**", timeout=1.0):
            parts = str(reply.ok.key_expr).split("/")
            if len(parts) >= 13 and parts[5] == "MP" and parts[9] in ("%boat%imu%data_raw", "%boat%gps_chatter"):
                found[parts[9].replace("%", "/")] = (parts[10], parts[11], parts[12])
        time.sleep(0.1)
    say(graph={k: list(v) for k, v in found.items()})

    got = {"imu": [], "gnss": []}
    lock = threading.Lock()

    def on_imu(sample):
        att = sample.attachment.to_bytes() if sample.attachment is not None else b""
        seq, ts, n = struct.unpack_from("<qqB", att) if len(att) == 33 else (-1, -1, 0)
        m = store.deserialize_cdr(sample.payload.to_bytes(), "sensor_msgs/msg/Imu")
        with lock:
            got["imu"].append({"seq": seq, "ts_ns": ts, "gid_len": n, "stamp": [m.header.stamp.sec, m.header.stamp.nanosec],
                               "frame": m.header.frame_id, "gyro": [m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z],
                               "accel": [m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z],
                               "orientation_cov0": float(m.orientation_covariance[0])})

    def on_gnss(sample):
        m = store.deserialize_cdr(sample.payload.to_bytes(), "sensor_msgs/msg/NavSatFix")
        with lock:
            got["gnss"].append({"lat": m.latitude, "lon": m.longitude, "alt": m.altitude, "status": int(m.status.status),
                                "cov0": float(m.position_covariance[0])})

    subs = []
    for topic, cb, want in [("/boat/imu/data_raw", on_imu, "sensor_msgs::msg::dds_::Imu_"),
                            ("/boat/gps_chatter", on_gnss, "sensor_msgs::msg::dds_::NavSatFix_")]:
        if topic in found and found[topic][0] == want:
            dtype, thash, _ = found[topic]
            subs.append(session.declare_subscriber(f"{DOMAIN}/{topic.strip('/')}/{dtype}/{thash}", cb))
            tokens.append(lv.declare_token(f"@ros2_lv/{DOMAIN}/{zid}/0/{len(tokens)}/MS/%/%shore/shore_tool/"
                                           f"{topic.replace('/', '%')}/{dtype}/{thash}/2::,5:,:,:,,"))

    # 3./4. publishers: operator command to the boat, sensors in the reverse direction
    def publisher(topic, ros_type):
        thash = store.hash_rihs01(ros_type)
        tokens.append(lv.declare_token(f"@ros2_lv/{DOMAIN}/{zid}/0/{len(tokens)}/MP/%/%shore/shore_tool/"
                                       f"{topic.replace('/', '%')}/{dds(ros_type)}/{thash}/::,10:,:,:,,"))
        return session.declare_publisher(f"{DOMAIN}/{topic.strip('/')}/{dds(ros_type)}/{thash}")

    pub_cmd = publisher("/boat/operator/command", "lotsen_msgs/msg/OperatorCommand")
    pub_imu = publisher("/rosbot/imu/data_raw", "sensor_msgs/msg/Imu")
    pub_fix = publisher("/rosbot/gps_chatter", "sensor_msgs/msg/NavSatFix")

    def header(t):
        return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=int(t), nanosec=int((t % 1) * 1e9)),
                                        frame_id="base_link")

    def command(action, tok, client, t):
        return bytes(store.serialize_cdr(T["lotsen_msgs/msg/OperatorCommand"](header=header(t), action=action,
                                                                             pilot_token=tok, client=client),
                                         "lotsen_msgs/msg/OperatorCommand"))

    V3 = T["geometry_msgs/msg/Vector3"]
    imu = bytes(store.serialize_cdr(T["sensor_msgs/msg/Imu"](
        header=header(12.5), orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.array([-1.0] + [0.0] * 8), angular_velocity=V3(x=0.01, y=0.02, z=0.03),
        angular_velocity_covariance=np.zeros(9), linear_acceleration=V3(x=0.1, y=-0.2, z=9.8),
        linear_acceleration_covariance=np.zeros(9)), "sensor_msgs/msg/Imu"))
    St = T["sensor_msgs/msg/NavSatStatus"]
    Fix = T["sensor_msgs/msg/NavSatFix"]
    fix = bytes(store.serialize_cdr(Fix(header=header(12.5), status=St(status=St.STATUS_FIX, service=St.SERVICE_GPS),
                                  latitude=57.7, longitude=11.97, altitude=3.0,
                                  position_covariance=np.array([0.25, 0, 0, 0, 0.25, 0, 0, 0, 1.0]),
                                  position_covariance_type=Fix.COVARIANCE_TYPE_DIAGONAL_KNOWN), "sensor_msgs/msg/NavSatFix"))

    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.readline(), stop.set()), daemon=True).start()
    seq = 0
    wrong_sent = False
    reported = False
    end = time.monotonic() + 30
    while not stop.is_set() and time.monotonic() < end:
        seq += 1
        if not wrong_sent and pub_cmd.matching_status:
            pub_cmd.put(command("arm", "not-the-token", "intruder", 1.0), attachment=attachment(seq))
            wrong_sent = True
        elif wrong_sent:
            pub_cmd.put(command(action, token, "shore_tool", 2.0), attachment=attachment(seq))
        pub_imu.put(imu, attachment=attachment(seq))
        pub_fix.put(fix, attachment=attachment(seq))
        with lock:
            if not reported and len(got["imu"]) >= 3 and got["gnss"]:
                reported = True
                say(have_data=True)
        time.sleep(0.2)
    with lock:
        say(imu=got["imu"][:5], n_imu=len(got["imu"]), gnss=got["gnss"][:2], n_gnss=len(got["gnss"]))
    session.close()
    say(done=True)


if __name__ == "__main__":
    code = 1
    try:
        main(*sys.argv[1:5])
        code = 0
    except BaseException:  # noqa: BLE001 - report, then leave at once
        traceback.print_exc()
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)  # zenoh's threads must not keep a failed peer alive
