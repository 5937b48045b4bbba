"""`eval elo`'s statistics at their edges: sequential Elo does not depend on the order in which a
cross-play played a pair's games, K must be a finite step, and each competitor's exploitability
within the population is never below 0 (the CLI's normal path is tested in test_crossplay.py)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.eval.crossplay import CrossPlay
from volleybots.eval.ranking import ratings
from volleybots.ratings.solvers import member_exploitability

runner = CliRunner()


def _even_pair(outcomes: str) -> CrossPlay:
    wins, losses = outcomes.count("W"), outcomes.count("L")
    wdl = np.zeros((2, 2, 3))
    wdl[0, 1], wdl[1, 0] = (wins, 0, losses), (losses, 0, wins)
    return CrossPlay(["a", "b"], wdl, outcomes={"0,1": outcomes})


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_elo_of_played_games_does_not_depend_on_the_order_of_the_side_batches():
    # a side advantage, recorded batch by batch: a wins all 100 games on team 0, then loses all 100
    # on team 1. In play order the last batch decided Elo (a ended about 300 points below b).
    first, last = "W" * 100 + "L" * 100, "L" * 100 + "W" * 100
    ra, rb = (ratings(_even_pair(s), rounds=200, k=32, seed=0)["elo"] for s in (first, last))
    assert ra["games"] == rb["games"] == "played"
    assert ra["ratings"] == pytest.approx(rb["ratings"], abs=1e-9)
    for seed in range(3):  # and an even record rates even, whatever the seed's shuffle
        r = ratings(_even_pair(first), rounds=200, k=32, seed=seed)["elo"]["ratings"]
        assert abs(r[0] - r[1]) < 120, (seed, r)
    again = ratings(_even_pair(first), rounds=200, k=32, seed=0)["elo"]
    assert again["ratings"] == ra["ratings"] and again["trajectory"] == ra["trajectory"]  # a seed gives one answer


def test_ratings_report_profile_likelihood_intervals_even_for_an_unbeaten_pair():
    rep = ratings(_even_pair("W" * 10), rounds=10, k=32)["bradley_terry"]
    assert rep["interval"].startswith("95 % Firth")
    assert rep["high"][0] - rep["low"][0] > 300 and rep["low"][0] > 1000 > rep["high"][1]


def test_member_exploitability_includes_the_member_itself():
    # rock-paper-scissors and a fourth member that beats everyone
    a = np.array([[0, 1, -1, -1], [-1, 0, 1, -1], [1, -1, 0, -1], [1, 1, 1, 0]], dtype=float)
    ex = member_exploitability(a)
    assert ex == pytest.approx([1.0, 1.0, 1.0, 0.0])  # the dominant member: no member does better against it than itself
    others = np.array([max(a[j, i] for j in range(4) if j != i) for i in range(4)])
    assert others[3] == -1.0 and ex[3] > others[3]  # "over the others only" would say -1: not an exploitability


def _crossplay_file(tmp_path) -> str:
    path = tmp_path / "cp.json"
    _even_pair("WL" * 20).save(path)
    return str(path)


@pytest.mark.parametrize("k", ["nan", "inf", "-inf", "0", "-5"])
def test_elo_cli_refuses_a_k_that_is_not_a_finite_positive_step(tmp_path, k):
    out = tmp_path / "out"
    res = runner.invoke(app, ["eval", "elo", f"from={_crossplay_file(tmp_path)}", f"k={k}", "rounds=10", "--out", str(out)])
    assert res.exit_code == 2, res.output
    err = res.stderr.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in res.output
    assert f"k={float(k)}" in err and "finite number > 0" in err
    assert not out.exists()


def test_elo_cli_refuses_the_former_bootstrap_option(tmp_path):
    res = runner.invoke(app, ["eval", "elo", f"from={_crossplay_file(tmp_path)}", "bootstrap=100", "--out", str(tmp_path / "out")])
    assert res.exit_code == 2 and "bootstrap=" in res.stderr and "profile-likelihood" in res.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_elo_cli_from_a_file_is_finite_and_the_same_for_a_seed(tmp_path):
    src = _crossplay_file(tmp_path)
    reps = []
    for name in ("one", "two"):
        res = runner.invoke(app, ["eval", "elo", f"from={src}", "k=16", "rounds=50", "seed=3", "--out", str(tmp_path / name), "--json"])
        assert res.exit_code == 0, res.output
        reps.append(json.loads(res.stdout))
    assert reps[0]["elo"]["ratings"] == reps[1]["elo"]["ratings"]
    assert all(math.isfinite(x) for x in reps[0]["elo"]["ratings"] + reps[0]["bradley_terry"]["low"] + reps[0]["bradley_terry"]["high"])


def _table(records: dict, n: int) -> CrossPlay:
    wdl = np.zeros((n, n, 3))
    for (a, b), rec in records.items():
        wdl[a, b], wdl[b, a] = rec, rec[::-1]
    return CrossPlay([f"p{i}" for i in range(n)], wdl)


def test_elo_is_reported_with_its_spread_over_seeded_game_orders():
    """Sequential Elo at K=168 moves with the order of the games alone: three near-even players get a
    spread of a few hundred points over orders, while their mean stays near 1000; the spread is
    reproducible from the seed and shrinks with a smaller K."""
    even = _table({(0, 1): (50, 0, 50), (0, 2): (52, 0, 48), (1, 2): (49, 0, 51)}, 3)
    e = ratings(even, rounds=200, seed=0, orders=50, resamples=5)["elo"]
    assert e["orders"] == 50 and all(abs(m - 1000) < 40 for m in e["order_mean"])
    widths = np.asarray(e["order_high"]) - np.asarray(e["order_low"])
    assert (widths > 150).all(), widths  # the order alone moves each rating by more than the players differ
    assert all(lo <= r <= hi for lo, r, hi in zip(e["order_low"], e["order_mean"], e["order_high"], strict=False))
    again = ratings(even, rounds=200, seed=0, orders=50, resamples=5)["elo"]
    assert again["order_low"] == e["order_low"] and again["order_high"] == e["order_high"]
    small = ratings(even, rounds=200, k=8, seed=0, orders=50, resamples=5)["elo"]
    assert (np.asarray(small["order_high"]) - np.asarray(small["order_low"]) < widths / 3).all()


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_the_nash_weight_comes_with_how_often_each_member_carries_it_on_resampled_payoffs():
    """p0 beats p1 and p2 clearly: it carries the mixture in (nearly) every resample. A tie between p0
    and p1 (a 50/50 record) makes the weight move between them from resample to resample."""
    clear = _table({(0, 1): (80, 0, 20), (0, 2): (90, 0, 10), (1, 2): (60, 0, 40)}, 3)
    s = ratings(clear, rounds=10, resamples=100, orders=2)["nash_sensitivity"]
    assert s["carries_weight"][0] == 1.0 and s["carries_weight"][2] == 0.0 and s["resamples"] == 100
    tied = _table({(0, 1): (50, 0, 50), (0, 2): (90, 0, 10), (1, 2): (90, 0, 10)}, 3)
    s = ratings(tied, rounds=10, resamples=100, orders=2)["nash_sensitivity"]
    assert 0.2 < s["mean_weight"][0] < 0.8 and s["carries_weight"][0] > 0.3 and s["carries_weight"][1] > 0.3


def test_draw_rates_stand_beside_bradley_terry_on_decisive_games():
    rep = ratings(_table({(0, 1): (10, 80, 10), (0, 2): (50, 0, 50), (1, 2): (0, 100, 0)}, 3), rounds=10, orders=2, resamples=5)
    assert rep["draw_rate"] == pytest.approx([80 / 200, 180 / 200, 100 / 200])
    assert rep["bradley_terry"]["draws"].startswith("left out")


def test_a_rating_registered_in_the_registry_appears_in_the_table_the_json_and_the_plot(tmp_path, monkeypatch):
    """`eval elo` knows no rating method by name: one added to RATINGS is computed, tabled, titled and
    drawn with no edit to the verb."""
    from volleybots.ratings.methods import RATINGS, Rating

    drawn = []

    def points(games):  # a toy rating: each competitor's total points, a draw half a win
        return {"toy_points": (np.asarray(games.wdl, float) @ [1.0, 0.5, 0.0]).sum(1).tolist()}

    toy = Rating(rate=points, columns=("toypts",), cells=lambda report, i: (f"{report['toy_points'][i]:.1f}",),
                 title=lambda report: "toypts by points", plot=lambda report, ax, x: drawn.append(list(x)))
    monkeypatch.setitem(RATINGS, "toy", toy)
    src = _crossplay_file(tmp_path)  # a and b, 20 wins each
    res = runner.invoke(app, ["eval", "elo", f"from={src}", "rounds=10", "orders=2", "--out", str(tmp_path / "t")], terminal_width=400)
    assert res.exit_code == 0, res.output
    assert "toypts" in res.stdout and "toypts by points" in res.stdout and "20.0" in res.stdout
    assert json.loads((tmp_path / "t" / "ratings.json").read_text())["toy_points"] == [20.0, 20.0]
    assert drawn == [[0, 1]] and (tmp_path / "t" / "ratings.png").is_file()
    clash = Rating(rate=lambda games: {"elo": 0}, columns=(), cells=lambda report, i: ())
    monkeypatch.setitem(RATINGS, "clash", clash)
    with pytest.raises(ValueError, match="'clash' writes \\['elo'\\]"):
        ratings(_even_pair("WL"), rounds=2, orders=1, resamples=1)
