"""What a run shows while it trains (``progress=true``).

In a terminal: a rich progress bar (frames, elapsed time, ETA, frames/s, the task metric of the last
finished episodes). Without one (a log file, ``nohup``, a batch job) a bar prints nothing useful, so
a plain line goes to stderr instead, after the first batch and then at most every ``every`` seconds
(a batch of a minute or more gets a line of its own)::

    train 32,768/1,000,000 frames (3.3 %)  2,905 frames/s  elapsed 0:00:11  ETA 0:05:33  win 0.42  | iteration 2/5, oracle update 4/300

The ETA is the remaining frames over the rate of the last ``RECENT`` batches (since this loop started
until there are two), or the time left to ``time_limit`` if that comes first: a run whose rate changes
(the population's clone: first its teacher plays, then the clone itself) would otherwise be told an ETA
off one way, then the other. The total is the frames the loop will reach: it trains whole batches, so a
budget that is no multiple of a batch ends past it, and the counter would pass 100 %. A caller may add
a note after ``|`` (the population loop: its iteration and the oracle's updates) and name its phase in
place of ``train`` (``label``: a population's clone says ``clone``).
"""

from __future__ import annotations

import math
import sys
import time
from collections import deque

PLAIN_EVERY_S = 10.0  # at most one plain line per this many seconds: enough to follow, few enough to read
RECENT = 8  # batches whose rate gives the ETA: recent enough to follow a change of pace, enough to smooth one slow batch


def note(progress: bool):
    """A one-line writer to stderr where ``progress`` is on (a run's phases: stage I, stage III), else None."""
    return (lambda line: print(line, file=sys.stderr, flush=True)) if progress else None


def hms(seconds: float) -> str:
    if seconds is None or not math.isfinite(seconds):
        return "-"
    s = int(round(max(seconds, 0.0)))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"


class Progress:
    """A context manager; calling it after each batch with (frames, frames/s, metric name, value, wall
    time, note) shows the run's state."""

    def __init__(self, enabled: bool, total: int, start: int, time_limit: float = 0.0, label: str = "train",
                 stream=None, every: float = PLAIN_EVERY_S, clock=time.perf_counter):
        self.enabled, self.total, self.start, self.time_limit, self.label = enabled, total, start, time_limit, label
        self.stream = stream if stream is not None else sys.stderr
        self.every, self.clock = every, clock
        self.plain = enabled and not _is_tty(self.stream)
        self._t0 = clock()
        self._last_line = -math.inf
        self._recent: deque = deque(maxlen=RECENT + 1)  # (time, frames) after each of the last batches

    def eta(self, frames: int, wall: float) -> float:
        now = self.clock()
        if len(self._recent) >= 2:
            (t_old, f_old), (t_new, f_new) = self._recent[0], self._recent[-1]
            rate = (f_new - f_old) / max(t_new - t_old, 1e-9)
        else:
            rate = (frames - self.start) / max(now - self._t0, 1e-9)
        eta = (self.total - frames) / rate if rate > 0 else math.inf
        if self.time_limit:
            eta = min(eta, self.time_limit - wall)
        return max(eta, 0.0)

    def line(self, frames: int, fps: float, metric: str, value, wall: float, note: str = "") -> str:
        shown = "-" if value is None or math.isnan(value) else f"{value:.3g}"
        pct = 100.0 * frames / self.total if self.total else 100.0
        text = (f"{self.label} {frames:,}/{self.total:,} frames ({pct:.1f} %)  {fps:,.0f} frames/s  "
                f"elapsed {hms(wall)}  ETA {hms(self.eta(frames, wall))}  {metric} {shown}")
        return f"{text}  | {note}" if note else text

    def __enter__(self):
        if self.enabled and not self.plain:
            from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn, TimeRemainingColumn
            from rich.progress import Progress as Bar

            self.bar = Bar(
                TextColumn(f"[bold]{self.label}"), BarColumn(), MofNCompleteColumn(), TextColumn("frames"),
                TimeElapsedColumn(), TimeRemainingColumn(), TextColumn("{task.fields[info]}"),
            )
            self.bar.__enter__()
            self.task = self.bar.add_task(self.label, total=self.total, completed=self.start, info="")
        return self

    def __call__(self, frames: int, fps: float, metric: str, value, wall: float, note: str = "") -> None:
        if not self.enabled:
            return
        self._recent.append((self.clock(), frames))
        if self.plain:
            now = self.clock()
            if now - self._last_line >= self.every or frames >= self.total:
                self._last_line = now
                print(self.line(frames, fps, metric, value, wall, note), file=self.stream, flush=True)
            return
        shown = "-" if value is None or math.isnan(value) else f"{value:.3g}"
        info = f"{fps:,.0f} frames/s  {metric} {shown}" + (f"  {note}" if note else "")
        self.bar.update(self.task, completed=min(frames, self.total), info=info)

    def __exit__(self, *exc):
        if self.enabled and not self.plain:
            self.bar.__exit__(*exc)
        return False


def _is_tty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


class Count:
    """Progress over a known number of items (cross-play's pairs, bench's rows): ``begin(total)``, then
    ``tick()`` after each item returns ``"3/10 pairs (30 %), elapsed 0:00:12, ETA 0:00:28"`` for the
    caller's line (one line per item reads well in a terminal and in a log alike, unlike a bar).

    The ETA is the items left at the rate of the items that took time so far: an item copied from an
    earlier result (``tick(timed=False)``, cross-play's ``reuse=``) costs nothing and would make it too
    short. Before ``begin`` (a caller that does not announce its total) ``tick`` says "done N"."""

    def __init__(self, what: str, clock=time.perf_counter):
        self.what, self.clock = what, clock
        self.total: int | None = None
        self.done = self.timed = 0
        self.spent = 0.0
        self._last = clock()

    def begin(self, total: int) -> None:
        self.total, self.done, self.timed, self.spent = int(total), 0, 0, 0.0
        self._t0 = self._last = self.clock()

    def tick(self, timed: bool = True) -> str:
        now = self.clock()
        self.done += 1
        if timed:
            self.timed += 1
            self.spent += now - self._last
        self._last = now
        if self.total is None:
            return f"done {self.done} {self.what}"
        left = max(self.total - self.done, 0)
        eta = self.spent / self.timed * left if self.timed else (0.0 if not left else math.inf)
        pct = min(100.0 * self.done / self.total, 100.0) if self.total else 100.0
        return f"{self.done}/{self.total} {self.what} ({pct:.0f} %), elapsed {hms(now - self._t0)}, ETA {hms(eta)}"
