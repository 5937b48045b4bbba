"""Training without a terminal: plain progress lines, time_limit kept without a whole batch's overshoot,
and a population run's progress, final evaluation, curves and wall-time split."""

from __future__ import annotations

import io
import re

import pytest

from volleybots.config import load
from volleybots.population.run import start
from volleybots.runs import read_metrics
from volleybots.train import train
from volleybots.train.progress import Progress, hms

LINE = re.compile(
    r"^train ([\d,]+)/([\d,]+) frames \(([\d.]+) %\)  ([\d,]+) frames/s  "
    r"elapsed (\d+:\d\d:\d\d)  ETA (\d+:\d\d:\d\d|-)  win (\S+)( {2}\| .*)?$"
)
TINY = ["task=1v1", "env.num_envs=16", "algo.steps_per_batch=16", "algo.minibatches=1", "algo.epochs=1", "algo.hidden=[32]",
        "threads=1", "evaluation.every=0", "evaluation.episodes=2", "evaluation.record=false", "checkpoint.every=0"]


def test_plain_lines_without_a_terminal_at_most_every_interval():
    out = io.StringIO()  # not a TTY
    with Progress(True, 1000, 0, stream=out, every=3600) as bar:
        assert bar.plain
        bar(100, 50.0, "win", 0.25, 2.0)
        bar(200, 50.0, "win", float("nan"), 4.0)  # within the interval: no line
        bar(1000, 50.0, "win", 0.5, 20.0, note="iteration 1/2")  # the end always shows
    lines = out.getvalue().splitlines()
    assert len(lines) == 2
    m = LINE.match(lines[0])
    assert m and m.group(1) == "100" and m.group(3) == "10.0" and m.group(7) == "0.25"
    assert LINE.match(lines[1]).group(8) == "  | iteration 1/2" and "ETA 0:00:00" in lines[1]
    assert hms(3725) == "1:02:05" and hms(float("inf")) == "-"
    quiet = io.StringIO()
    with Progress(False, 1000, 0, stream=quiet) as bar:
        bar(100, 50.0, "win", 0.25, 2.0)
    assert quiet.getvalue() == ""


def test_eta_follows_the_time_limit_when_it_comes_first():
    p = Progress(True, 10**9, 0, time_limit=60.0, stream=io.StringIO())
    assert p.eta(1000, 15.0) <= 45.0


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_a_time_limited_run_prints_lines_and_stops_before_a_batch_would_overshoot(tmp_path, capsys):
    limit = 4.0
    cfg = load([*TINY, "algo=mappo", "opponent=random", "total_frames=100000000", f"time_limit={limit}", "progress=true"])
    train(cfg, tmp_path / "run")
    err = capsys.readouterr().err.splitlines()
    lines = [ln for ln in err if ln.startswith("train ")]
    assert lines and all(LINE.match(ln) for ln in lines), err
    rows = [r for r in read_metrics(tmp_path / "run" / "metrics.csv") if r["phase"] == "train"]
    dts = [256 / r["fps"] for r in rows]  # 16 envs x 16 steps a batch
    assert rows[-1]["wall_time"] <= limit + max(dts)
    assert rows[-1]["wall_time"] + dts[-1] + 0.5 > limit  # and it did not stop far too early


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_a_population_run_reports_progress_final_eval_curves_and_its_wall_time_split(tmp_path, capsys):
    cfg = load([*TINY, "algo=psro_uniform", "algo.start=scratch",
                "algo.iterations=1", "algo.min_updates=2", "algo.max_updates=2", "algo.payoff_games=2",
                "total_frames=100000", "progress=true"])
    summary = start(cfg, tmp_path / "pop")
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("train ")]
    assert lines and all(LINE.match(ln) for ln in lines)
    assert re.search(r"\| iteration 1/1, oracle update [12]/2, run ETA \d+:\d\d:\d\d$", lines[-1]), lines[-1]
    ev = summary["final_eval"]
    assert ev["episodes"] == 2 and ev["opponent"] == "random" and sum(ev["wdl"]) == 2
    assert ev["stats"]["win"]["mean"] == ev["wdl"][0] / 2
    assert ev["content"]["games"] == 2
    split = summary["wall_time_split"]
    assert set(split) == {"clone", "drills", "oracle_training", "payoff_games", "evaluations", "other"} and split["clone"] == 0
    assert all(v >= 0 for v in split.values()) and split["oracle_training"] > 0 and split["payoff_games"] > 0 and split["evaluations"] > 0
    assert abs(sum(split.values()) - summary["wall_time_s"]) < 0.05
    assert (tmp_path / "pop" / "curves.rrd").stat().st_size > 0
    last = read_metrics(tmp_path / "pop" / "metrics.csv")[-1]
    assert last["phase"] == "eval" and last["eval_win"] == ev["stats"]["win"]["mean"]


def test_an_oracle_stops_early_enough_for_its_payoff_games_to_end_by_the_time_limit():
    from types import SimpleNamespace

    from volleybots.population.loop import PopulationLoop
    from volleybots.ratings.payoffs import payoff_reserve

    assert payoff_reserve(0.0, 1) == 0.0  # no pair played yet: nothing to estimate from
    assert payoff_reserve(30.0, 3) == 30.0  # 3 pairs took 30 s: the 3 pairs of a fourth member take 30 s more
    assert payoff_reserve(12.0, 4) == 8.0  # 6 pairs in 12 s: 2 s a pair, 4 new pairs
    # iteration i's learner gets the run's time limit less the reserve; without a limit nothing changes
    for limit, want in ((100.0, 80.0), (0.0, 0.0)):
        cfg = load([*TINY, "algo=psro_nash", "algo.start=scratch", f"time_limit={limit}"])
        loop = SimpleNamespace(cfg=cfg, m=cfg.population, clone=None)
        assert PopulationLoop._iteration_cfg(loop, 2, 0, reserve=20.0).time_limit == want
        assert PopulationLoop._iteration_cfg(loop, 2, 0).time_limit == limit
