"""Carrying lotsen messages between processes and machines: the versioned wire encoding
(`codec`) and the Zenoh bridge (`zenoh_bridge`, attached to a stack by `part.add_bridge`); the ROS 2
mode (`ros2_bridge`: rmw_zenoh's wire format `rmw_zenoh`, message mapping `ros2_map`, ROS types
and hashes `ros2_types`)."""
