"""Identification on N worker processes gives the answer of one, to the last digit (issue 49 item 1).

The shooting intervals are cut into blocks by the record alone (lotsen.sysid.shooting_blocks) and
their parts summed in the blocks' order (lotsen.sysid.parallel); the equation-error searches map
their independent solves. A short record is one block at the default block size, so these tests cut
it finer (MIN_BLOCK_STEPS) to have as many blocks as a 10-min record.
"""

import argparse
import json
import pickle

import numpy as np
import pytest

from lotsen.cli.workers import JOBS, worker_pool
from lotsen.sysid import multiple, parallel, shooting_blocks
from lotsen.sysid.parallel import SERIAL, Held, map_held, ordered_sum


@pytest.fixture()
def small_blocks(monkeypatch):
    """Blocks of 128 steps (the default 1024), and how many each problem was cut into."""
    counts: list[int] = []
    cut = shooting_blocks.cut_blocks

    def counted(node_step, n_steps):  # type: ignore[no-untyped-def]
        out = cut(node_step, n_steps)
        counts.append(len(out))
        return out

    monkeypatch.setattr(shooting_blocks, "MIN_BLOCK_STEPS", 128)
    monkeypatch.setattr(multiple, "cut_blocks", counted)
    return counts


@pytest.fixture(scope="module")
def lake_minute():
    from lotsen.harness.identification import lake_run

    return lake_run(7, 60.0, 0.05, 3.0)


def test_identify_on_a_lake_gives_the_same_answer_with_1_and_2_workers(lake_minute, small_blocks):
    """Equation error (the lake's kappa, current and wind searches), both lake stages of multiple
    shooting, the sandwich covariance and the judge: every number equal, not merely close."""
    from lotsen.sysid.identify import identify, split_holdout
    from lotsen.sysid.problem import IdentificationProblem

    est, val = split_holdout([lake_minute.run.record], 0.2)
    problem = IdentificationProblem(tuple(est), tuple(val), {"m11": lake_minute.boat.m11}, lake=True)
    answers = []
    for jobs in (1, 2):
        with worker_pool(jobs) as par:
            assert (par is SERIAL) == (jobs == 1)
            answers.append(identify(problem, None, par))
    assert small_blocks and min(small_blocks) >= 4, small_blocks  # the intervals were cut, and run apart
    one, two = answers
    assert json.dumps(one.to_json_dict(), sort_keys=True) == json.dumps(two.to_json_dict(), sort_keys=True)
    for a, b in zip(one.estimates, two.estimates):
        assert a.estimator == b.estimator
        assert np.array_equal(a.result.params.to_vector(), b.result.params.to_vector())
        assert np.array_equal(a.result.covariance, b.result.covariance, equal_nan=True)


def test_identify_jobs_writes_the_same_file_as_one_job(short_run, small_blocks, tmp_path, capsys):
    """`lotsen identify --jobs 2` and `--jobs 1`: the same parameter file, byte for byte."""
    from lotsen.cli.identify import main_standalone
    from lotsen.sysid.data import save_csv

    data = tmp_path / "run.csv"
    save_csv(short_run.record, data)
    files = []
    for jobs in ("1", "2"):
        out = tmp_path / f"p{jobs}.json"
        assert main_standalone(["identify", str(data), "--out", str(out), "--jobs", jobs,
                                "--fix", "kappa=0.02", "--fix", "Y_rv=-2", "--fix", "N_vv=-1"]) == 0
        files.append(out.read_bytes())
    capsys.readouterr()
    assert small_blocks and min(small_blocks) >= 4, small_blocks
    assert files[0] == files[1]


def test_jobs_is_a_count_of_processes():
    assert JOBS("3") == 3
    for bad in ("0", "-1", "1.5", "nan", "many"):
        with pytest.raises(argparse.ArgumentTypeError):
            JOBS(bad)


def _scaled(value, factor):  # type: ignore[no-untyped-def]
    return value * factor


def test_held_values_are_sent_once_and_summed_in_order():
    """map_held: the value goes with the first call a worker gets for it (a second call only for the
    workers that missed it), later calls send the argument alone; ordered_sum adds in the parts' order."""
    held = [Held(np.arange(3.0) + k) for k in range(4)]
    sent = []

    def recording_map(function, items):  # type: ignore[no-untyped-def]
        items = list(items)
        sent.append([it[4] for it in items])
        return [function(it) for it in items]  # one "worker": this process, with its own store

    first = map_held(recording_map, _scaled, held, [1.0, 2.0, 3.0, 4.0])
    again = map_held(recording_map, _scaled, held, [1.0, 1.0, 1.0, 1.0])
    assert sent == [[False] * 4, [True] * 4, [False] * 4]  # missed once, then held
    assert all(np.array_equal(a, h.value * f) for a, h, f in zip(first, held, (1, 2, 3, 4)))
    assert all(np.array_equal(a, h.value) for a, h in zip(again, held))
    assert map_held(SERIAL, _scaled, held, [2.0] * 4)[3].tolist() == [6.0, 8.0, 10.0]
    parts = [np.array([1e16]), np.array([1.0]), np.array([-1e16])]
    assert ordered_sum(parts)[0] == (1e16 + 1.0) - 1e16  # the parts' order, whatever ran them
    assert ordered_sum(iter(parts)) is not parts[0]
    parallel._held.clear()


def test_the_filter_on_runs_of_segments_is_the_masked_filter_to_the_last_digit():
    """equation_error._filtered filters each segment's run in place (no copies in and out): the numbers
    of the per-segment masked filter, for a C-ordered and a transposed input."""
    from scipy.ndimage import gaussian_filter1d

    from lotsen.sysid.equation_error import FILTER_SIGMA_S, _filtered

    rng = np.random.default_rng(4)
    seg = np.repeat([0, 1, 2], [300, 41, 500])
    for x in (rng.normal(size=(len(seg), 7)), rng.normal(size=(3, len(seg))).T):
        ref = np.empty(x.shape)
        for q in np.unique(seg):
            ref[seg == q] = gaussian_filter1d(x[seg == q], FILTER_SIGMA_S / 0.125, axis=0, mode="nearest")
        assert np.array_equal(_filtered(x, seg, 0.125), ref)
    scattered = np.array([0, 1, 0, 1] * 50)  # not runs: the masked filter itself
    x = rng.normal(size=(len(scattered), 2))
    ref = np.empty(x.shape)
    for q in (0, 1):
        ref[scattered == q] = gaussian_filter1d(x[scattered == q], 4.0, axis=0, mode="nearest")
    assert np.array_equal(_filtered(x, scattered, 0.125), ref)


def test_the_command_keeps_freed_memory_on_glibc():
    import platform
    import sys

    from lotsen.cli.workers import keep_freed_memory

    glibc = sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc"
    assert keep_freed_memory() == glibc


def _whole_regression(ms, kappa, theta_fixed, geometry, current, wind):  # type: ignore[no-untyped-def]
    """The reference: rows (3 n) of A theta_free = b with every column group side by side, built at once
    (what _Regression.regressors assembles group by group), the free parameters' indices and n."""
    from lotsen.sysid.equation_error import (
        _free_names, _housing_column, _record_columns, _right_side, _water_columns, _wind_columns,
    )

    cols = {**_record_columns(ms, geometry), **_water_columns(ms, current), **_housing_column(ms, current, kappa, geometry),
            **(_wind_columns(ms, wind) if wind is not None else {})}
    free, names = _free_names(theta_fixed, wind)
    n = len(ms.u)
    A = np.zeros((3, n, len(names)))
    for j, name in enumerate(names):
        for e, x in enumerate(cols[name]):
            if x is not None:
                A[e, :, j] = x
    return A.reshape(3 * n, -1), _right_side(cols, theta_fixed, n).ravel(), free, n


def test_the_kept_filtered_regressors_are_the_filtered_regression_to_the_last_digit():
    """_Regression.regressors filters each column group once per value of what it depends on (the record,
    the current, kappa, the air's velocity) and keeps it: whatever was kept before, the numbers are those of
    filtering the whole A and b (_whole_regression), on the record and on a stretch of it."""
    from lotsen.model import DEFAULT_GEOMETRY
    from lotsen.sysid.equation_error import (
        CurrentPath, MotionSamples, _filtered, _Regression,
    )
    from lotsen.sysid.estimate import NAMES, parameter_bounds

    rng = np.random.default_rng(5)
    n = 400
    seg = np.repeat([0, 1], [250, 150])
    ms = MotionSamples(np.arange(n) * 0.125, *rng.normal(size=(7, n)),
                       np.column_stack([rng.normal(size=(n, 2)), rng.normal(size=(n, 3)) * 20]), seg)
    ms.inputs[::7, 2] = 0.0  # some samples with a unit stopped (zero thrust)
    fixed = {NAMES.index("m11"): 14.0, NAMES.index("X_uuu"): 0.0}
    reg = _Regression(ms, fixed, DEFAULT_GEOMETRY, 0.125, *parameter_bounds())
    path = CurrentPath(np.array([0.0, 25.0, 50.0]), np.array([0.05, 0.1, 0.0]), np.array([-0.1, 0.0, 0.02]))
    calls = [(0.02, (0.0, 0.0), None, None), (0.05, (0.0, 0.0), None, None), (0.02, (0.0, 0.0), None, None),
             (0.02, path, (3.0, -1.0), None), (0.03, path, (3.0, -1.0), None), (0.03, path, (2.0, -1.0), None),
             (0.02, path, (3.0, -1.0), np.arange(100, 300)), (0.02, (0.1, 0.0), (3.0, -1.0), np.arange(100, 300))]
    for kappa, current, wind, rows in calls * 2:
        mx = ms if rows is None else ms.subset(rows)
        A, b, free, m = _whole_regression(mx, kappa, fixed, DEFAULT_GEOMETRY, current, wind)
        Af, bf, free_kept, _ = reg.regressors(kappa, current, wind, rows)
        assert free_kept == free
        assert np.array_equal(Af, _filtered(A.reshape(3, m, -1).transpose(1, 0, 2).reshape(m, -1), mx.segment,
                                            0.125).reshape(m, 3, -1))
        assert np.array_equal(bf, _filtered(b.reshape(3, m).T, mx.segment, 0.125))
    assert pickle.loads(pickle.dumps(reg)).memo == {}  # a worker's copy fills its own


def test_a_linearisation_is_made_again_only_where_it_differs(lake_minute):
    """MultipleShootingProblem.linearise keeps its last linearisation with sensitivities: asked again at the
    same point, free parameters and noise it is the one made; with another noise (the noise re-estimate
    between passes) it is made anew, equal to a fresh problem's to the last digit."""
    from lotsen.model import DEFAULT_PARAMETERS
    from lotsen.sysid.estimate import SolverOptions, starting_point
    from lotsen.sysid.multiple import MultipleShootingProblem, initial_nodes

    records = [lake_minute.run.record]
    prob = MultipleShootingProblem(records, SolverOptions())
    theta, free, _, tscale = starting_point(DEFAULT_PARAMETERS, {"m11": lake_minute.boat.m11})
    nodes = initial_nodes(prob.grid, prob.segments)
    first = prob.linearise(theta, nodes, free, tscale, True)
    assert prob.linearise(theta.copy(), nodes.copy(), free, tscale, True) is first
    assert prob.linearise(theta, nodes, free, tscale, False) is first  # its residuals serve as well
    prob.noise["r"] *= 2.0
    again = prob.linearise(theta, nodes, free, tscale, True)
    fresh = MultipleShootingProblem(records, SolverOptions(noise_std=dict(prob.noise)))
    ref = fresh.linearise(theta, nodes, free, tscale, True)
    assert again is not first
    for a, b in zip((again.e, again.c, again.Gx, again.Gp, *again.normal), (ref.e, ref.c, ref.Gx, ref.Gp, *ref.normal)):
        assert np.array_equal(a, b)


def test_a_stage_point_is_the_estimates_point_without_its_intervals(lake_minute):
    """shooting_point (the lake's steady-wind stages, the reconstruction spread's step) ends where
    estimate_multiple_shooting ends, to the last digit: the coefficients, node states, environment and
    gyro offsets the next search starts from. It skips the covariance and the sensitivities at the last
    point, which the last iteration's trial (states without sensitivities) makes unnecessary: the
    kernels' states are the same to the last bit with and without the sensitivities."""
    from lotsen.model import DEFAULT_PARAMETERS
    from lotsen.sysid.estimate import SolverOptions
    from lotsen.sysid.multiple import ENV_NAMES, estimate_multiple_shooting, shooting_point

    records = [lake_minute.run.record]
    options = SolverOptions(lake=True, gust_std=1e-3, max_iterations=3, estimate_noise=False)
    fixed = {"m11": lake_minute.boat.m11}
    res = estimate_multiple_shooting(records, DEFAULT_PARAMETERS, fixed, options)
    params, start = shooting_point(records, DEFAULT_PARAMETERS, fixed, options)
    assert res.iterations == 3  # ended by the budget: the last iteration's trial is the end point
    assert np.array_equal(params.to_vector(), res.params.to_vector())
    assert np.array_equal(start.nodes, res.details.nodes)
    assert np.array_equal(start.environment, [res.details.environment.values[n] for n in ENV_NAMES])
    assert np.array_equal(start.gyro_bias, res.details.gyro_bias)


def _where(x: int) -> tuple[int, int]:
    import os

    return os.getpid(), 2 * x


def test_jobs_counts_the_commands_own_process():
    """--jobs N: N processes compute, the command's own (the first ceil(n / N) pieces of a map, the same
    ones every call) and N - 1 workers; the results in the pieces' order."""
    import os

    with worker_pool(3) as par:
        out = list(par(_where, range(7)))
        again = list(par(_where, range(7)))
    assert [v for _, v in out] == [2 * k for k in range(7)]
    assert [pid == os.getpid() for pid, _ in out] == [True] * 3 + [False] * 4
    assert [pid == os.getpid() for pid, _ in again] == [True] * 3 + [False] * 4
    assert [pid for pid, _ in out] == [pid for pid, _ in again]  # each worker the same pieces
    assert len({pid for pid, _ in out + again} - {os.getpid()}) <= 2  # two workers
