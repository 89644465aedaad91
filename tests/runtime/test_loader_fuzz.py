"""Fuzz the file loaders at the boundary (issue: input robustness): whatever a YAML file holds,
the route, launch-config, experiment and schedule loaders either accept it or refuse it with a
LotsenError that says what is wrong; no other exception escapes."""

import math

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lotsen.errors import LotsenError
from lotsen.planning.io import route_from_dict
from lotsen.runtime.config import LaunchConfig, from_mapping
from lotsen.runtime.schedule import InputSchedule
from lotsen.sysid.experiment import parse_experiment

scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8))
yamlish = st.recursive(scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=5), st.dictionaries(st.text(max_size=12), inner, max_size=5)), max_leaves=25)

# documents close to valid ones find the deeper checks
near_route = st.fixed_dictionaries({
    "harbour": st.one_of(yamlish, st.fixed_dictionaries(
        {"north": scalars, "east": scalars, "heading_deg": scalars})),
    "nodes": st.lists(st.one_of(yamlish, st.fixed_dictionaries(
        {"north": st.floats(-50, 50), "east": st.floats(-50, 50), "heading_deg": scalars, "speed_mps": scalars})),
        max_size=4),
    "area": st.one_of(yamlish, st.lists(st.lists(st.floats(-60, 60), min_size=2, max_size=2), max_size=5)),
}, optional={"obstacles": yamlish, "extra": yamlish})
near_experiment = st.fixed_dictionaries({
    "name": scalars,
    "pieces": st.lists(st.one_of(yamlish, st.fixed_dictionaries(
        {"type": st.sampled_from(["constant", "steps", "ramp", "zigzag", "prbs", "multisine", "x"]),
         "duration_s": scalars}, optional={"n_rps": scalars, "levels": yamlish, "alpha_deg": scalars})),
        max_size=3),
}, optional={"area": yamlish, "start": yamlish, "command_rate_hz": scalars})
near_config = st.fixed_dictionaries({}, optional={
    "mode": st.one_of(scalars, st.sampled_from(["sim", "hardware"])), "seed": scalars,
    "sim": st.one_of(yamlish, st.fixed_dictionaries({}, optional={"dt_s": scalars, "initial_state": yamlish,
                                                                  "environment": yamlish})),
    "nodes": yamlish, "web": yamlish, "extra": yamlish})

FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _accepts_or_explains(fn, data):
    try:
        fn(data)
    except LotsenError as exc:
        assert str(exc).strip(), "a refusal must say what is wrong"


@FUZZ
@given(st.one_of(yamlish, near_route))
def test_route_loader(data):
    _accepts_or_explains(route_from_dict, data)


@FUZZ
@given(st.one_of(yamlish, near_experiment))
def test_experiment_loader(data):
    _accepts_or_explains(parse_experiment, data)


@FUZZ
@given(st.one_of(yamlish, near_config))
def test_launch_config_loader(data):
    _accepts_or_explains(lambda d: from_mapping(LaunchConfig, d), data)


@FUZZ
@given(st.one_of(yamlish, st.fixed_dictionaries({"segments": yamlish})))
def test_schedule_loader(data):
    def load(d):
        sched = from_mapping(InputSchedule, d)
        assert all(math.isfinite(s.duration_s) for s in sched.segments)
    _accepts_or_explains(load, data)
