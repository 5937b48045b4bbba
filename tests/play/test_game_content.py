"""Game content in games and cross-play: touches per team, rally length, ending faults, serving and
receiving apart (1 vs 1, scripted against random, a few games)."""

from __future__ import annotations

import numpy as np
import pytest

from volleybots.config import load
from volleybots.eval.content import by_competitor, format_content
from volleybots.eval.crossplay import CrossPlay, crossplay
from volleybots.eval.ranking import ratings
from volleybots.play.games import play_games
from volleybots.policies import resolve_competitor
from volleybots.rules import Referee


@pytest.fixture(scope="module")
def games():
    return play_games(
        load(["task=1v1", "task.episode_len=200"]), resolve_competitor("scripted"), resolve_competitor("random"), 8, seed=0, batch=4
    )


def test_touches_and_rallies_match_the_per_game_record(games):
    c = games.content()
    assert games.touches.shape == (8, 2) and games.touches.dtype.kind == "i" and (games.touches >= 0).all()
    assert np.allclose(c["touches"], games.touches.mean(0))
    assert c["rally_touches"] == pytest.approx(games.touches.sum(1).mean())
    assert c["rally_touches_max"] == games.touches.sum(1).max()
    assert c["games_3plus_touches"] == int((games.touches.sum(1) >= 3).sum())
    assert c["rally_steps"] == pytest.approx(games.steps.mean()) and (games.steps >= 1).all()
    assert (games.steps <= 200).all()  # never past the time limit
    # the scripted player serves: it touches the ball in every game it served
    assert (games.touches[games.a_served, 0] >= 1).all()
    for s in (0, 1):
        m = games.side == s
        assert m.sum() == 4
        assert np.allclose(c["touches_per_side"][s], games.touches[m].mean(0))
        assert c["rally_steps_per_side"][s] == pytest.approx(games.steps[m].mean())


def test_serve_and_receive_split_the_totals(games):
    c = games.content()
    serve, receive = np.array(c["serve_wdl"]), np.array(c["receive_wdl"])
    assert (serve + receive).tolist() == games.total.tolist()
    assert serve.sum() == games.served and receive.sum() == 8 - games.served
    faults_a, faults_b = (sum(c["faults"][t].values()) for t in "AB")
    assert faults_b == games.total[0] and faults_a == games.total[2]  # every decided game is the loser's fault
    assert set(c["faults"]["A"]) | set(c["faults"]["B"]) <= set(Referee.FAULTS)


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_crossplay_carries_content_through_json_table_and_ratings(tmp_path):
    # random players keep it cheap; which numbers they give does not matter here, only that they travel
    comps = [resolve_competitor("random"), resolve_competitor("r1=random"), resolve_competitor("r2=random")]
    res = crossplay(load(["task=1v1", "task.episode_len=100"]), comps, 4, seed=1, batch=4)
    assert sorted(res.content) == ["0,1", "0,2", "1,2"]
    assert all(c["games"] == 4 for c in res.content.values())
    res.save(tmp_path / "cp.json")
    back = CrossPlay.load(tmp_path / "cp.json")
    assert back.content == res.content
    per = by_competitor(res.labels, res.content)
    # a competitor's serve/receive W/D/L over its two pairs add up to its row of the W/D/L matrix
    assert (np.add(per[0]["serve_wdl"], per[0]["receive_wdl"])).tolist() == res.wdl[0].sum(0).astype(int).tolist()
    # r1's touches seen from its own side: its touches as B in pair 0,1 and as A in pair 1,2
    own_vs_scripted = res.content["0,1"]["touches"][1]
    assert per[1]["touches"] == pytest.approx((own_vs_scripted + res.content["1,2"]["touches"][0]) / 2)
    rep = ratings(back, rounds=4, seed=0)
    assert rep["content"]["competitors"] == per
    assert format_content(res.labels, res.content).row_count == 3
