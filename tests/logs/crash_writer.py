"""Helper process for test_crash_safety: records ImuSamples at a steady rate until killed.
Prints the number of messages handed to the recorder, every 0.05 s."""

import sys
import time

from lotsen.logs.recorder import McapRecorder, RecorderConfig
from lotsen.messages import ImuSample
from lotsen.runtime import Bus


def main(path: str, rate_hz: float, flush_period_s: float) -> None:
    bus = Bus()
    rec = McapRecorder(RecorderConfig(flush_period_s=flush_period_s, foxglove_views=False)).attach(bus)
    rec.start(path)
    t0 = time.monotonic()
    n = 0
    last_print = t0
    while True:
        now = time.monotonic()
        while n < (now - t0) * rate_hz:
            bus.publish("imu/data_raw", ImuSample(stamp_s=float(n), gyro_radps=(0.0, 0.0, 0.01), accel_mps2=(0.0, 0.0, -9.81)))
            n += 1
        if now - last_print >= 0.05:
            print(n, flush=True)
            last_print = now
        time.sleep(0.002)


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]), float(sys.argv[3]))
