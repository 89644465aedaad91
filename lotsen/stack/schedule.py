"""Open-loop input schedules (`lotsen sim --schedule`) and the node that plays them."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from lotsen.errors import ConfigError
from lotsen.messages import ThrustCommand, Topic
from lotsen.runtime.config import from_mapping, load_yaml_file
from lotsen.runtime.executor import Node, NodeContext


@dataclass(frozen=True)
class ScheduleSegment:
    """Constant set-points held for `duration_s` (angles in degrees here, as a person writes them)."""

    duration_s: float = field(metadata={"range": (0.01, 36000.0)})
    alpha1_deg: float = field(default=0.0, metadata={"range": (-90.0, 90.0)})
    alpha2_deg: float = field(default=0.0, metadata={"range": (-90.0, 90.0)})
    n1_rps: float = field(default=0.0, metadata={"range": (-200.0, 200.0)})
    n2_rps: float = field(default=0.0, metadata={"range": (-200.0, 200.0)})
    nt_rps: float = field(default=0.0, metadata={"range": (-200.0, 200.0)})

    def command(self, stamp_s: float) -> ThrustCommand:
        return ThrustCommand(stamp_s=stamp_s, alpha1_rad=math.radians(self.alpha1_deg),
                             alpha2_rad=math.radians(self.alpha2_deg), n1_rps=self.n1_rps,
                             n2_rps=self.n2_rps, nt_rps=self.nt_rps, source="schedule")


@dataclass(frozen=True)
class InputSchedule:
    segments: tuple[ScheduleSegment, ...]

    @property
    def duration_s(self) -> float:
        return sum(s.duration_s for s in self.segments)

    def at(self, t: float) -> ScheduleSegment | None:
        acc = 0.0
        for s in self.segments:
            acc += s.duration_s
            if t < acc:
                return s
        return None


# A short demonstration: speed up, turn both ways with the azimuths, spin on the bow thruster.
DEMO_SCHEDULE = InputSchedule(segments=(
    ScheduleSegment(duration_s=10.0, n1_rps=50.0, n2_rps=50.0),
    ScheduleSegment(duration_s=10.0, n1_rps=50.0, n2_rps=50.0, alpha1_deg=-20.0, alpha2_deg=-20.0),
    ScheduleSegment(duration_s=10.0, n1_rps=60.0, n2_rps=60.0, alpha1_deg=20.0, alpha2_deg=20.0),
    ScheduleSegment(duration_s=10.0, n1_rps=30.0, n2_rps=30.0, nt_rps=40.0),
    ScheduleSegment(duration_s=20.0, n1_rps=60.0, n2_rps=60.0),
))


def load_schedule(path: str | Path) -> InputSchedule:
    data = load_yaml_file(path)
    if not isinstance(data, dict) or "segments" not in data:
        raise ConfigError(f"{path}: expected a mapping with a 'segments' list")
    try:
        sched = from_mapping(InputSchedule, data)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    if not sched.segments:
        raise ConfigError(f"{path}: segments: the list is empty")
    return sched


class ScheduleNode(Node):
    """Publishes the schedule's set-point on ship_command at `rate_hz`; neutral after the end."""

    name = "schedule"

    def __init__(self, schedule: InputSchedule, rate_hz: float = 20.0) -> None:
        self.schedule = schedule
        self.period_s = 1.0 / rate_hz

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        self.t0 = ctx.now()
        ctx.add_timer(self.period_s, self._tick)

    def _tick(self) -> None:
        now = self.ctx.now()
        seg = self.schedule.at(now - self.t0)
        cmd = seg.command(now) if seg else ThrustCommand.neutral(now, source="schedule:end")
        self.ctx.publish(Topic.SHIP_COMMAND, cmd)
