"""metrics.csv: one row per training batch and per evaluation, and the training curves recorded from it."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from volleybots.errors import ConfigError
from volleybots.files import read_text


class MetricsLog:
    """metrics.csv: the header is the first row's keys; a resumed run drops the rows after its checkpoint."""

    def __init__(self, path: Path, keep_until_frames: int | None = None):
        self.path = Path(path)
        self.fields: list[str] | None = None
        if keep_until_frames is not None and self.path.is_file():
            with self.path.open(newline="") as f:
                reader = csv.DictReader(f)
                self.fields = list(reader.fieldnames or [])
                # a row cut short by a kill has no number in frames (RunDir.check_metrics allows it last)
                rows = [r for r in reader if _is_number(r["frames"]) and float(r["frames"]) <= keep_until_frames]
            with self.path.open("w", newline="") as f:
                w = csv.DictWriter(f, self.fields)
                w.writeheader()
                w.writerows(rows)

    def write(self, row: dict) -> None:
        new = self.fields is None
        if new:
            self.fields = list(row)
        with self.path.open("a" if not new else "x", newline="") as f:
            w = csv.DictWriter(f, self.fields, extrasaction="ignore")
            if new:
                w.writeheader()
            w.writerow({k: _fmt(row.get(k)) for k in self.fields})


def _fmt(v):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    if isinstance(v, float):
        return f"{v:.6g}"
    return v


def read_metrics(path) -> list[dict[str, float | str]]:
    """The rows of metrics.csv, numbers as floats; a file that is not such a table (binary, damaged,
    no ``frames`` column) is one ``ConfigError`` line naming it."""
    out = []
    # bounded like every file read (a received 3 GB metrics.csv is refused at once, not parsed for minutes)
    text = read_text(path, "metrics.csv")
    try:
        for r in csv.DictReader(io.StringIO(text, newline="")):
            out.append({k: (float(v) if _is_number(v) else v) for k, v in r.items()})
    except csv.Error as e:
        raise ConfigError(f"{path} is damaged ({type(e).__name__}: {' '.join(str(e).split())[:120]})") from None
    if out and "frames" not in out[0]:
        raise ConfigError(f"{path} is damaged (no 'frames' column in the header)")
    return out


def wall_at(path, frames: int) -> float:
    """The run's wall time when it had trained ``frames`` frames: the last ``wall_time`` of metrics.csv's
    rows up to them (0.0 without any). A resume continues its clock from here, since a checkpoint holds
    no wall time (its bytes depend on the training alone: two identical runs write equal files)."""
    path = Path(path)
    if not path.is_file():
        return 0.0
    walls = [float(r["wall_time"]) for r in read_metrics(path)
             if isinstance(r.get("frames"), float) and r["frames"] <= frames and isinstance(r.get("wall_time"), float)]
    return max(walls, default=0.0)


def _is_number(v) -> bool:
    try:
        float(v)
    except (TypeError, ValueError):
        return False
    return True
