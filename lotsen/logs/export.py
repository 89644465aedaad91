"""Export a log to tables: one CSV per topic, and the identification CSV of `lotsen identify`.

Per-topic tables (`<topic with / as .>.csv`): `log_time_s` (receipt time since the first message of
the log), then the message fields; fixed-size tuples are split into columns (`gyro_radps_0..2`),
enums written as their integer (the name in a `<field>_name` column), variable-length tuples,
dicts and bytes as JSON / hex text in one cell. NaN is written as `nan`.

Identification table (`sysid.csv`, the format of `lotsen.sysid.data.load_csv`):
`t,alpha1,alpha2,n1,n2,nt,north,east,psi,r,u,v`, one row per output message.
* outputs from `state/estimate` (what the boat believed), or `sim/truth` with `outputs="truth"`;
  `outputs="auto"` takes the estimate when the log has one, else the truth;
* inputs from `sim/actuators` (achieved servo angles and propeller speeds; what actually drove
  the boat) when present, else `ship_command` (the set-points), zero-order held to each output
  time (the latest input received before the output);
* `t` is the output message's `stamp_s`; psi is as recorded (the estimators wrap psi residuals).
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

from lotsen.errors import DataError, LotsenError
from lotsen.logs.reader import LogReader
from lotsen.messages import Topic


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
    return topic.strip("/").replace("/", ".") + ".csv"


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
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    reader = LogReader(path)
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
    files = {}
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
            with open(f, "w", newline="") as fh:
                w = csv.DictWriter(fh, fieldnames=cols, restval="")
                w.writeheader()
                w.writerows(rs)
        files[topic] = f
    if problems is not None:
        problems.extend(reader.problems)
    return files


@dataclass
class SysidTable:
    header: list[str]
    rows: list[list[float]]
    inputs_topic: str
    outputs_topic: str


def sysid_table(path: str | os.PathLike, outputs: Literal["auto", "estimate", "truth"] = "auto",
                inputs: Literal["auto", "achieved", "command"] = "auto") -> SysidTable:
    """The identification table of a log (see module docstring for the choices)."""
    reader = LogReader(path)
    want = [Topic.STATE, Topic.TRUTH, Topic.ACTUATORS, Topic.SHIP_COMMAND]
    counts = {t: 0 for t in want}
    for ch, *_ in reader.iter_raw():
        if ch.topic in counts:
            counts[ch.topic] += 1
    out_topic = {"estimate": Topic.STATE, "truth": Topic.TRUTH}.get(outputs) or (
        Topic.STATE if counts[Topic.STATE] else Topic.TRUTH)
    in_topic = {"achieved": Topic.ACTUATORS, "command": Topic.SHIP_COMMAND}.get(inputs) or (
        Topic.ACTUATORS if counts[Topic.ACTUATORS] else Topic.SHIP_COMMAND)
    if not counts[out_topic]:
        raise DataError(f"{path}: no {out_topic} messages (outputs of the identification table)")
    if not counts[in_topic]:
        raise DataError(f"{path}: no {in_topic} messages (inputs of the identification table)")
    header = ["t", "alpha1", "alpha2", "n1", "n2", "nt", "north", "east", "psi", "r", "u", "v"]
    rows: list[list[float]] = []
    u_last: tuple[float, ...] | None = None
    for topic, msg in reader.messages([in_topic, out_topic]):
        if topic == in_topic:
            u_last = msg.as_tuple()
        elif u_last is not None:
            if rows and not msg.stamp_s > rows[-1][0]:
                continue  # sysid needs strictly increasing time
            rows.append([msg.stamp_s, *u_last, msg.north_m, msg.east_m, msg.heading_rad, msg.r_radps,
                         msg.u_mps, msg.v_mps])
    if len(rows) < 2:
        raise DataError(f"{path}: fewer than 2 rows with both {in_topic} and {out_topic}")
    return SysidTable(header, rows, in_topic, out_topic)


def write_sysid_csv(path: str | os.PathLike, out_file: str | os.PathLike, **kw: Any) -> SysidTable:
    table = sysid_table(path, **kw)
    Path(out_file).parent.mkdir(parents=True, exist_ok=True)
    with open(out_file, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(table.header)
        for row in table.rows:
            w.writerow(["nan" if not math.isfinite(v) else f"{v:.9g}" for v in row])
    return table


def sysid_loader(path: Path) -> Any:
    """`lotsen.sysid.data` loader for `.mcap` files (register with
    `lotsen.sysid.data.register_loader(".mcap", sysid_loader)`)."""
    import numpy as np

    from lotsen.sysid.data import IdRecord

    table = sysid_table(path)
    a = np.array(table.rows, dtype=float)
    return IdRecord(a[:, 0], a[:, 1:6], np.column_stack([a[:, 6:10], a[:, 10:12]]),
                    ("north", "east", "psi", "r", "u", "v"), f"{path} ({table.inputs_topic} -> {table.outputs_topic})")
