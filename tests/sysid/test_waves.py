"""Identification of records taken in waves (issue 46 item 4; lotsen.sysid.waves): the record's sea state
from its own IMU, and an answer that is never a wrong physical one, naming the sea when it refuses.

Records on lotsen's simulator (a boat of the model's structure, lotsen.harness.identification.lake_run)
in a JONSWAP sea (lotsen.sim.waves); the 10-min Hs 6 cm case of the issue over three seeds, with the calm
records' answers beside them, is bench/bench_identify.py's waves table."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lotsen.harness.identification import lake_boat, lake_run, record_sea_state
from lotsen.model.environment import Waves
from lotsen.sysid import waves as sea_words
from lotsen.sysid.data import IMU_COLUMNS, load_csv, save_csv


@pytest.fixture(scope="module")
def wavy_record():
    """10 min of PRBS in Hs 6 cm, Tp 1.0 s from 100 deg (issue 46's 5 m/s over 500 m)."""
    return lake_run(7, 600.0, 0.0, 0.0, boat=lake_boat(7), waves=Waves(0.06, 1.0, 100.0))


def _angle_deg(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def test_the_record_carries_its_imu_through_the_csv(tmp_path):
    rec = lake_run(1, 20.0, 0.0, 0.0).run.record
    assert rec.imu is not None and rec.imu.shape == (len(rec.t), len(IMU_COLUMNS))
    assert np.isfinite(rec.imu).all(axis=1).mean() > 0.9  # every command tick holds IMU samples
    # at rest-ish on a level hull the specific force's z is -g
    assert np.nanmedian(rec.imu[:, 2]) == pytest.approx(-9.81, abs=0.2)
    save_csv(rec, tmp_path / "r.csv")
    back = load_csv(tmp_path / "r.csv")
    assert back.output_names == rec.output_names  # the IMU is not an output of the model
    np.testing.assert_allclose(back.imu, rec.imu, rtol=1e-8, atol=1e-9)
    part = back.slice(5.0, 10.0)
    assert part.imu is not None and len(part.imu) == len(part.t)


def test_the_sea_state_of_a_wavy_record_is_the_simulated_sea(wavy_record):
    sea = record_sea_state(wavy_record.run.record)
    assert sea is not None and sea.valid
    # measured: Hs 7.1 cm, Tp 0.80 s, from 108 deg; in 2-min windows of it 6.7-7.8 cm, 0.74-0.88 s, 104-113
    # deg (a boat circling through its PRBS meets the waves at every encounter frequency: Tp reads short)
    assert sea.hs_m == pytest.approx(0.06, rel=0.35)
    assert sea.tp_s == pytest.approx(1.0, rel=0.3)
    assert _angle_deg(sea.from_deg, 100.0) < 30.0
    assert sea_words.in_waves(sea)
    assert "in waves: Hs" in sea_words.describe(sea)


def test_a_calm_record_reads_calm_water():
    sea = record_sea_state(lake_run(2, 120.0, 0.0, 0.0).run.record)
    assert sea is not None and sea.valid and sea.hs_m < sea_words.IN_WAVES_HS_M
    assert not sea_words.in_waves(sea)
    assert sea_words.describe(sea).startswith("calm water")
    assert record_sea_state(lake_run(2, 20.0, 0.0, 0.0).run.record).valid is False  # too short to tell


def test_a_wavy_record_is_never_a_wrong_physical_answer_and_its_refusal_names_the_sea(wavy_record):
    from lotsen.sysid.identify import identify
    from lotsen.sysid.judge import CORE_PARAMETERS
    from lotsen.sysid.problem import IdentificationProblem, held_out_split

    rec, boat = wavy_record.run.record, wavy_record.boat
    est, val, src, _ = held_out_split([rec], None, 0.2)
    ident = identify(IdentificationProblem(est, val, {"m11": boat.m11}, validation_source=src,
                                           sea=record_sea_state(rec)))
    v = ident.verdict.verdict
    assert v != "predictive"  # in waves: no effective coefficients from wave motion
    if v in ("ok", "weak"):  # a physical answer must be right within its intervals
        for n in CORE_PARAMETERS:
            true, got, sd = getattr(boat, n), getattr(ident.result.params, n), ident.result.std[n]
            assert abs(got / true - 1) < 0.05 and abs(got - true) < 3 * sd, n
    else:
        assert any("taken in waves: Hs" in r for r in ident.verdict.reasons)
        assert any("calmer moment" in a for a in ident.advice)
    out = ident.to_json_dict()
    assert out["identification"]["sea_state"]["in_waves"] is True
    assert out["identification"]["sea_state"]["hs_m"] == pytest.approx(0.06, rel=0.3)


def test_the_experiment_check_knows_the_sea():
    assert sea_words.experiment_sea_warning(0.0) is None
    assert sea_words.experiment_sea_warning(0.01) is None  # below what the IMU tells from calm water
    warn = sea_words.experiment_sea_warning(0.03, 0.8, 250.0)
    assert warn is not None and warn.startswith("WARNING") and "calmer moment" in warn
    assert "heading 250 deg" in warn  # head to the sea: where the waves come from
    assert "Hs 3.0 cm, Tp 0.8 s, from 250 deg" in warn


def test_in_waves_the_judge_gives_no_effective_coefficients_and_says_why():
    """The judge alone, on a calm short record's estimates: told the record was in waves, an answer that
    would be predictive is refused, naming the sea; told calm water, it stays as it was."""
    from dataclasses import replace

    from lotsen.messages import SeaState
    from lotsen.sysid.identify import identify
    from lotsen.sysid.judge import judge
    from lotsen.sysid.problem import IdentificationProblem, held_out_split

    from lotsen.harness.identification import LAKE_EXPERIMENT, run_on_simulator
    from lotsen.sim import DEFAULT_BOAT
    from lotsen.sysid.experiment import parse_experiment

    # the lake boat (dead band, weaker astern thrust: not the model's structure): 3 min of PRBS give
    # effective coefficients ("predictive") in calm water
    spec = dict(LAKE_EXPERIMENT, pieces=[dict(LAKE_EXPERIMENT["pieces"][0], duration_s=180.0, seed=3)])
    rec = replace(run_on_simulator(parse_experiment(spec, "prbs"), DEFAULT_BOAT, seed=3).record, input_kind="mean")
    est, val, src, _ = held_out_split([rec], None, 0.25)
    problem = IdentificationProblem(est, val, {"m11": 14.0}, validation_source=src)
    calm = identify(problem)
    assert calm.verdict.verdict == "predictive"
    sea = SeaState(stamp_s=0.0, valid=True, hs_m=0.05, tp_s=1.0, tp_encounter_s=1.0, from_deg=250.0,
                   heave_std_m=0.01, roll_std_deg=3.0, pitch_std_deg=2.0)
    wavy = judge(replace(problem, sea=sea), calm.estimates)
    again = judge(replace(problem, sea=replace(sea, hs_m=0.0)), calm.estimates)  # read as calm water
    assert again.verdict.verdict == calm.verdict.verdict and again.estimator == calm.estimator
    assert wavy.verdict.verdict == "refused"
    assert any("taken in waves: Hs 5.0 cm, Tp 1.0 s, from 250 deg" in r for r in wavy.verdict.reasons)


def test_the_experiment_on_the_stack_warns_when_it_starts_in_waves():
    from lotsen.messages import SeaState
    from lotsen.stack.experiment import ExperimentNode
    from lotsen.sysid.experiment import parse_experiment

    node = ExperimentNode(parse_experiment({"name": "x", "pieces": [
        {"type": "constant", "duration_s": 5, "n_rps": 40}]}, "x"))
    logged: list[tuple[str, str]] = []

    class Ctx:
        def log(self, level: str, text: str, **_: object) -> None:
            logged.append((level, text))

    node.ctx = Ctx()  # type: ignore[assignment]
    node._check_sea()
    assert logged == []  # no estimate: nothing said
    node._on_sea(SeaState(stamp_s=1.0, valid=True, hs_m=0.0, tp_s=math.nan, tp_encounter_s=math.nan,
                          from_deg=math.nan, heave_std_m=0.0, roll_std_deg=0.0, pitch_std_deg=0.0))
    node._check_sea()
    assert logged == []  # calm water
    node._on_sea(SeaState(stamp_s=2.0, valid=True, hs_m=0.06, tp_s=1.0, tp_encounter_s=1.0, from_deg=250.0,
                          heave_std_m=0.01, roll_std_deg=3.0, pitch_std_deg=2.0))
    node._check_sea()
    assert logged and logged[0][0] == "warning" and "too high for a trustworthy identification record" in logged[0][1]


def test_experiment_check_says_when_the_sea_is_too_high(capsys):
    from pathlib import Path

    from lotsen.cli.main import main

    exp = Path(__file__).parents[2] / "examples" / "experiments" / "zigzag_10_10.yaml"
    assert main(["experiment", "check", str(exp), "--sea", "0.06,1.0,250"]) == 0
    err = capsys.readouterr()
    assert "too high for a trustworthy identification record" in err.err and "heading 250 deg" in err.err
    assert main(["experiment", "check", str(exp), "--sea", "0,1.0,250"]) == 0
    assert "WARNING" not in capsys.readouterr().err  # calm water: nothing to say


def test_heading_and_velocity_of_a_record():
    """The velocity over ground from the fixes, whatever the heading: a boat adrift lies beam-on and
    moves sideways down the waves, which the encounter frequency feels as much as speed ahead."""
    from lotsen.sysid.data import IdRecord

    t = np.arange(0.0, 10.0, 0.125)
    K = len(t)
    y = np.column_stack([0.5 * t, -0.2 * t, np.full(K, 0.0), np.zeros(K)])  # 0.5 m/s north, 0.2 west
    y[1::2, :] = np.nan  # every other row without a fix or a heading (asynchronous)
    rec = IdRecord(t, np.zeros((K, 5)), y)
    psi, velocity = sea_words.heading_and_velocity(rec)
    assert np.all(psi == 0.0)  # held between headings
    np.testing.assert_allclose(np.nanmedian(velocity, axis=0), [0.5, -0.2], atol=1e-9)
    rec.outputs[:, 2] = np.where(np.isfinite(rec.outputs[:, 2]), math.pi / 2, np.nan)  # heading east: the same
    np.testing.assert_allclose(np.nanmedian(sea_words.heading_and_velocity(rec)[1], axis=0), [0.5, -0.2], atol=1e-9)


def test_a_long_low_motion_is_not_a_wind_sea():
    """The 6-DOF test hull's own manoeuvres in calm water read Hs 2.1 cm at Tp 2.8 s from its IMU (a
    designed experiment of bench hull's lab loop); a wind sea of that period stands 30 cm or more
    (JONSWAP's growth), so the record is calm water and the run is not warned about. A configured
    (simulated) sea of that height and period is taken as given; the wind seas the benches measure are
    in waves."""
    from lotsen.messages import SeaState
    from lotsen.model.environment import wind_sea_hs_floor_m

    # the growth laws against the fetch examples of lotsen.model.environment's docstring
    assert wind_sea_hs_floor_m(0.66) < 0.035 and wind_sea_hs_floor_m(1.0) < 0.06
    assert wind_sea_hs_floor_m(2.8) == pytest.approx(0.30, rel=0.05)

    def sea(hs: float, tp: float) -> SeaState:
        return SeaState(stamp_s=0.0, valid=True, hs_m=hs, tp_s=tp, tp_encounter_s=math.nan, from_deg=167.0,
                        heave_std_m=math.nan, roll_std_deg=math.nan, pitch_std_deg=math.nan)

    manoeuvres = sea(0.021, 2.8)
    assert not sea_words.in_waves(manoeuvres)
    assert sea_words.describe(manoeuvres).startswith("calm water") and "no wind sea" in sea_words.describe(manoeuvres)
    assert sea_words.experiment_sea_warning(0.021, 2.8, 167.0) is None
    assert sea_words.experiment_sea_warning(0.021, 2.8, 167.0, measured=False) is not None
    for hs, tp in ((0.027, 0.85), (0.036, 0.80), (0.068, 0.95), (0.078, 0.78)):  # bench identify's readings
        assert sea_words.in_waves(sea(hs, tp)), (hs, tp)
        assert sea_words.experiment_sea_warning(hs, tp) is not None
