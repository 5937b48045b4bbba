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
    ``<out>.part`` and moved into place when the recording is complete (removed if it fails)."""
    import rerun as rr

    rec = rr.RecordingStream(app_id)
    tmp = None if out is None else Path(out).with_name(Path(out).name + ".part")
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
    rec.flush()
    rec.disconnect()
    if tmp is not None:
        tmp.replace(out)
