"""Export a log to tables: one CSV per topic, and the identification CSV of `lotsen identify`.

Per-topic tables (`<topic with / as .>.csv`): `log_time_s` (receipt time since the first message of
the log), then the message fields; fixed-size tuples are split into columns (`gyro_radps_0..2`),
enums written as their integer (the name in a `<field>_name` column), variable-length tuples,
dicts and bytes as JSON / hex text in one cell. NaN is written as `nan`.

Identification record (`sysid_record`, written as `sysid.csv` by `lotsen export` and read by
`lotsen identify RUN.mcap`): the asynchronous form of docs/sysid.md, every message a row at its
own stamp carrying only what it measured.
"""

from __future__ import annotations

import csv
import dataclasses
import enum
import json
import math
import os
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Literal

import numpy as np

from lotsen.errors import DataError, LotsenError
from lotsen.files import atomic_output
from lotsen.model.geodetic import FixFrame
from lotsen.model.angles import lever_arm_ne
from lotsen.logs.reader import LogReader
from lotsen.messages import Topic
from lotsen.sysid.data import IdRecord, check_record


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return "nan" if math.isnan(v) else repr(v)
    return str(v)


def _flatten(name: str, tp: Any, v: Any, out: dict[str, str]) -> None:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if isinstance(v, enum.Enum):
        out[name] = str(v.value)
        out[f"{name}_name"] = v.name
    elif origin is tuple and args and args[-1] is not Ellipsis:
        for i, (a, x) in enumerate(zip(args, v)):
            _flatten(f"{name}_{i}", a, x, out)
    elif isinstance(v, (bytes, bytearray)):
        out[name] = bytes(v).hex()
    elif isinstance(v, (tuple, list, dict)):
        from lotsen.transport.codec import _value_out

        out[name] = json.dumps(_value_out(v))
    elif dataclasses.is_dataclass(v):
        hints = typing.get_type_hints(type(v))
        for f in dataclasses.fields(v):
            _flatten(f"{name}.{f.name}", hints[f.name], getattr(v, f.name), out)
    elif v is None:
        out[name] = ""
    else:
        out[name] = _fmt(v)


def message_row(msg: Any) -> dict[str, str]:
    out: dict[str, str] = {}
    hints = typing.get_type_hints(type(msg))
    for f in dataclasses.fields(msg):
        _flatten(f.name, hints[f.name], getattr(msg, f.name), out)
    return out


def topic_file_name(topic: str) -> str:
    """`state/estimate` -> `state.estimate.csv`; a recorded topic name is data from a file, so
    anything but letters, digits, '.', '_' and '-' becomes '_' and the name stays short."""
    name = "".join(c if c.isascii() and (c.isalnum() or c in "._-") else "_" for c in topic.strip("/").replace("/", "."))
    return (name.lstrip(".") or "_")[:120] + ".csv"


def output_folder(path: str | os.PathLike) -> Path:
    """A folder to write tables into: created if missing (its parent must exist), refused if it is a file."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise DataError(f"{out}: exists and is not a folder; --out names the folder the tables go to")
    if not out.parent.is_dir():
        raise DataError(f"{out}: cannot create the folder: {out.parent} does not exist")
    try:
        out.mkdir(exist_ok=True)
    except OSError as exc:
        raise DataError(f"{out}: cannot create the folder: {exc.strerror or exc}") from None
    return out


def check_format(fmt: str) -> None:
    if fmt == "parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise LotsenError("--format parquet needs pyarrow, which is not installed "
                              "(pip install pyarrow); use --format csv") from None
    elif fmt != "csv":
        raise LotsenError(f"unknown export format {fmt!r} (csv or parquet)")


def export_topics(path: str | os.PathLike, out_dir: str | os.PathLike, topics: Iterable[str] | None = None,
                  fmt: str = "csv", problems: list | None = None) -> dict[str, Path]:
    """Write one table per topic; returns {topic: file}. Reading problems (a truncated tail, a
    damaged chunk) are appended to `problems` when given."""
    check_format(fmt)
    reader = LogReader(path)
    out = output_folder(out_dir)
    rows: dict[str, list[dict[str, str]]] = {}
    t0: int | None = None
    for m in reader.read(topics):
        t0 = m.log_time_ns if t0 is None else t0
        row = {"log_time_s": repr((m.log_time_ns - t0) / 1e9)}
        row.update(message_row(m.message))
        rows.setdefault(m.topic, []).append(row)
    if topics is not None:
        missing = [t for t in topics if t not in rows]
        if missing and not rows:
            raise DataError(f"{path}: none of the topics {', '.join(missing)} is in the log")
    files: dict[str, Path] = {}
    for topic, rs in rows.items():
        cols: list[str] = []
        for r in rs:
            for k in r:
                if k not in cols:
                    cols.append(k)
        if fmt == "parquet":  # pragma: no cover - pyarrow absent here
            import pyarrow as pa
            import pyarrow.parquet as pq

            f = out / topic_file_name(topic).replace(".csv", ".parquet")
            pq.write_table(pa.table({c: [r.get(c, "") for r in rs] for c in cols}), f)
        else:
            f = out / topic_file_name(topic)
            if f in files.values():  # two topics whose names differ only in replaced characters
                f = out / f"{f.stem}_{len(files)}.csv"
            with atomic_output(f, (path,), DataError, "table") as tmp, open(tmp, "w", newline="") as fh:
                w = csv.DictWriter(fh, fieldnames=cols, restval="")
                w.writeheader()
                w.writerows(rs)
        files[topic] = f
    if problems is not None:
        problems.extend(reader.problems)
    return files


def recorded_on(path: str | os.PathLike) -> str | None:
    """The boat a run log was recorded on, as the recorder named it (metadata `lotsen`, key `boat`:
    the simulated boat with its parameter file, or the external physics), or None (a log of the
    real boat, or one written before the key existed). The recorder writes the metadata before the
    first message, so reading stops there."""
    reader = LogReader(path)
    for _ in reader.iter_raw():
        break
    return reader.metadata.get("lotsen", {}).get("boat")


def sysid_record(path: str | os.PathLike, outputs: str = "auto", inputs: str = "auto",
                 gnss_antenna_m: tuple[float, float] = (0.0, 0.0)) -> IdRecord:
    """The identification record of a run log, in the asynchronous form of docs/sysid.md ("Data"):
    every message becomes a row at its own `stamp_s` carrying only what it measured.

    inputs:  `actuators/state` (achieved servo angles and measured propeller speeds: what drove the
             boat), or `ship_command` (set-points) with inputs="command" or when there is no
             actuator state. Commands hold from their stamp until the next (input kind "held");
             achieved values are readings at their stamps (input kind "sample": the estimator
             interpolates them linearly, docs/sysid.md).
    outputs: "raw": north/east of every usable GNSS fix (WGS84 -> NED at the first usable fix;
             the origin only shifts the estimated initial state), r = IMU gyro z minus the gyro
             bias the estimate last published (0 before it), psi from `state/estimate`;
             "estimate" / "truth": north, east, psi, r, u, v of `state/estimate` / `sim/truth`.
    `gnss_antenna_m`: where the antenna sits on the hull (body x, y from the model's origin, as
    `vessel.gnss_antenna_m`); raw fixes are moved from the antenna to the origin with the heading
    last estimated (an uncorrected 5 cm lever arm leaves a heading-dependent track error that the
    coefficients would otherwise absorb).
    `lotsen export` writes this record as sysid.csv and `lotsen identify RUN.mcap` reads it:
    both go through this function."""
    reader = LogReader(path)
    counts: dict[str, int] = {}
    for ch, *_ in reader.iter_raw():
        counts[ch.topic] = counts.get(ch.topic, 0) + 1
    has = lambda topic: counts.get(topic, 0) > 0  # noqa: E731
    if outputs == "auto":
        outputs = ("raw" if has(Topic.GNSS) and has(Topic.IMU_RAW) and has(Topic.STATE)
                   else "estimate" if has(Topic.STATE) else "truth")
    if inputs == "auto":
        inputs = "achieved" if has(Topic.ACTUATORS) else "command"
    in_topic = Topic.ACTUATORS if inputs == "achieved" else Topic.SHIP_COMMAND
    if outputs not in ("raw", "estimate", "truth"):
        raise LotsenError(f"sysid outputs {outputs!r}: expected auto, raw, estimate or truth")
    need = [in_topic] + ([Topic.GNSS, Topic.IMU_RAW, Topic.STATE] if outputs == "raw"
                         else [Topic.STATE if outputs == "estimate" else Topic.TRUTH])
    for topic in need:
        if not has(topic):
            raise DataError(f"{path}: no {topic} messages (needed for the identification record, outputs "
                            f"{outputs}, inputs {inputs})")
    names = ("north", "east", "psi", "r") + (("u", "v") if outputs != "raw" else ())
    ny = len(names)
    nan = float("nan")
    rows: list[tuple[float, ...]] = []  # (t, 5 inputs, ny outputs, 6 IMU_COLUMNS)
    blank_u, blank_y, blank_imu = (nan,) * 5, (nan,) * ny, (nan,) * 6
    frame = FixFrame()  # the identification record's frame: at the first usable fix
    bias = 0.0
    psi_last = nan
    arm = (float(gnss_antenna_m[0]), float(gnss_antenna_m[1]))
    for topic, msg in reader.messages(need):
        t = float(msg.stamp_s)
        if topic == in_topic:
            rows.append((t, *msg.as_tuple(), *blank_y, *blank_imu))
        elif outputs == "raw" and topic == Topic.GNSS:
            if not msg.usable:
                continue
            n, e = frame.to_ne(msg.lat_deg, msg.lon_deg, msg.height_m)
            if any(arm):
                if not math.isfinite(psi_last):
                    continue  # no heading yet to carry the lever arm: the fix cannot be placed
                dn, de = lever_arm_ne(psi_last, arm)
                n, e = n - dn, e - de
            rows.append((t, *blank_u, n, e, nan, nan, *blank_imu))
        elif outputs == "raw" and topic == Topic.IMU_RAW:
            # the IMU sample itself too: the record's sea state is estimated from it (lotsen.sysid.waves)
            rows.append((t, *blank_u, nan, nan, nan, msg.gyro_radps[2] - bias, *msg.accel_mps2, *msg.gyro_radps))
        elif outputs == "raw":  # the estimate: heading, and the gyro bias for the following IMU rows
            bias = msg.gyro_bias_radps if math.isfinite(msg.gyro_bias_radps) else bias
            psi_last = msg.heading_rad if math.isfinite(msg.heading_rad) else psi_last
            rows.append((t, *blank_u, nan, nan, msg.heading_rad, nan, *blank_imu))
        else:
            rows.append((t, *blank_u, msg.north_m, msg.east_m, msg.heading_rad, msg.r_radps, msg.u_mps, msg.v_mps,
                         *blank_imu))
    if len(rows) < 2:
        raise DataError(f"{path}: fewer than 2 identification rows")
    a = np.array(rows, dtype=float)
    a[~np.isfinite(a)] = np.nan  # an infinite reading is no reading
    a = a[np.argsort(a[:, 0], kind="stable")]  # topics are recorded on receipt: order by stamp
    imu = a[:, 6 + ny:]
    rec = IdRecord(a[:, 0], a[:, 1:6], a[:, 6:6 + ny], names,
                   f"{path} (inputs {in_topic}, outputs {outputs})",
                   input_kind="sample" if in_topic == Topic.ACTUATORS else "held",
                   imu=imu if np.isfinite(imu).all(axis=1).any() else None)
    check_record(rec)
    return rec
