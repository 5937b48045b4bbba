"""The learned high level of the hierarchical 3v3 team (volleybots/policies/high_level.py,
volleybots/train/high_level.py): the chooser seam of the rule-based high level, the features, legal
options, the update that moves choices toward what won, the saved file, and a team file with a
learned high level playing games."""

import pytest
import torch
import yaml

from volleybots.config import ConfigError, load
from volleybots.play.games import play_games
from volleybots.policies import resolve_competitor
from volleybots.policies.high_level import HighLevelNet, LearnedChooser, chooser_from_file, load_high_level, save_high_level
from volleybots.scripted.hierarchical import ATTACK, CHOICES, FEATURES, HOVER, PASS, SET, HighLevel, features
from volleybots.tasks.drills import BACK, FRONT_LEFT, FRONT_RIGHT
from volleybots.train.high_level import HighLevelConfig, train_high_level, update

N = 16
ALL = torch.ones(N, dtype=torch.bool)


def preferring(kind: str, option: int) -> HighLevelNet:
    """A net whose ``kind`` head puts nearly all weight on ``option`` (zero hidden-to-logit weights)."""
    net = HighLevelNet((8,))
    with torch.no_grad():
        net.heads[kind][-1].bias.zero_()
        net.heads[kind][-1].bias[option] = 20.0
    return net


def test_a_learned_chooser_decides_who_receives_and_respects_legal_options():
    h = HighLevel(N, "cpu", chooser=LearnedChooser(preferring("receive", FRONT_LEFT), greedy=True))
    h.on_opponent_hit(ALL)
    assert (h.drill[:, FRONT_LEFT] == PASS).all() and (h.drill[:, [FRONT_RIGHT, BACK]] == HOVER).all()
    # a set head that prefers the drone that just passed: that option is illegal, so another sets
    h = HighLevel(N, "cpu", chooser=LearnedChooser(preferring("set", FRONT_LEFT), greedy=False, generator=torch.Generator().manual_seed(0)))
    h.on_opponent_hit(ALL)  # the rules' chooser is not used here: the learned receive head is uniform at start
    h.touched[:] = False
    h.on_own_touch(ALL, torch.full((N,), FRONT_LEFT))
    assert (h.drill[:, FRONT_LEFT] == HOVER).all()
    assert ((h.drill == SET).sum(1) == 1).all()
    # an attack head preferring (back, right): legal after front-left passed and front-right set
    h = HighLevel(N, "cpu", chooser=LearnedChooser(preferring("attack", BACK * 2 + 1), greedy=True))
    h.on_own_touch(ALL, torch.full((N,), FRONT_LEFT))
    h.on_own_touch(ALL, torch.full((N,), FRONT_RIGHT))
    assert (h.drill[:, BACK] == ATTACK).all() and (h.side == 1).all()


def test_features_see_where_the_ball_comes_down():
    pos = torch.tensor(((3.0, -1.5, 2.0), (3.0, 1.5, 2.0), (6.0, 0.0, 2.0))).expand(N, 3, 3)
    ball = torch.tensor((4.0, 1.0, 5.0))
    parts = {"root": torch.cat((pos, torch.zeros(N, 3, 20)), -1), "ball": (ball - pos), "ball_vel": torch.zeros(N, 3, 3),
             "positions": torch.cat((pos, -pos), 1).flatten(1).unsqueeze(1).expand(N, 3, 18)}
    f = features(parts, torch.zeros(N, 3, dtype=torch.bool))
    assert f.shape == (N, FEATURES)
    # dropped from rest at 5 m: it comes down through the contact height right below, in sqrt(2 h / g) s
    assert torch.allclose(f[:, 6:8] * 6.0, torch.tensor((4.0, 1.0)).expand(N, 2), atol=1e-5)
    assert float(f[0, 8]) == pytest.approx((2 * (5.0 - 2.75) / 9.81) ** 0.5, abs=1e-4)


def test_the_update_moves_choices_toward_what_won():
    torch.manual_seed(0)
    net = HighLevelNet((16,))
    opt = torch.optim.Adam(net.parameters(), lr=1e-2)
    chooser = LearnedChooser(net, record=True, generator=torch.Generator().manual_seed(1))
    feats, legal = torch.zeros(64, FEATURES), torch.ones(64, CHOICES["receive"], dtype=torch.bool)
    before = net.logits("receive", feats[:1], legal[:1]).softmax(-1)[0, FRONT_RIGHT].detach()
    for _ in range(20):
        chooser.memory.clear()
        pick = chooser("receive", feats, legal, torch.ones(64, dtype=torch.bool))
        results = torch.where(pick == FRONT_RIGHT, 1.0, -1.0)  # env k's game paid to its choice
        update(net, opt, chooser, results, HighLevelConfig(epochs=2))
    after = net.logits("receive", feats[:1], legal[:1]).softmax(-1)[0, FRONT_RIGHT].detach()
    assert float(before) == pytest.approx(1 / 3, abs=1e-6)
    assert float(after) > 0.8


def test_a_high_level_file_round_trips_and_a_damaged_one_is_refused(tmp_path):
    net = preferring("set", BACK)
    save_high_level(net, tmp_path / "h.pt", {"games": 3})
    back = load_high_level(tmp_path / "h.pt")
    x = torch.randn(5, FEATURES)
    ok = torch.ones(5, 3, dtype=torch.bool)
    assert torch.equal(back.logits("set", x, ok), net.logits("set", x, ok))
    assert torch.load(tmp_path / "h.pt", weights_only=True)["info"] == {"games": 3}
    assert chooser_from_file(tmp_path / "h.pt").receive_coming is False  # the rules' event, unless trained otherwise
    save_high_level(net, tmp_path / "c.pt", {"receive_coming": True})
    assert chooser_from_file(tmp_path / "c.pt").receive_coming is True
    (tmp_path / "bad.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(ConfigError, match="damaged or no learned high level"):
        load_high_level(tmp_path / "bad.pt")
    with pytest.raises(ConfigError, match="is a folder, not a file"):  # the bounded read of volleybots.files
        load_high_level(tmp_path)
    torch.save({"format": "volleybots-high-level/1", "hidden": [8], "state_dict": {}}, tmp_path / "empty.pt")
    with pytest.raises(ConfigError, match="do not fit"):
        load_high_level(tmp_path / "empty.pt")


@pytest.mark.slow
def test_training_plays_games_and_a_team_file_with_its_high_level_plays(tmp_path):
    cfg = load(["task=3v3"])
    net, history = train_high_level(cfg, None, "scripted", HighLevelConfig(games=8, batch=4, seed=3))
    assert [r["games"] for r in history] == [4, 8] and [r["side"] for r in history] == [0, 1]
    assert all(r["won"] + r["drawn"] + r["lost"] == 4 for r in history)
    assert sum(r["choices"] for r in history) > 0  # the opponents hit balls the team had to receive
    save_high_level(net, tmp_path / "high_level.pt")
    (tmp_path / "team.yaml").write_text(yaml.safe_dump({"hierarchical": {"high_level": "high_level.pt"}}))
    comp = resolve_competitor(f"hcsp={tmp_path / 'team.yaml'}")
    assert comp.members[0].source["drill_files"]["high_level"]["sha256"]
    g = play_games(cfg, comp, resolve_competitor("random"), 4, seed=5)
    assert g.games == 4 and g.total[2] == 0  # random never wins a game against the team's serve and drills
    (tmp_path / "typo.yaml").write_text(yaml.safe_dump({"hierarchical": {"high_levle": "high_level.pt"}}))
    with pytest.raises(ConfigError, match="allowed: hover, serve, pass, set, attack, high_level"):
        resolve_competitor(str(tmp_path / "typo.yaml"))
