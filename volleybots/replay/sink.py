"""Where a recording goes: a ``.rrd`` file written whole (``.part`` until complete) and/or a viewer."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path


def has_display() -> bool:
    import os

    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


@contextmanager
def recording(out: Path | None, app_id: str = "volleybots", viewer: bool = False):
    """A rerun ``RecordingStream`` to the file ``out`` and/or a viewer. The file is written as
    ``<out>.<pid>.part`` (two processes never share one) and moved into place when the recording is
    complete; it is removed if the recording fails, and a failed write (a full disk) is one line."""
    import os

    import rerun as rr

    from volleybots.errors import ConfigError

    rec = rr.RecordingStream(app_id)
    tmp = None if out is None else Path(out).with_name(f"{Path(out).name}.{os.getpid()}.part")
    if viewer:
        rec.spawn(connect=tmp is None)
        if tmp is not None:
            rec.set_sinks(rr.FileSink(str(tmp)), rr.GrpcSink())  # both the viewer and the file
    elif tmp is not None:
        rec.save(tmp)
    try:
        yield rec
    except BaseException:
        rec.disconnect()
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        raise
    try:
        rec.flush()
        rec.disconnect()
        if tmp is not None:
            if not tmp.is_file() or tmp.stat().st_size == 0:
                raise OSError(5, "the recording was not written (is the disk full?)")
            tmp.replace(out)
    except OSError as e:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        raise ConfigError(f"cannot write the recording {str(out)!r}: {e.strerror or e}; free space or choose another --out") from None
