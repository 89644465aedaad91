"""Reading files at the boundary, with errors that name the file and what is wrong with it."""

from __future__ import annotations

import json
import os
import re
import stat
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterable, Iterator

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


# Size caps of every file the project reads (docs/inputs.md). A file over its cap is refused before
# a byte of it is parsed: PyYAML reads ~0.2 MB/s on the boat's class of CPU, so a 50 MB route file
# ran for minutes. The caps are far above any real file of the kind.
MAX_TEXT_BYTES = 512 * 1024  # configuration, route, experiment, schedule, parameter and calibration files
MAX_DATA_BYTES = 64 * 1024 * 1024  # CSV records: identification data (~6 MB for 10 min), magnetometer turns
MAX_CAPTURE_BYTES = 256 * 1024 * 1024  # raw receiver captures (UBX): a day of 8 Hz NAV-PVT is ~70 MB
MAX_LOG_BYTES = 4 * 1024 * 1024 * 1024  # MCAP recordings, read as a stream


def _size(n: int) -> str:
    for unit, k in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= k:
            return f"{n / k:.3g} {unit}"
    return f"{n} bytes"


def check_input_file(path: str | Path, limit: int, error: type[LotsenError] = LotsenError, what: str = "file") -> int:
    """The size of `path`, a regular file of at most `limit` bytes; `error` naming the file
    otherwise (missing, a folder, a device or pipe, which could block or never end, or too large)."""
    p = Path(path)
    try:
        st = p.stat()
    except OSError as exc:
        raise error(f"{_short_name(str(p))}: cannot read {what}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(st.st_mode):
        raise error(f"{p}: is a folder, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{p}: not a regular file (a device or a pipe); the {what} must be a file")
    if st.st_size > limit:
        raise error(f"{p}: {_size(st.st_size)} is more than a {what} may be ({_size(limit)}); "
                    "is it the right file?")
    return st.st_size


def read_bytes(path: str | Path, limit: int, error: type[LotsenError] = LotsenError, what: str = "file") -> bytes:
    """The bytes of `path` (`check_input_file`), never more than `limit` (a file that grows meanwhile)."""
    check_input_file(path, limit, error, what)
    try:
        with open(path, "rb") as f:
            data = f.read(limit + 1)
    except OSError as exc:
        raise error(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise error(f"{path}: more than a {what} may be ({_size(limit)})")
    return data


def read_text(path: str | Path, error: type[LotsenError] = LotsenError, what: str = "file",
              limit: int = MAX_TEXT_BYTES) -> str:
    """The UTF-8 text of `path` (`decode_text`), at most `limit` bytes; `error` names the file and the problem."""
    return decode_text(read_bytes(path, limit, error, what), Path(path), error, what)


# ---------------------------------------------------------------------------------- outputs
def same_file(a: str | Path, b: str | Path) -> bool:
    """Are `a` and `b` one file (the same path, a hard link or a symbolic link to it)?"""
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


def check_output(path: str | Path, inputs: Iterable[str | Path | None] = (), error: type[LotsenError] = LotsenError,
                 what: str = "output") -> Path:
    """`path` as an output a command may write, checked before any work: its folder exists, it is
    not a folder, and it is none of `inputs` (the same path, a hard link or a symbolic link to one:
    an output never destroys what the command reads)."""
    text = str(path)
    if not text.strip() or "\x00" in text:
        raise error(f"{what}: {text!r} is not a file name")
    try:
        return _check_output(Path(path), inputs, error, what)
    except OSError as exc:  # e.g. a name longer than the file system takes
        raise error(f"{_short_name(text)}: cannot write the {what}: {exc.strerror or exc}") from None


def _short_name(text: str) -> str:
    return text if len(text) <= 120 else text[:100] + "..." + text[-15:]


def _check_output(p: Path, inputs: Iterable[str | Path | None], error: type[LotsenError], what: str) -> Path:
    if p.is_dir():
        raise error(f"{p}: is a folder; give the {what} a file name")
    if p.exists() and not p.is_file():  # a device (/dev/null), a FIFO, a socket: never replaced by a file
        raise error(f"{p}: not a regular file; the {what} is written as a new file, give it a file name")
    parent = p.parent
    if not parent.is_dir():
        raise error(f"{p}: cannot write the {what}: the folder {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise error(f"{p}: cannot write the {what}: no permission to write in {parent}")
    for i in inputs:
        if i is not None and str(i) and same_file(p, i):
            how = "a link to it" if Path(i).absolute() != p.absolute() else "the same file"
            raise error(f"{p}: the {what} would overwrite the input {i} ({how}); choose another name")
    return p


def check_outputs(outputs: Iterable[str | Path | None], inputs: Iterable[str | Path | None] = (),
                  error: type[LotsenError] = LotsenError) -> None:
    """`check_output` for each given output, and no two outputs the same file."""
    given = [o for o in outputs if o is not None]
    ins = list(inputs)
    for k, o in enumerate(given):
        check_output(o, ins, error)
        for other in given[:k]:
            if Path(o).absolute() == Path(other).absolute() or same_file(o, other):
                raise error(f"{o}: given as two outputs of one command; choose two names")


@contextmanager
def atomic_output(path: str | Path, inputs: Iterable[str | Path | None] = (), error: type[LotsenError] = LotsenError,
                  what: str = "output") -> Iterator[Path]:
    """A temporary file beside `path` (same suffix, so writers that choose a format by it still
    do) that replaces `path` by a rename when the block ends without an exception; otherwise it is
    removed and `path` is left as it was. `check_output` first. OSError becomes `error`."""
    p = check_output(path, inputs, error, what)
    tmp = p.with_name(f".{p.stem}.{os.getpid()}.tmp{p.suffix}")
    try:
        yield tmp
        if tmp.is_file():
            with open(tmp, "rb+") as f:
                os.fsync(f.fileno())
        os.replace(tmp, p)
    except OSError as exc:
        raise error(f"{p}: cannot write the {what}: {exc.strerror or exc}") from None
    finally:
        try:
            tmp.unlink()
        except OSError:
            pass


def write_output(path: str | Path, data: str | bytes, inputs: Iterable[str | Path | None] = (),
                 error: type[LotsenError] = LotsenError, what: str = "output") -> Path:
    """Write `data` (text as UTF-8) to `path` atomically (`atomic_output`)."""
    with atomic_output(path, inputs, error, what) as tmp:
        tmp.write_bytes(data.encode("utf-8") if isinstance(data, str) else data)
    return Path(path)


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
