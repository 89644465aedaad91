"""Reading files at the boundary, with errors that name the file and what is wrong with it."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from typing import Any

import yaml

from lotsen.errors import LotsenError

_CONTROL = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")


def decode_text(data: bytes, path: str | Path, error: type[LotsenError] = LotsenError, what: str = "file") -> str:
    """UTF-8 text (a UTF-8 byte-order mark is dropped); anything else is `error` naming the file
    and, for UTF-16 (what some Windows editors save), the fix. Control characters other than tab,
    line feed and carriage return are refused too (YAML and JSON allow none): UTF-16 text without
    a byte-order mark is often valid UTF-8 with a NUL or another control byte beside each letter."""
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise error(f"{path}: the {what} is UTF-16 text; save it as UTF-8")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise error(f"{path}: the {what} is not UTF-8 text (byte 0x{data[exc.start]:02x} at line {line}); "
                    "save it as UTF-8") from None
    bad = _CONTROL.search(text)
    if bad:
        line = text[:bad.start()].count("\n") + 1
        name = "a NUL character" if bad.group() == "\x00" else f"the control character 0x{ord(bad.group()):02x}"
        controls = len(_CONTROL.findall(text))
        utf16 = " (UTF-16 without a byte-order mark?)" if controls * 3 > len(text) else ""
        raise error(f"{path}: the {what} holds {name} at line {line}: not a text file{utf16}; "
                    "save it as UTF-8")
    return text


def read_text(path: str | Path, error: type[LotsenError] = LotsenError, what: str = "file") -> str:
    """The UTF-8 text of `path` (`decode_text`); `error` names the file and the problem."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise error(f"{p}: cannot read {what}: {exc.strerror or exc}") from None
    return decode_text(data, p, error, what)


# Limits of what a configuration, route or parameter file may hold. Real files nest < 10 levels
# and hold < 100 k values (a long GeoJSON route); beyond these the file is hostile or broken.
MAX_NESTING = 64
MAX_VALUES = 1_000_000  # counted with YAML aliases expanded: refuses "billion laughs" alias bombs
_FLOAT_MAX = sys.float_info.max


def _at(where: str) -> str:
    return where if len(where) <= 80 else where[:60] + "..." + where[-15:]


def check_structure(data: Any, path: str | Path, error: type[LotsenError] = LotsenError) -> Any:
    """Refuse parsed data no loader should have to walk: nesting deeper than MAX_NESTING, a
    structure that contains itself (YAML `&a [*a]`), more than MAX_VALUES values once aliases
    are expanded, and integers beyond the float range (every loader converts numbers to float).
    The message names the file and the key path. Iterative: safe at any depth. Returns `data`."""
    memo: dict[int, tuple[int, int]] = {}  # id of a container -> (values below, height)
    active: set[int] = set()
    total = 0
    # frames: [container, its key path, iterator over (key, child), values, height]
    frames: list[list[Any]] = []

    def join(parent: str, key: Any) -> str:  # key paths are built only for containers and errors
        return f"{parent}[{key}]" if isinstance(key, int) else (f"{parent}.{key}" if parent else str(key))

    def visit(obj: Any, parent: str, key: Any) -> tuple[int, int] | None:
        """(values, height) of a leaf or an already walked container; None after pushing a frame."""
        nonlocal total
        if isinstance(obj, (dict, list)):
            where = join(parent, key) if key is not None else parent
            size, height = memo.get(id(obj), (0, -1))
            if height >= 0:  # shared (a YAML alias): counted again, walked once
                if len(frames) + height > MAX_NESTING:
                    raise error(f"{path}: {_at(where)}: nested deeper than {MAX_NESTING} levels")
                total += size
                if total > MAX_VALUES:
                    raise error(f"{path}: {_at(where)}: more than {MAX_VALUES} values once YAML aliases are "
                                "expanded (an alias bomb?)")
                return size, height
            if id(obj) in active:
                raise error(f"{path}: {_at(where)}: the structure contains itself (a recursive YAML alias)")
            if len(frames) >= MAX_NESTING:
                raise error(f"{path}: {_at(where)}: nested deeper than {MAX_NESTING} levels")
            active.add(id(obj))
            frames.append([obj, where, iter(obj.items() if isinstance(obj, dict) else enumerate(obj)), 1, 0])
            return None
        if isinstance(obj, int) and not isinstance(obj, bool) and abs(obj) > _FLOAT_MAX:
            where = join(parent, key) if key is not None else "value"
            raise error(f"{path}: {_at(where)}: integer with {len(str(abs(obj)))} digits is too large")
        total += 1
        if total > MAX_VALUES:
            raise error(f"{path}: {_at(join(parent, key) if key is not None else parent)}: more than "
                        f"{MAX_VALUES} values")
        return 1, 0

    visit(data, "", None)
    while frames:
        frame = frames[-1]
        for key, child in frame[2]:
            got = visit(child, frame[1], key)
            if got is None:
                break  # descend first
            frame[3] += got[0]
            frame[4] = max(frame[4], got[1] + 1)
        else:
            frames.pop()
            active.discard(id(frame[0]))
            memo[id(frame[0])] = (frame[3], frame[4])
            if frames:
                frames[-1][3] += frame[3]
                frames[-1][4] = max(frames[-1][4], frame[4] + 1)
    return data


class DuplicateKeyError(yaml.constructor.ConstructorError):
    pass


def _construct_unique_mapping(loader: yaml.SafeLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    """A mapping whose keys are all different: YAML itself lets the last of two equal keys win
    silently (a setting typed twice, the first one believed)."""
    seen: dict[Any, int] = {}
    for key_node, _ in node.value:
        if key_node.tag == "tag:yaml.org,2002:merge":  # `<<: *base`: its keys may be overridden here
            continue
        key = loader.construct_object(key_node, deep=deep)
        try:
            first = seen.get(key)
        except TypeError:  # an unhashable key: the constructor reports it below
            continue
        if first is not None:
            raise DuplicateKeyError(None, None, f"duplicate key {str(key)[:60]!r} (first at line {first})",
                                    key_node.start_mark)
        seen[key] = key_node.start_mark.line + 1
    return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)


class StrictYamlLoader(yaml.SafeLoader):
    """Safe YAML that refuses duplicate keys (top level and nested) with the key and its line."""


class FastStrictYamlLoader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # type: ignore[misc]
    """StrictYamlLoader on libyaml's parser when present (the constructor stays in Python)."""


#: YAML 1.1 (PyYAML) reads 1e9, 3e-2 and 1.0e9 as text: its floats need a dot and a signed
#: exponent. An operator writing a coefficient in exponent form means a number (YAML 1.2 agrees).
_EXPONENT_FLOAT = re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$")

for _loader in (StrictYamlLoader, FastStrictYamlLoader):
    _loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_unique_mapping)  # type: ignore[arg-type]
    _loader.add_implicit_resolver("tag:yaml.org,2002:float", _EXPONENT_FLOAT, list("-+.0123456789"))


class NoAliasYamlLoader(StrictYamlLoader):
    """StrictYamlLoader without anchors/aliases, for text from outside (a route pasted into the
    page never needs them, and nested aliases make a few kB expand into millions of nodes)."""

    def compose_node(self, parent, index):  # type: ignore[no-untyped-def]  # noqa: ANN001 - PyYAML's signature
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.YAMLError(f"aliases (*{event.anchor}) are not allowed here "
                                 f"(line {event.start_mark.line + 1})")
        return super().compose_node(parent, index)


def _yaml_loader(text: str, aliases: bool) -> type:
    if aliases:
        return StrictYamlLoader
    # libyaml composes in C, out of reach of compose_node: only for text that cannot hold an alias
    return FastStrictYamlLoader if "*" not in text else NoAliasYamlLoader


def parse_yaml(text: str, path: str | Path, error: type[LotsenError] = LotsenError, aliases: bool = True) -> Any:
    """YAML with the line of a syntax error in the message; duplicate keys and hostile
    structures refused (`check_structure`); `aliases=False` refuses anchors and aliases too."""
    try:
        data = yaml.load(text, Loader=_yaml_loader(text, aliases))  # noqa: S506 - safe loaders only
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        loc = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise error(f"{path}: not valid YAML{loc}: {getattr(exc, 'problem', exc)}") from None
    except RecursionError:
        raise error(f"{path}: nested too deeply to read (more than {MAX_NESTING} levels are refused)") from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        raise error(f"{path}: not valid YAML: {exc}") from None
    return check_structure(data, path, error)


class _DuplicateJsonKey(ValueError):
    pass


def _unique_object(pairs: list[tuple[str, Any]]) -> dict:
    """A JSON object whose keys are all different (json.loads lets the last one win silently)."""
    out: dict = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateJsonKey(f"duplicate key {key[:60]!r} in an object")
        out[key] = value
    return out


def parse_json(text: str, path: str | Path, error: type[LotsenError] = LotsenError) -> Any:
    """JSON with the line of a syntax error in the message; hostile structures refused
    (`check_structure`)."""
    try:
        data = json.loads(text, object_pairs_hook=_unique_object)
    except json.JSONDecodeError as exc:
        raise error(f"{path}: not valid JSON at line {exc.lineno}: {exc.msg}") from None
    except RecursionError:
        raise error(f"{path}: nested too deeply to read (more than {MAX_NESTING} levels are refused)") from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        raise error(f"{path}: not valid JSON: {exc}") from None
    return check_structure(data, path, error)


def read_yaml(path: str | Path, error: type[LotsenError] = LotsenError, what: str = "file") -> Any:
    return parse_yaml(read_text(path, error, what), path, error)


def read_json(path: str | Path, error: type[LotsenError] = LotsenError, expect_object: bool = True) -> Any:
    """The parsed JSON of `path`; `error` (a LotsenError kind) names the file and the problem."""
    data = parse_json(read_text(path, error), path, error)
    if expect_object and not isinstance(data, dict):
        raise error(f"{path}: expected a JSON object")
    return data
