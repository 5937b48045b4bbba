"""The zoo: every shipped policy loads with ``weights_only=True``, fits its task, beats ``random`` in a
few games and is listed by ``volleybots list``; ``zoo:`` names work wherever a competitor goes."""

from __future__ import annotations

import pytest
import torch
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import ConfigError
from volleybots.zoo import PREFIX, entries

ZOO = sorted(entries())


def test_the_zoo_ships_entries_with_cards():
    assert ZOO, "the package ships no zoo entries"
    for name, e in entries().items():
        for key in ("command", "frames", "seed", "figures", "evaluation"):
            assert key in e.card, f"{name}'s card lacks {key!r}"
        assert e.checkpoint.stat().st_size < 2_000_000, f"{name} is {e.checkpoint.stat().st_size} bytes: not weights only"


@pytest.mark.parametrize("name", ZOO)
def test_every_zoo_entry_loads_weights_only_fits_its_task_and_beats_random(name):
    from volleybots.eval.crossplay import crossplay, match_config, resolve_all

    e = entries()[name]
    state = torch.load(e.checkpoint, weights_only=True)
    assert state["task"] == e.task and int(state["frames"]) == int(e.card["frames"])
    comps = resolve_all([PREFIX + name, "random"])
    cfg = match_config(comps, ["threads=1"])  # checks task, action space and observation size
    assert cfg.task.name == e.task
    res = crossplay(cfg, comps, games=16, seed=123, batch=16)
    w, d, l_ = res.wdl[0, 1].astype(int).tolist()
    # a regression guard far below the card's figure (hundreds of games on a held-out seed)
    assert w > l_, f"{name} against random: W/D/L {w}/{d}/{l_}"


def test_volleybots_list_shows_the_zoo_and_an_unknown_entry_is_one_line():
    res = CliRunner().invoke(app, ["list"])
    assert res.exit_code == 0
    for name in ZOO:
        assert PREFIX + name in res.output
    from volleybots.policies import resolve_competitor

    with pytest.raises(ConfigError, match="not in the zoo; shipped: zoo:"):
        resolve_competitor("zoo:1v1/nothing")
