"""Progress over counted items (issue 55: ``eval crossplay``, ``eval elo`` and ``bench`` show done / total and
an ETA): the line ``Count.tick`` gives, its ETA at the rate of the items that took time, never past 100 %."""

from __future__ import annotations

import pytest

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


def test_the_training_eta_follows_the_recent_rate_when_the_pace_changes():
    """A clone first drives its teacher, then itself, at another pace: the ETA is the recent batches' rate."""
    import io

    from volleybots.train.progress import RECENT, Progress

    clock = Clock()
    p = Progress(True, 10_000, 0, stream=io.StringIO(), every=3600, clock=clock)
    frames = 0
    for _ in range(RECENT + 2):  # slow: 100 frames/s
        clock.t += 1.0
        frames += 100
        p(frames, 100.0, "win", 0.0, clock.t - 100.0)
    assert p.eta(frames, 10.0) == pytest.approx((10_000 - frames) / 100)
    for _ in range(RECENT):  # then fast: 1000 frames/s; the ETA since the start would be about 3x too long
        clock.t += 0.1
        frames += 100
        p(frames, 1000.0, "win", 0.0, clock.t - 100.0)
    assert p.eta(frames, 11.0) == pytest.approx((10_000 - frames) / 1000)


def test_a_population_clone_says_it_is_the_clone_and_its_counter_ends_at_100_percent(tmp_path, capsys):
    import re

    from volleybots.config import load
    from volleybots.population.clone import make_clone

    cfg = load(["task=1v1", "env.num_envs=8", "algo.steps_per_batch=16", "algo.hidden=[16]", "algo=psro_nash", "algo.learner_init=bc",
                "algo.bc_frames=600", "evaluation.episodes=2", "evaluation.every=0", "evaluation.record=false", "checkpoint.every=0",
                "progress=true", "threads=1"])
    assert make_clone(cfg, tmp_path).name in ("best.pt", "final.pt")
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("clone: the population's first phase, a behaviour clone of the scripted team (algo=bc, "
                             "population.bc_frames=600)"), err
    counted = [re.match(r"^clone ([\d,]+)/([\d,]+) frames \(([\d.]+) %\)", line) for line in err[1:]]
    assert counted and all(counted), err
    # 600 frames in whole batches of 128 end at 640: the total says so, the share never passes 100 %
    assert {m[2] for m in counted} == {"640"} and counted[-1][1] == "640" and counted[-1][3] == "100.0"
    assert all(float(m[3]) <= 100.0 for m in counted)
