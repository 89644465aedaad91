"""Reading files at the boundary, with errors that name the file and what is wrong with it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from lotsen.errors import LotsenError


def read_json(path: str | Path, error: type[LotsenError] = LotsenError, expect_object: bool = True) -> Any:
    """The parsed JSON of `path`; `error` (a LotsenError kind) names the file and the problem."""
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise error(f"{p}: cannot read: {exc.strerror}") from None
    except json.JSONDecodeError as exc:
        raise error(f"{p}: not valid JSON at line {exc.lineno}: {exc.msg}") from None
    if expect_object and not isinstance(data, dict):
        raise error(f"{p}: expected a JSON object")
    return data
