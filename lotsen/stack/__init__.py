"""Assembly: a running stack from a launch config (the simulated or the hardware boat, fusion,
the supervisor, the logs / web / Zenoh attachments), the process split (`lotsen run`), and the
harnesses (mission, fault injection, experiments) that all run on one closed loop.

This is the only layer that imports the runtime, the algorithms, the supervisor and the edge
packages (drivers, logs, transport, web) together; nothing below imports it.
"""
