"""``init=`` on a population run: every learner starts from that policy (with the fine-tuning recipe),
not from the clone that ``population.start=clone`` would otherwise give it (the two together are refused)."""

import pytest

from volleybots.config import ConfigError, load
from volleybots.population.loop import ITERATION_SEED, PopulationLoop
from volleybots.train import preflight

RECEIVER = ["task=1v1", "init=zoo:1v1/ft_receiver", "algo.obs_norm=true", "env.num_envs=16", "threads=1"]


@pytest.mark.parametrize("algo, want", [("psro_nash", "scratch"), ("psro_uniform", "scratch"), ("sp", "scratch"), ("fsp", "last")])
def test_init_is_every_learners_start_where_the_start_would_clone(algo, want):
    """``algo=psro_nash init=zoo:1v1/ft_receiver`` was refused ("init= and algo.learner_init=bc both say
    where learners start") because ``algo.start=clone`` filled in the clone: so were the zoo cards'
    commands ``algo=sp init=zoo:1v1/sp`` and ``algo=psro_uniform init=zoo:1v1/bc``."""
    cfg = load([*RECEIVER, f"algo={algo}"])
    assert cfg.population.learner_init == want
    preflight(cfg)  # the checkpoint fits the learner's networks; no conflict
    # without init=: the start's (1v1: the zoo start, zoo:1v1/dag_rally; sp keeps the clone)
    assert load(["task=1v1", f"algo={algo}"]).population.learner_init == {"fsp": "last", "sp": "bc"}.get(algo, "zoo")
    if algo != "sp":
        loop = PopulationLoop.__new__(PopulationLoop)
        loop.cfg, loop.m, loop.clone = cfg, cfg.population, None
        it = loop._iteration_cfg(2, 0)
        # the learner loads init= and is held to it: the recipe's critic warm-up and KL anchor stay on
        assert (it.init, it.algo.actor_freeze_updates, it.algo.anchor_coeff) == ("zoo:1v1/ft_receiver", 10, 0.3)
        assert it.seed == cfg.seed + 2 * ITERATION_SEED  # its own seed


def test_an_explicit_clone_start_beside_init_is_still_one_refusal():
    cfg = load([*RECEIVER, "algo=psro_nash", "algo.learner_init=bc"])
    with pytest.raises(ConfigError, match=r"^init='zoo:1v1/ft_receiver' and population.learner_init=bc both say where learners start"):
        preflight(cfg)


def test_the_zoo_cards_population_commands_with_init_are_accepted():
    for overrides in (["algo=sp", "init=zoo:1v1/sp", "algo.anchor_coeff=0"],
                      ["algo=psro_uniform", "init=zoo:1v1/bc", "algo.seed_members=[zoo:1v1/bc]", "algo.anchor_coeff=0"]):
        cfg = load(["task=1v1", "env.num_envs=16", "threads=1", *overrides])
        preflight(cfg)
        assert cfg.population.learner_init == "scratch"
