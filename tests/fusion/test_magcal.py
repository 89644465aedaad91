"""Magnetometer calibration: recovers a known distortion, refuses partial turns, CLI round trip."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest

from lotsen.cli import calibrate
from lotsen.errors import DataError, LotsenError
from lotsen.fusion.magcal import CalibrationError, MagCalibration, calibrated_heading, fit_mag_calibration
from lotsen.messages import MagSample


def _rot(a: float) -> np.ndarray:
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def _turn(M: np.ndarray, c: np.ndarray, span_deg: float = 360.0, n: int = 400, noise: float = 0.2,
          seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Raw field of a turn: m = M w + c, w = [cos psi, -sin psi] (sim convention)."""
    rng = np.random.default_rng(seed)
    psi = np.linspace(0.0, math.radians(span_deg), n, endpoint=span_deg < 360.0)
    W = np.vstack([np.cos(psi), -np.sin(psi)])
    m = M @ W + c[:, None] + noise * rng.standard_normal((2, n))
    return psi, m[0], m[1]


def test_recovers_known_symmetric_distortion() -> None:
    # soft iron with axes rotated by 30 deg and 1.3 : 0.8 axis ratio, field 20 units, hard iron (12, -7)
    S = _rot(math.radians(30)) @ np.diag([1.3, 0.8]) @ _rot(math.radians(30)).T
    M_true, c_true = 20.0 * S, np.array([12.0, -7.0])
    psi, x, y = _turn(M_true, c_true)
    cal = fit_mag_calibration(x, y)
    assert np.allclose(cal.center, c_true, atol=0.05)
    assert np.allclose(np.array(cal.matrix), M_true, atol=0.1)
    assert cal.coverage_deg > 355.0 and cal.residual_rms < 0.02
    err = [math.remainder(cal.heading(a, b) - p, 2 * math.pi) for a, b, p in zip(x, y, psi)]
    assert math.degrees(float(np.sqrt(np.mean(np.square(err))))) < 1.0


def test_rotation_part_is_a_heading_offset_not_fitted() -> None:
    # M = S R: the fit returns the symmetric S' with S' S' = M M'; the rest is a constant heading offset
    S = np.array([[1.1, 0.05], [0.05, 0.9]]) * 10.0
    rot = math.radians(7.0)
    psi, x, y = _turn(S @ _rot(rot), np.array([1.0, 2.0]), noise=0.0)
    cal = fit_mag_calibration(x, y)
    M = np.array(cal.matrix)
    assert np.allclose(M, M.T)
    assert np.allclose(M @ M.T, (S @ _rot(rot)) @ (S @ _rot(rot)).T, rtol=1e-6)
    offsets = [math.remainder(cal.heading(a, b) - p, 2 * math.pi) for a, b, p in zip(x, y, psi)]
    assert np.std(offsets) < 1e-6  # constant: a heading offset, not a shape error
    assert abs(abs(np.mean(offsets)) - rot) < 1e-6


def test_refuses_half_turn() -> None:
    _, x, y = _turn(np.diag([15.0, 14.0]), np.array([3.0, -4.0]), span_deg=180.0)
    with pytest.raises(CalibrationError, match="cover"):
        fit_mag_calibration(x, y)


def test_refuses_too_few_points_and_skips_nan() -> None:
    _, x, y = _turn(np.eye(2) * 15.0, np.zeros(2), n=20)
    with pytest.raises(CalibrationError, match="finite points"):
        fit_mag_calibration(x, y)
    _, x, y = _turn(np.eye(2) * 15.0, np.array([2.0, 1.0]), n=200)
    x[::10] = np.nan
    cal = fit_mag_calibration(x, y)
    assert cal.n_points == 180 and np.allclose(cal.center, (2.0, 1.0), atol=0.1)
    assert issubclass(CalibrationError, LotsenError)


def test_calibrated_heading_message() -> None:
    cal = MagCalibration(center=(1.0, 1.0), matrix=((2.0, 0.0), (0.0, 2.0)), heading_offset_rad=0.2)
    psi = 0.5
    raw = (1.0 + 2.0 * math.cos(psi), 1.0 - 2.0 * math.sin(psi), 40.0)
    msg = calibrated_heading(MagSample(stamp_s=3.0, field_uT=raw), cal)
    assert msg is not None and msg.stamp_s == 3.0
    assert msg.heading_rad == pytest.approx(psi + 0.2)
    assert msg.heading_rad == pytest.approx(math.atan2(-msg.mag_y, msg.mag_x))
    assert math.hypot(msg.mag_x, msg.mag_y) == pytest.approx(1.0)
    assert calibrated_heading(MagSample(stamp_s=3.0, field_uT=(math.nan, 0.0, 0.0)), cal) is None


def _args(sub: str, *argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    calibrate.register(parser.add_subparsers())
    return parser.parse_args([sub, *argv])


def test_cli_round_trip(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    M, c = np.array([[16.0, 1.0], [1.0, 14.0]]), np.array([8.0, -5.0])
    psi, x, y = _turn(M, c, n=300)
    lines = ["t,mag_x,mag_y"] + [f"{i * 0.02:.2f},{a:.4f},{b:.4f}" for i, (a, b) in enumerate(zip(x, y))]
    lines.insert(5, "0.1,,3.0")  # an empty cell: skipped
    data = tmp_path / "turn.csv"
    data.write_text("\n".join(lines) + "\n")
    out = tmp_path / "mag.json"
    args = _args("calibrate-mag", str(data), "--out", str(out))
    assert args.func(args) == 0
    d = json.loads(out.read_text())
    assert set(d) >= {"center", "matrix", "residual_rms", "coverage_deg"}
    assert np.allclose(d["center"], c, atol=0.1) and np.allclose(d["matrix"], M, atol=0.2)
    said = capsys.readouterr()
    assert "1 rows skipped" in said.out and "1 of 301 rows skipped (unreadable), 300 used" in said.err
    cal = calibrate.load_mag_calibration(out)
    assert cal.heading(x[10], y[10]) == pytest.approx(math.remainder(psi[10], 2 * math.pi), abs=0.05)


def test_cli_errors(tmp_path) -> None:  # type: ignore[no-untyped-def]
    bad = tmp_path / "bad.csv"
    bad.write_text("time,mx,my\n0,1,2\n")
    args = _args("calibrate-mag", str(bad), "--out", str(tmp_path / "o.json"))
    with pytest.raises(DataError, match="missing column"):
        args.func(args)
    half = tmp_path / "half.csv"
    _, x, y = _turn(np.eye(2) * 15.0, np.zeros(2), span_deg=150.0)
    half.write_text("t,mag_x,mag_y\n" + "".join(f"{i},{a},{b}\n" for i, (a, b) in enumerate(zip(x, y))))
    args = _args("calibrate-mag", str(half), "--out", str(tmp_path / "o.json"))
    with pytest.raises(CalibrationError, match="half.csv.*cover"):
        args.func(args)
    assert not (tmp_path / "o.json").exists()


def test_cli_refuses_when_too_few_readable_rows_remain_and_says_how_many_were_skipped(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Issue 49: unreadable rows are skipped and counted; when the rest are too few to fit (an ellipse
    needs --min-points), the refusal says how many were skipped."""
    _, x, y = _turn(np.eye(2) * 15.0, np.zeros(2), n=40)
    rows = [f"{i * 0.1:.1f},{a:.4f},{b:.4f}" for i, (a, b) in enumerate(zip(x, y))]
    rows[3] = "0.3,x,1.0"  # one unreadable row in 40: a record, not a damaged file
    data = tmp_path / "few.csv"
    data.write_text("t,mag_x,mag_y\n" + "\n".join(rows) + "\n")
    args = _args("calibrate-mag", str(data), "--out", str(tmp_path / "o.json"), "--min-points", "100")
    with pytest.raises(DataError, match=r"few.csv.*\(1 of 40 rows were unreadable and skipped\)"):
        args.func(args)
    assert not (tmp_path / "o.json").exists()
