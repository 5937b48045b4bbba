"""Locks and directories: one process per run directory, paths checked before anything is written.

A directory is used by one process at a time: the one holding the ``fcntl.flock`` lock on its
``.lock`` file. The operating system drops the lock when that process ends, however it ends, so a
killed run never leaves its directory stuck.
"""

from __future__ import annotations

import contextlib
import errno
import itertools
import os
import socket
import sys
from pathlib import Path

import torch

from volleybots.errors import ConfigError

try:
    import fcntl
except ImportError:  # not on Windows: run directories are then not locked
    fcntl = None

LOCK_NAME = ".lock"
_HELD: dict[str, list] = {}  # resolved path -> [lock file descriptor, times locked by this process]


class InUseError(ConfigError):
    """The directory is locked by another process."""


def lock(path) -> None:
    """Take the exclusive lock of the directory ``path`` for this process (again: counted), or raise
    ``ConfigError`` naming the process that holds it. ``fcntl.flock`` locks die with their process."""
    key = str(Path(path).resolve())
    if key in _HELD:
        _HELD[key][1] += 1
        return
    if fcntl is None:
        return
    lock_path = Path(key) / LOCK_NAME
    try:
        # never through a link: the lock file is truncated and written, and must be the directory's own
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
    except OSError as e:
        raise ConfigError(f"cannot lock {str(path)!r}: {e.strerror} ({lock_path})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        holder = os.read(fd, 200).decode(errors="replace").strip() or "another process"
        os.close(fd)
        raise InUseError(f"{path} is in use by {holder}; wait for it to finish or choose another directory") from None
    os.ftruncate(fd, 0)
    os.write(fd, f"process {os.getpid()} on {socket.gethostname()}\n".encode())
    _HELD[key] = [fd, 1]


def unlock(path) -> None:
    key = str(Path(path).resolve())
    held = _HELD.get(key)
    if held is None:
        return
    held[1] -= 1
    if held[1] == 0:
        del _HELD[key]
        os.close(held[0])  # closing the descriptor drops the flock


@contextlib.contextmanager
def locked(path):
    lock(path)
    try:
        yield
    finally:
        unlock(path)


def check_writable(path, what: str) -> None:
    """Raise ``ConfigError`` unless the directory ``path`` exists and is writable or can be created:
    no file in the way and permission to write in its nearest existing ancestor. Writes nothing."""
    path = Path(path).absolute()
    probe = path
    while not probe.exists() and probe != probe.parent:
        if probe.is_symlink():  # a dangling link: mkdir would fail on it
            raise ConfigError(f"{what} {str(path)!r} cannot be created: {probe} is a broken link")
        probe = probe.parent
    if not probe.is_dir():
        raise ConfigError(f"{what} {str(path)!r} cannot be created: {probe} is a file, not a directory")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ConfigError(f"{what} {str(path)!r} cannot be written: no permission to write in {probe}")


def make_dir(path, what: str) -> Path:
    """Create the directory ``path`` (with its parents) or raise ``ConfigError`` naming it."""
    check_writable(path, what)
    try:
        Path(path).mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ConfigError(f"{what} {str(path)!r} cannot be created: {e.strerror}") from None
    return Path(path)

def _holds_results(path: Path) -> bool:
    return path.exists() and (not path.is_dir() or any(p.name != LOCK_NAME for p in path.iterdir()))


def _resume_hint(folder: Path) -> str:
    """Advice for a folder that an earlier command left with a run that stopped before its end (a
    killed exploitability leaves ``<out>/br`` so): the run can be finished rather than started again."""
    stopped = sorted(d for d in folder.iterdir() if d.is_dir() and (d / "config.yaml").is_file() and not (d / "summary.json").exists())
    if not stopped:
        return ""
    return (f" (it holds {len(stopped)} run(s) that stopped before their end, such as {str(stopped[0])!r}: "
            f"`volleybots train resume={stopped[0]}` finishes one; choose another folder to start again)")


@contextlib.contextmanager
def output_dir(out, default, what: str = "--out"):
    """Claim a verb's output folder, hold its lock while the verb writes, and yield it.

    ``out`` (the user's, or None for ``default``) must be new or empty: checked before and again
    under the lock, so two processes writing one folder at once end with one result and one refusal
    rather than a silent overwrite. The default, time-stamped folder moves on to ``_2``, ``_3``, ...
    when taken. A verb that fails leaves no folder behind that it created."""
    explicit = out is not None
    base = Path(out if explicit else default)
    for n in itertools.count(1):
        cand = base if n == 1 else base.with_name(f"{base.name}_{n}")
        if _holds_results(cand):
            if explicit:
                raise ConfigError(f"{what} {str(cand)!r} exists and is not an empty folder; results are never overwritten"
                                  + _resume_hint(cand))
            continue
        created = not cand.exists()
        make_dir(cand, what)
        try:
            lock(cand)
        except InUseError as e:
            if explicit:
                raise ConfigError(f"{what} {str(cand)!r} is being written by another command ({e}); choose another folder") from None
            continue
        if _holds_results(cand):  # another process was first
            unlock(cand)
            if explicit:
                raise ConfigError(f"{what} {str(cand)!r} exists and is not an empty folder; results are never overwritten")
            continue
        break
    try:
        yield cand
    except BaseException:
        if created and not _holds_results(cand):
            (cand / LOCK_NAME).unlink(missing_ok=True)
            with contextlib.suppress(OSError):
                cand.rmdir()
        raise
    finally:
        unlock(cand)


def reserve_file(path, explicit: bool, what: str = "--out") -> Path:
    """Create the file ``path`` empty and exclusively (``O_EXCL``), so that two processes never pick
    the same name: the first free one of ``path``, ``<stem>_2<suffix>``, ... unless ``explicit``
    (then an existing file is refused). The caller replaces it with its result, or removes it."""
    path = Path(path)
    for n in itertools.count(1):
        cand = path if n == 1 else path.with_name(f"{path.stem}_{n}{path.suffix}")
        try:
            os.close(os.open(cand, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
            return cand
        except FileExistsError:
            if explicit:
                raise ConfigError(f"{what} {str(cand)!r} exists; choose another file (never overwritten)") from None
        except OSError as e:
            if e.errno == errno.ENAMETOOLONG:
                raise ConfigError(f"{what} {cand.name[:40]!r}... is too long for a file name ({len(cand.name)} characters); "
                                  "choose a shorter label or --out FILE") from None
            raise ConfigError(f"{what} {str(cand)!r} cannot be written: {e.strerror}") from None
    raise AssertionError("unreachable")


@contextlib.contextmanager
def memory_errors_as(what: str):
    """Turn an out-of-memory error of torch (CPU or CUDA) or Python into one ``ConfigError`` line
    naming ``what`` (the counts that asked for the memory): ``check_memory`` only knows a lower bound."""
    try:
        yield
    except (MemoryError, RuntimeError) as e:
        oom = isinstance(e, (MemoryError, torch.OutOfMemoryError)) or any(s in str(e) for s in ("can't allocate memory", "out of memory"))
        if not oom:
            raise
        raise ConfigError(f"ran out of memory with {what}; lower them ({' '.join(str(e).split())[:160]})") from None


def note(msg: str) -> None:
    """A line on stderr for what the user should know but that is no error (a run started afresh)."""
    print(f"note: {msg}", file=sys.stderr, flush=True)

