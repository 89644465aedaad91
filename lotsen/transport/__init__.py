"""Carrying lotsen messages between processes and machines: the versioned wire encoding
(`codec`) and the Zenoh bridge (`zenoh_bridge`, attached to a stack by `part.add_bridge`)."""
