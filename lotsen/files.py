"""Reading files at the boundary, with errors that name the file and what is wrong with it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from lotsen.errors import LotsenError


def read_text(path: str | Path, error: type[LotsenError] = LotsenError, what: str = "file") -> str:
    p = Path(path)
    try:
        return p.read_text(encoding="utf-8")
    except OSError as exc:
        raise error(f"{p}: cannot read {what}: {exc.strerror or exc}") from None


def parse_yaml(text: str, path: str | Path, error: type[LotsenError] = LotsenError) -> Any:
    """YAML with the line of a syntax error in the message."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        loc = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise error(f"{path}: not valid YAML{loc}: {getattr(exc, 'problem', exc)}") from None


def parse_json(text: str, path: str | Path, error: type[LotsenError] = LotsenError) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise error(f"{path}: not valid JSON at line {exc.lineno}: {exc.msg}") from None


def read_yaml(path: str | Path, error: type[LotsenError] = LotsenError, what: str = "file") -> Any:
    return parse_yaml(read_text(path, error, what), path, error)


def read_json(path: str | Path, error: type[LotsenError] = LotsenError, expect_object: bool = True) -> Any:
    """The parsed JSON of `path`; `error` (a LotsenError kind) names the file and the problem."""
    data = parse_json(read_text(path, error), path, error)
    if expect_object and not isinstance(data, dict):
        raise error(f"{path}: expected a JSON object")
    return data
