"""Progress over counted items (issue 55: ``eval crossplay``, ``eval elo`` and ``bench`` show done / total and
an ETA): the line ``Count.tick`` gives, its ETA at the rate of the items that took time, never past 100 %."""

from __future__ import annotations

from volleybots.train.progress import Count


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_count_gives_done_total_elapsed_and_an_eta_at_the_rate_of_the_timed_items():
    clock = Clock()
    c = Count("pairs", clock=clock)
    c.begin(4)
    clock.t += 10.0
    assert c.tick() == "1/4 pairs (25 %), elapsed 0:00:10, ETA 0:00:30"
    clock.t += 0.01  # a pair copied from an earlier file (reuse=): its no-time does not shorten the ETA
    assert c.tick(timed=False) == "2/4 pairs (50 %), elapsed 0:00:10, ETA 0:00:20"
    clock.t += 30.0
    assert c.tick() == "3/4 pairs (75 %), elapsed 0:00:40, ETA 0:00:20"
    clock.t += 20.0
    assert c.tick() == "4/4 pairs (100 %), elapsed 0:01:00, ETA 0:00:00"
    assert c.tick().startswith("5/4 pairs (100 %)")  # a caller that miscounts: the share stays at 100 %


def test_count_without_a_total_or_with_only_copied_items():
    clock = Clock()
    c = Count("rows", clock=clock)
    assert c.tick() == "done 1 rows"
    c.begin(2)
    assert c.tick(timed=False) == "1/2 rows (50 %), elapsed 0:00:00, ETA -"  # nothing timed yet: no rate to tell
    assert c.tick(timed=False) == "2/2 rows (100 %), elapsed 0:00:00, ETA 0:00:00"
