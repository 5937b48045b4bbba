"""The files the project writes and reads back: atomic writes and one reader for its JSON formats.

A leaf module (it imports nothing of volleybots but ``errors``), so that run directories, the
population loop's payoff table and the evaluation verbs write and read the same way.

Writes are atomic: the data goes to ``<name>.<pid>.tmp`` beside the file and is moved into place when
complete, so a process killed meanwhile leaves the old file whole. A write that fails (a full disk, a
folder made read-only) removes its temporary file and is one ``ConfigError`` line naming the file.

Reads turn every way a file can be damaged or hand-edited (missing, not JSON, a key missing, a value
of the wrong type or shape) into one ``ConfigError`` line naming the file and what is wrong in it.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import stat
import unicodedata
from pathlib import Path
from typing import Callable, Union

from volleybots.errors import ConfigError

Data = Union[str, bytes, Callable]  # text, bytes, or a function writing to a binary file object


def printable(s) -> str:
    """``s`` as a string with every control and format character written out as its escape: a label
    from a received file or a name on a command line can then never retitle, recolour or rewrite the
    terminal it is shown on (``\\x1b]0;...`` is shown, not obeyed)."""
    s = str(s)
    return "".join(c.encode("unicode_escape").decode() if unicodedata.category(c)[0] == "C" else c for c in s)


def _write(f, data: Data) -> None:
    """Write ``data`` to the open binary file ``f`` (monkeypatched by tests to simulate a full disk)."""
    if callable(data):
        data(f)
    else:
        f.write(data.encode() if isinstance(data, str) else data)


class _Watched:
    """A binary file that keeps the ``OSError`` its last failed write raised, for writers that turn it
    into another error of their own (``torch.save``)."""

    def __init__(self, f):
        self.f, self.error = f, None

    def write(self, b):
        try:
            return self.f.write(b)
        except OSError as e:
            self.error = e
            raise

    def __getattr__(self, name):
        return getattr(self.f, name)


def write_atomic(path, data: Data, what: str = "") -> Path:
    """Write ``data`` to ``path`` atomically; an OS error (ENOSPC, EACCES, ...) is one line, and no
    temporary file is left behind."""
    path = Path(path)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as raw:
            f = _Watched(raw)
            try:
                _write(f, data)
            except RuntimeError:
                # torch.save turns a short write (a full disk, a file size limit) into its own RuntimeError
                # ("unexpected pos ..."); the OSError under it is the user's to fix, and said as such
                if f.error is None:
                    raise
                raise f.error from None
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise ConfigError(
            f"cannot write {what + ' ' if what else ''}{str(path)!r}: {e.strerror or e}; free space or choose another folder"
        ) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_json(path, data, what: str = "", indent: int = 1) -> Path:
    return write_atomic(path, json.dumps(data, indent=indent, default=float) + "\n", what)


def sha256(path) -> str:
    """The hex sha256 of a file's bytes: what a results file or a population records of the file that played."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def exists(path) -> bool:
    """Whether ``path`` exists; a name the OS cannot even look up (too long, invalid) does not."""
    try:
        return Path(path).exists()
    except (OSError, ValueError):
        return False


def _one_line(e: Exception) -> str:
    return " ".join(str(getattr(e, "msg", None) or e).split())[:160]


MAX_READ_BYTES = 256 * 2**20  # the largest file of this project's (a 100-competitor cross-play is a few MB)


def read_bytes(path, what: str, limit: int = MAX_READ_BYTES) -> bytes:
    """The bytes of the regular file ``path``, read with a bound: a folder, a device (``/dev/zero``), a
    pipe or a file over ``limit`` bytes is one line naming it, never a hang or a MemoryError."""
    p = Path(path)
    try:
        st = p.stat()
    except (OSError, ValueError):
        raise ConfigError(f"{what} {str(path)!r} does not exist") from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "a device, pipe or socket"
        raise ConfigError(f"{what} {str(path)!r} is {kind}, not a file")
    too_big = ConfigError(f"{what} {str(path)!r} is larger than {limit:,} bytes, more than any {what} holds; "
                          "it is not one (or it is damaged)")
    if st.st_size > limit:
        raise too_big
    try:
        with open(p, "rb") as f:
            data = f.read(limit + 1)  # a file still growing is cut at the bound too
    except OSError as e:
        raise ConfigError(f"{what} {str(path)!r} cannot be read: {e.strerror or e}") from None
    if len(data) > limit:
        raise too_big
    return data


def read_text(path, what: str, limit: int = MAX_READ_BYTES) -> str:
    """The text of the regular file ``path``, read with a bound (``read_bytes``); a file that is not
    UTF-8 is one line naming it."""
    data = read_bytes(path, what, limit)
    try:
        return data.decode()
    except UnicodeDecodeError:
        raise ConfigError(f"{str(path)!r} is damaged or not a {what} (not text: binary bytes)") from None


def read_yaml_text(path, what: str) -> str:
    """The text of the YAML file ``path`` (``read_text``), refused if it holds an alias: the byte bound
    does not bound what a loader builds from ``*aliases`` (a few hundred bytes of nested ones expand
    to billions of nodes), and no file of this project's needs one."""
    import yaml

    text = read_text(path, what)
    try:
        for event in yaml.parse(text, Loader=yaml.SafeLoader):  # events only: nothing is expanded
            if isinstance(event, yaml.AliasEvent):
                raise ConfigError(f"{what} {str(path)!r} holds a YAML alias (*{event.anchor}); a received YAML file is read "
                                  "without aliases: write each value out")
    except yaml.YAMLError:
        pass  # malformed: the caller's loader names what is wrong
    return text


def read_json(path, what: str):
    """The JSON value in ``path``; a missing, unreadable, unbounded or malformed file is one line naming it."""
    p = Path(path)
    if not p.exists():
        raise ConfigError(f"{what} {str(path)!r} does not exist")
    text = read_text(p, what)
    try:
        return json.loads(text)
    except (json.JSONDecodeError, RecursionError) as e:
        raise ConfigError(f"{str(path)!r} is damaged or not a {what} (not JSON: {_one_line(e)})") from None


def read_jsonl(path, what: str) -> list:
    """The JSON values of the non-blank lines of ``path`` (none if it does not exist); a bad line is
    one line naming the file and the line number."""
    p = Path(path)
    if not p.exists():
        return []
    lines = read_text(p, what).splitlines()
    out = []
    for n, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError as e:
            raise ConfigError(f"{what} {str(path)!r} is damaged (line {n} is not JSON: {_one_line(e)})") from None
    return out


class Fields:
    """Typed access to one JSON object of a file: ``need(key, kind)`` raises one line naming the file,
    the key and what it should be."""

    def __init__(self, data, where: str):
        self.where = where
        if not isinstance(data, dict):
            self.fail(f"not a JSON object but {type(data).__name__}")
        self.data = data

    def fail(self, msg: str):
        raise ConfigError(f"{self.where} is damaged ({msg}); restore it or produce it again")

    def need(self, key: str, kind, optional: bool = False):
        if key not in self.data:
            if optional:
                return None
            self.fail(f"no {key!r}")
        v = self.data[key]
        kinds = kind if isinstance(kind, tuple) else (kind,)
        if isinstance(v, bool) and bool not in kinds or not isinstance(v, kinds):
            self.fail(f"{key!r} is {type(v).__name__}, not {' or '.join(k.__name__ for k in kinds)}")
        return v

    def count(self, key: str, optional: bool = False):
        """One non-negative integer count (a whole float is one: JSON may write 5.0); None where absent and ``optional``."""
        if key not in self.data and optional:
            return None
        self._counts(self.need(key, (int, float)), (), key)
        return int(self.data[key])

    def counts(self, key: str, shape: tuple) -> list:
        """A nested list of non-negative integers of exactly ``shape`` (no ragged rows)."""
        v = self.need(key, list)
        self._counts(v, shape, key)
        return v

    def _counts(self, v, shape, where):
        if not shape:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v != int(v) or v < 0:
                self.fail(f"{where} is {v!r}, not a non-negative integer count")
            return
        if not isinstance(v, list) or len(v) != shape[0]:
            self.fail(f"{where} should be a list of {shape[0]} entries, got {len(v) if isinstance(v, list) else type(v).__name__}")
        for i, x in enumerate(v):
            self._counts(x, shape[1:], f"{where}[{i}]")

    def mirrored(self, key: str, wdl) -> None:
        """``wdl`` (counts ``[n][n][3]``, checked already) as a zero-sum record holds them: each (j, i)
        the mirror of (i, j), wins and losses swapped, and nothing on the diagonal (no self-play)."""
        for i, row in enumerate(wdl):
            if any(row[i]):
                self.fail(f"{key}[{i}][{i}] is {list(row[i])!r}: a member does not play itself")
            for j in range(i + 1, len(wdl)):
                w, d, l_ = row[j]
                if list(wdl[j][i]) != [l_, d, w]:
                    self.fail(f"{key}[{j}][{i}] is {list(wdl[j][i])!r}, not the mirror {[l_, d, w]!r} of {key}[{i}][{j}]")

    def mixture(self, key: str, n: int) -> list[float]:
        """``n`` non-negative finite weights summing to 1 (to 1e-6)."""
        v = self.need(key, list)
        if len(v) != n:
            self.fail(f"{key!r} has {len(v)} weights for {n} members")
        for i, w in enumerate(v):
            if isinstance(w, bool) or not isinstance(w, (int, float)) or not math.isfinite(w) or w < 0:
                self.fail(f"{key}[{i}] is {w!r}, not a weight >= 0")
        if abs(sum(v) - 1.0) > 1e-6:
            self.fail(f"{key!r} sums to {sum(v):.6g}, not 1")
        return [float(w) for w in v]


__all__ = ["MAX_READ_BYTES", "Fields", "exists", "read_bytes", "read_json", "read_jsonl", "read_text", "sha256", "write_atomic",
           "write_json"]
