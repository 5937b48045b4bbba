"""One best response (population/oracle.py) for the population loop and eval exploitability, and its two stop rules."""

import json
import math

import pytest
import torch

from volleybots.population import oracle
from volleybots.population.convergence import Convergence, Plateau, StopRule

LEARNER = ["algo.hidden=[32,32]", "algo.steps_per_batch=16", "algo.minibatches=2", "algo.epochs=1"]


@pytest.mark.slow  # trains two responses and plays their games
def test_the_population_loop_and_eval_exploitability_train_a_response_through_one_object(tmp_path, monkeypatch):
    """A PSRO oracle of iteration 1 (seed 0 + 1000, against its one seed member, random, two batches) and
    exploitability's response to random (seed 1000, the same two batches): both go through
    ``BestResponse.__call__`` and end with the same weights, to the bit."""
    from volleybots.config import load
    from volleybots.eval.exploitability import run_exploitability
    from volleybots.population.run import start

    calls = []
    orig = oracle.BestResponse.__call__

    def spy(self, cfg, run, opponent, stop, *args, **kwargs):
        calls.append((type(stop).__name__, int(cfg.seed), int(cfg.total_frames), opponent.opponent.label))
        return orig(self, cfg, run, opponent, stop, *args, **kwargs)

    monkeypatch.setattr(oracle.BestResponse, "__call__", spy)
    cfg = load(["task=1v1", "population=psro_uniform", "population.start=scratch", "population.iterations=1", "population.min_updates=2",
                "population.max_updates=2", "population.payoff_games=2", "env.num_envs=16", "evaluation.episodes=2", "evaluation.every=0",
                "evaluation.record=false", "progress=false", "threads=1", "seed=0", *LEARNER])
    assert list(cfg.population.seed_members) == ["random"]
    start(cfg, tmp_path / "pop")
    _, path = run_exploitability(["random", "task=1v1", "budget=512", "num_envs=16", "seeds=1", "seed=1000", "games=2", "select_games=2",
                                  "progress=false", "threads=1", *LEARNER], tmp_path / "x")
    # one object, one call each: the loop's with its convergence rule, the verb's with the plateau rule
    assert calls == [("Convergence", 1000, 512, "population"), ("Plateau", 1000, 512, "random")]
    ours = torch.load(tmp_path / "pop" / "population" / "member_001.pt", weights_only=True)["algo"]
    theirs = torch.load(path / "br" / "checkpoints" / "final.pt", weights_only=True)["algo"]
    for part in ("actor", "critic"):
        assert ours[part].keys() == theirs[part].keys()
        assert all(torch.equal(ours[part][k], theirs[part][k]) for k in ours[part]), part
    # both runs' summaries come from the one writer (train.write_summary): the same keys every run has
    pop, br = (json.loads((d / "summary.json").read_text()) for d in (tmp_path / "pop", path / "br"))
    shared = ["task", "algo", "action_space", "num_envs", "seed", "frames", "iterations", "wall_time_s", "frames_per_s", "metric",
              "final_eval", "version"]
    assert set(shared) <= set(pop) and set(shared) <= set(br) and list(pop)[-1] == list(br)[-1] == "version"
    assert (pop["algo"], pop["frames"], pop["iterations"]) == ("psro_uniform", 512, 1)
    assert (br["algo"], br["frames"], br["seed"]) == ("mappo", 512, 1000)


def _feed(rule: StopRule, wins) -> int | None:
    """The batch (1-based) after which ``rule`` says stop, fed the training win rates ``wins``; None: never."""
    for k, w in enumerate(wins):
        if rule({"win": w}):
            return k + 1
    return None


RISING = [0.1 + 0.02 * k for k in range(40)]
FLAT = [0.6 + (0.02 if k % 2 else -0.02) for k in range(40)]
HIGH = [0.95 + (0.01 if k % 2 else -0.01) for k in range(40)]


def test_convergence_stops_at_a_settled_high_win_rate_or_at_max_updates_and_judges_after_min_updates():
    def rule(**kw):
        return Convergence(**{"min_updates": 5, "max_updates": 30, "window": 4, "mean": 0.9, "std": 0.05, **kw})

    assert _feed(rule(), HIGH) == 5  # settled above the level from the start: stops at min_updates
    assert _feed(rule(), FLAT) == 30  # settled, but below the level: max_updates
    assert _feed(rule(early=False), HIGH) == 30  # a fixed budget: never early, still judged
    r = rule()
    _feed(r, HIGH[:5])
    assert r.summary() == {"updates": 5, "converged": True, "stopped": "converged", "win_rate": pytest.approx(0.95),
                           "win_mean": pytest.approx(0.95), "win_std": pytest.approx(0.01), }
    # a batch where no episode ended says nothing about the win rate, but is an update
    r = rule()
    assert not r({"win": math.nan}) and not r({}) and r.updates == 2 and r.win_rates == []
    assert not r.judged  # fewer than min_updates: no response (the loop drops it)
    _feed(r, [0.1, 0.1, 0.1])
    assert r.judged and r.summary()["stopped"] == "budget"


def test_plateau_stops_once_the_win_rate_stops_rising_at_any_level_and_budget_never_does():
    assert _feed(Plateau(early=True, window=10), RISING) is None
    assert _feed(Plateau(early=True, window=10), FLAT) == 20  # two windows of a flat line
    assert _feed(Plateau(early=True, window=10), HIGH) == 20
    whole = Plateau(early=False, window=10)
    assert _feed(whole, FLAT) is None
    s = whole.summary()
    assert s["plateau"] is True and s["updates"] == 40 and s["batches"] == 40 and s["win_rate"] == pytest.approx(0.6)
    assert Plateau().judged and not Plateau().summary()["plateau"]  # every response it trains is one; none judged flat untrained


@pytest.mark.parametrize("make, wins", [
    (lambda: Convergence(3, 25, 4, 0.9, 0.05), HIGH[:2] + [math.nan] + HIGH[2:]),
    (lambda: Plateau(early=True, window=5), [math.nan] + FLAT),
])
def test_a_stop_rule_resumed_from_its_state_decides_as_the_whole_one(make, wins):
    """Both rules are one interface: the best response records ``state_dict()`` in a periodic checkpoint
    and loads it into a fresh rule on resume, which must then stop at the same batch with the same summary."""
    whole = make()
    stop_at = _feed(whole, wins)
    assert stop_at is not None
    cut = make()
    _feed(cut, wins[:3])
    resumed = make()
    resumed.load_state_dict(cut.state_dict())
    assert _feed(resumed, wins[3:]) == stop_at - 3
    assert resumed.summary() == whole.summary() and resumed.state_dict() == whole.state_dict()
