"""A hierarchical oracle's games played by Ray actors train the same high level as played here in turn
(``population.oracle_pool=ray``, volleybots/train/high_level.py ``ChunkPlayer``), and a hierarchical
population run (member files naming drills relative to the run's population folder, the run dir itself
relative) gives the same members and payoff table with both pools on Ray as with both serial."""

from __future__ import annotations

import json

import pytest
import torch

from volleybots.config import ConfigError, load
from volleybots.policies.competitors import Competitor, builtin_member
from volleybots.train import high_level
from volleybots.train.high_level import HighLevelConfig, chunk_seed, train_high_level


def _timeless(history: list[dict]) -> list[dict]:
    """A history without its wall times (the one thing a pool changes)."""
    return [{k: v for k, v in row.items() if k != "wall_s"} for row in history]


@pytest.fixture
def local_ray(monkeypatch):
    ray = pytest.importorskip("ray", reason="ray comes with the cluster extra of the test install")
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


def test_chunk_seeds_differ_by_run_and_chunk_and_fit_a_generator():
    seeds = {chunk_seed(s, c) for s in (0, 1, 2**63 - 1) for c in range(1, 9)}
    assert len(seeds) == 24 and max(seeds) < 2**61
    assert chunk_seed(5, 2) == chunk_seed(5, 2)  # a function of the two alone


@pytest.mark.slow  # plays 3v3 games, on a local Ray instance too
def test_oracle_games_played_as_ray_tasks_train_the_same_high_level(local_ray, monkeypatch):
    cfg = load(["task=3v3", "threads=1", "task.episode_len=150"])  # short games: drawn where no point is won by then
    # a mixture opponent, so the chunks' generators also draw members
    mix = Competitor("mix", [builtin_member("scripted"), builtin_member("hierarchical")], [0.5, 0.5])

    class Counted(high_level.ChunkPlayer):  # pickled by value: a Ray actor counts into its own copy of plays
        plays: list = []

        def play(self, state, side):
            Counted.plays.append(side)
            return super().play(state, side)

    monkeypatch.setattr(high_level, "ChunkPlayer", Counted)
    tiny = dict(games=12, batch=6, chunks=2, seed=7, epochs=2)  # two batches (one a side) of two chunks each
    net_s, hist_s = train_high_level(cfg, None, mix, HighLevelConfig(**tiny))
    assert Counted.plays == [0, 0, 1, 1]
    net_r, hist_r = train_high_level(cfg, None, mix, HighLevelConfig(**tiny, pool="ray"))
    assert Counted.plays == [0, 0, 1, 1]  # no chunk of the Ray run was played in this process
    a, b = net_s.state_dict(), net_r.state_dict()
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    assert _timeless(hist_s) == _timeless(hist_r)
    assert [r["games"] for r in hist_s] == [6, 12] and [r["side"] for r in hist_s] == [0, 1]
    assert all(r["won"] + r["drawn"] + r["lost"] == 6 for r in hist_s) and sum(r["choices"] for r in hist_s) > 0
    # the trained net moved from its start: the update saw the joined chunks' choices
    torch.manual_seed(7)
    start = high_level.HighLevelNet(HighLevelConfig().hidden).state_dict()
    assert any(not torch.equal(start[k], a[k]) for k in a)


@pytest.mark.slow  # trains a tiny 3v3 population twice
def test_a_hierarchical_population_on_ray_pools_equals_the_serial_one(local_ray, tmp_path, monkeypatch):
    from volleybots.population.run import start

    monkeypatch.chdir(tmp_path)  # relative run dirs: members name their drills relative to population/
    tiny = ["task=3v3", "algo=psro_nash", "algo.fixed_opponents=[]", "algo.iterations=1", "algo.high_level_games=8",
            "algo.high_level_batch=8", "algo.oracle_chunks=2", "algo.payoff_games=4", "task.episode_len=150", "evaluation.episodes=2",
            "evaluation.record=false", "progress=false", "threads=1", "seed=3"]
    start(load(tiny), "serial")
    start(load([*tiny, "algo.oracle_pool=ray", "algo.payoff_pool=ray"]), "ray")
    pop_s, pop_r = tmp_path / "serial" / "population", tmp_path / "ray" / "population"
    assert json.loads((pop_s / "payoffs.json").read_text()) == json.loads((pop_r / "payoffs.json").read_text())
    for k in range(2):
        a, b = (torch.load(p / f"member_{k:03d}.pt", weights_only=True) for p in (pop_s, pop_r))
        assert a == b and not any(v.startswith("/") for v in a["drills"].values())
        ha, hb = (torch.load(p / f"high_level_{k:03d}.pt", weights_only=True)["state_dict"] for p in (pop_s, pop_r))
        assert ha.keys() == hb.keys() and all(torch.equal(ha[n], hb[n]) for n in ha)
    table = json.loads((pop_s / "payoffs.json").read_text())
    assert table["members"] == ["zoo:3v3/hcsp_return", "br1"] and table["games"][1][0] == 4


def test_an_oracle_pool_is_refused_where_it_would_do_nothing_or_is_unknown():
    assert load(["task=3v3", "algo=psro_nash", "algo.oracle_pool=ray", "algo.oracle_chunks=4"]).population.oracle_chunks == 4
    with pytest.raises(ConfigError, match="unknown population.oracle_pool 'dask'"):
        load(["task=3v3", "algo=psro_nash", "algo.oracle_pool=dask"])
    with pytest.raises(ConfigError, match="population.oracle_pool / oracle_chunks play hierarchical oracles' games; a flat member"):
        load(["task=1v1", "algo=psro_nash", "algo.oracle_pool=ray"])
    with pytest.raises(ConfigError, match="population.oracle_chunks=300 must be at most population.high_level_batch=256"):
        load(["task=3v3", "algo=psro_nash", "algo.oracle_chunks=300"])
    with pytest.raises(ConfigError, match="high level chunks=5 must be at most batch=4"):
        HighLevelConfig(batch=4, chunks=5).check()


def test_a_resume_may_move_the_games_to_ray_and_change_nothing_else(tmp_path):
    from volleybots.population.loop import RESUME_KEYS
    from volleybots.runs import RunDir
    from volleybots.train import resume_config

    run = RunDir(tmp_path)
    run.write_config(load(["task=3v3", "algo=psro_nash"]))
    cfg = resume_config(tmp_path, ["population.oracle_pool=ray", "population.payoff_pool=ray"], RESUME_KEYS)
    assert (cfg.population.oracle_pool, cfg.population.payoff_pool, cfg.population.oracle_chunks) == ("ray", "ray", 1)
    with pytest.raises(ConfigError, match="population.oracle_chunks"):  # the chunks make the games: not a resume's to change
        resume_config(tmp_path, ["population.oracle_chunks=2"], RESUME_KEYS)


@pytest.mark.slow  # plays 3v3 games
def test_one_chunk_plays_the_games_of_before_chunks():
    """The figures the code before chunks gave for this run (commit 18973be), so one
    chunk keeps the headline's high levels: a tiny self-play high level, seed 5."""
    cfg = load(["task=3v3", "threads=1", "task.episode_len=150"])
    _, hist = train_high_level(cfg, None, None, HighLevelConfig(games=8, batch=4, seed=5, epochs=2))
    assert [(r["won"], r["drawn"], r["lost"], r["frames"], r["choices"]) for r in hist] == [(1, 0, 3, 455, 6), (4, 0, 0, 416, 1)]
    assert [r.get("share_receive") for r in hist] == [[1, 1, 2], [0, 0, 1]]
