"""Training curves (a run's metrics.csv) as the rerun recording ``curves.rrd``."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np


def curve_columns(rows: list[dict]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``phase/column`` -> (frames, values) over the rows where that column holds a number."""
    out: dict[str, tuple[list[int], list[float]]] = {}
    for r in rows:
        phase = r.get("phase", "train") or "train"
        for k, v in r.items():
            if k in ("frames", "phase") or not isinstance(v, float) or math.isnan(v):
                continue
            frames, values = out.setdefault(f"{phase}/{k}", ([], []))
            frames.append(int(r["frames"]))
            values.append(v)
    return {k: (np.asarray(f, dtype=np.int64), np.asarray(v, dtype=np.float64)) for k, (f, v) in out.items()}


def write_curves(metrics_csv, out_path) -> None:
    """The training curves of metrics.csv as a rerun recording: one time series per numeric column,
    on a ``frames`` timeline, each sent as one column, with a layout grouping them by quantity.
    Rebuilt whole, so it is always complete and a resumed run needs no merge."""
    import rerun as rr

    from volleybots.replay.layout import curves_blueprint
    from volleybots.replay.sink import recording
    from volleybots.runs import read_metrics

    columns = curve_columns(read_metrics(metrics_csv))
    with recording(Path(out_path), "volleybots_curves") as rec:
        for path, (frames, values) in columns.items():
            rec.send_columns(path, indexes=[rr.TimeColumn("frames", sequence=frames)], columns=rr.Scalars.columns(scalars=values))
        rec.send_blueprint(curves_blueprint(list(columns)))
