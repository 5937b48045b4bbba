"""The verbs' options as data (``volleybots.config.verbs``): each verb's ``--help`` lists every field of
its dataclass with its default and what it allows, a bad value for any verb is one line naming it and
exit code 2 with nothing written, and the defaults the dataclasses repeat from lower modules agree."""

from __future__ import annotations

import dataclasses

import pytest
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config.args import allowed, fields_of, parse, split_args
from volleybots.config.verbs import BenchOptions, CrossplayOptions, EloOptions, ExploitabilityOptions, ReplayOptions
from volleybots.errors import ConfigError

runner = CliRunner()
VERBS = [(["eval", "crossplay"], CrossplayOptions), (["eval", "elo"], EloOptions),
         (["eval", "exploitability"], ExploitabilityOptions), (["replay"], ReplayOptions), (["bench"], BenchOptions)]


def _flat(text: str) -> str:
    """The help as one line of words: rich wraps it to the terminal and frames it."""
    return " ".join(text.replace("│", " ").split())


@pytest.mark.parametrize("verb, options", VERBS, ids=[" ".join(v) for v, _ in VERBS])
def test_a_verbs_help_lists_every_field_with_its_default_and_range(verb, options):
    res = runner.invoke(app, [*verb, "--help"], terminal_width=200)
    assert res.exit_code == 0, res.output
    text = _flat(res.output)
    for key, (f, kind, _) in fields_of(options).items():
        default = f.default_factory() if f.default is dataclasses.MISSING else f.default
        shown = "unset" if default is None else str(default).lower() if isinstance(default, bool) else None
        assert f"- {key}=" in text, key
        if shown is not None:
            assert f"- {key}={shown} (" in text, key
        assert _flat(allowed(f, kind)) in text, (key, allowed(f, kind))
        assert _flat(f.metadata["help"]) in text, key


def test_the_help_shows_the_ranges_the_parser_enforces():
    text = _flat(runner.invoke(app, ["eval", "exploitability", "--help"], terminal_width=200).output)
    assert "- seeds=2 (an integer in [1, 64]):" in text
    assert "- until=budget (budget|plateau):" in text
    assert "- budget=1000000 (an integer >= 0):" in text
    with pytest.raises(ConfigError, match=r"seeds=65 is out of range: it must be an integer in \[1, 64\]"):
        split_args(["seeds=65"], ExploitabilityOptions)
    text = _flat(runner.invoke(app, ["eval", "elo", "--help"], terminal_width=200).output)
    assert "- k=168.0 (a finite number > 0):" in text and "- from=unset (text):" in text


@pytest.mark.parametrize("args, words", [
    (["eval", "crossplay", "scripted", "random", "task=1v1", "batch=0"], ["batch=0", ">= 1", "worlds played together"]),
    (["eval", "crossplay", "scripted", "random", "task=1v1", "pool=dask"], ["unknown pool 'dask'", "serial, ray"]),
    (["eval", "crossplay", "scripted", "random", "task=1v1", "deterministic=maybe"], ["deterministic='maybe'", "true or false"]),
    (["eval", "elo", "scripted", "random", "task=1v1", "orders=0"], ["orders=0", "[1, 10000]"]),
    (["eval", "elo", "scripted", "random", "task=1v1", "games=3"], ["rounds=3", "even"]),
    (["eval", "exploitability", "random", "task=1v1", "until=forever"], ["unknown until 'forever'", "budget, plateau"]),
    (["eval", "exploitability", "random", "task=1v1", "num_envs=0"], ["num_envs=0", ">= 1"]),
    (["replay", "scripted", "random", "task=1v1", "scenario=volley"], ["unknown scenario 'volley'", "any, serve, receive"]),
    (["bench", "repeats=0"], ["repeats", "0"]),
])
def test_a_bad_value_for_each_verb_is_one_line_exit_2_and_writes_nothing(tmp_path, args, words):
    out = ["--out", str(tmp_path / ("o.rrd" if args[0] == "replay" else "o"))] if args[0] != "bench" else []
    res = runner.invoke(app, [*args, *out])
    err = res.stderr.strip()
    assert res.exit_code == 2 and len(err.splitlines()) == 1 and err.startswith("error: "), res.output
    for w in words:
        assert w in err, err
    assert list(tmp_path.iterdir()) == []


def test_elo_takes_games_as_another_name_of_rounds():
    # a command line copied from eval crossplay (README: `eval elo ... games=100`) plays those games per pair
    _, opts, _ = split_args(["a", "b", "games=100"], EloOptions)
    assert (opts.games, opts.rounds, opts.given) == (100, 2000, {"games"})  # (run_elo plays games=100 rounds)


def test_a_scripts_parser_fills_lists_positionals_and_refuses_the_old_flags():
    @dataclasses.dataclass
    class Args:
        names: list[str] = dataclasses.field(default_factory=list, metadata={"positional": "+", "help": "what plays"})
        tasks: list[str] = dataclasses.field(default_factory=lambda: ["hover"], metadata={"help": "tasks"})
        games: int = dataclasses.field(default=4, metadata={"help": "games", "range": None})

    a = parse(Args, ["x", "n=PATH", "tasks=[solo_bump,3v3]", "games=8"], "t.py")
    assert (a.names, a.tasks, a.games, a.given) == (["x", "n=PATH"], ["solo_bump", "3v3"], 8, {"tasks", "games"})
    assert parse(Args, ["x"], "t.py").tasks == ["hover"]
    # an item keeps its own list: a config override in a list of them
    assert parse(BenchOptions, ["train_overrides=[algo.hidden=[64,64],algo.epochs=2]"], "b").train_overrides == [
        "algo.hidden=[64,64]", "algo.epochs=2"]
    with pytest.raises(ConfigError, match=r"'--games': options are key=value \(games=...\)"):
        parse(Args, ["x", "--games", "8"], "t.py")
    with pytest.raises(ConfigError, match="name at least one of the names"):
        parse(Args, ["games=2"], "t.py")


def test_the_defaults_the_verbs_repeat_agree_with_their_sources():
    from volleybots.algos.population import POOLS
    from volleybots.config.verbs import DEFAULT_BATCH, SCENARIOS
    from volleybots.config.verbs import POOLS as VERB_POOLS
    from volleybots.play.games import DEFAULT_BATCH as PLAY_BATCH
    from volleybots.play.games import SCENARIOS as PLAY_SCENARIOS
    from volleybots.ratings import ELO_K
    from volleybots.ratings.methods import ORDERS, ROUNDS

    elo = EloOptions()
    assert (elo.rounds, elo.k, elo.orders) == (ROUNDS, ELO_K, ORDERS)
    assert VERB_POOLS == POOLS and (DEFAULT_BATCH, SCENARIOS) == (PLAY_BATCH, PLAY_SCENARIOS)
