"""Results files checked as a whole before use, never silently wrong (issue 49): a tampered ``reuse=`` or
payoff table is refused, ``from=`` refuses options that only play, the game fingerprint covers the config
tree, a population member replaced by another policy is caught by its recorded checksum, a run whose
config.yaml is a folder is reported failed, and Nash's tie-break does not depend on the members' order."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import torch
from conftest import one_line_exit_2, snapshot
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import ConfigError
from volleybots.population.solvers import nash

runner = CliRunner()
PAIR = ["random", "scripted", "task=1v1", "task.episode_len=20", "games=2", "batch=2"]


@pytest.fixture(scope="module")
def played(tmp_path_factory):
    out = tmp_path_factory.mktemp("cp") / "o"
    res = runner.invoke(app, ["eval", "crossplay", *PAIR, "--json", "--out", str(out)])
    assert res.exit_code == 0, res.output
    return json.loads((out / "crossplay.json").read_text())


@pytest.fixture
def no_games(monkeypatch):
    def play(*a, **k):
        raise AssertionError("a game was played")

    monkeypatch.setattr("volleybots.eval.crossplay.play_games", play)


TAMPER = {
    "side_wdl disagrees with wdl": (lambda d: d["side_wdl"].update({"0,1": [[2, 0, 0], [0, 0, 0]]}), ["side_wdl['0,1']", "adds up"]),
    "mirror disagrees": (lambda d: d["wdl"][1].__setitem__(0, [9, 0, 9]), ["wdl[1][0]", "mirror"]),
    "competitors missing": (lambda d: d.pop("competitors"), ["no 'competitors'"]),
    "config a list": (lambda d: d.update(config=[1, 2]), ["'config' is list"]),
    "versions a string": (lambda d: d.update(versions="x"), ["'versions' is str"]),
    "served too many": (lambda d: d["served"].update({"0,1": 2**70}), ["served['0,1']"]),
    "content mistyped": (lambda d: d["content"]["0,1"].update(touches="many"), ["content['0,1']", "'touches'"]),
    "mixture broken": (lambda d: d["competitors"][0].update(mixture=[0.3]), ["competitors[0]", "sums to 0.3"]),
}


@pytest.mark.parametrize("case", list(TAMPER))
def test_a_tampered_reuse_file_is_refused_before_any_game(case, played, no_games, tmp_path):
    edit, words = TAMPER[case]
    data = json.loads(json.dumps(played))
    edit(data)
    path = tmp_path / "crossplay.json"
    path.write_text(json.dumps(data))
    one_line_exit_2(runner.invoke(app, ["eval", "crossplay", *PAIR, f"reuse={path}", "--out", str(tmp_path / "o")]), *words)
    assert not (tmp_path / "o").exists()


def test_a_pair_cut_short_is_not_reused(played, no_games, tmp_path):
    data = json.loads(json.dumps(played))
    data["outcomes"]["0,1"] = data["outcomes"]["0,1"][:1]
    w = data["outcomes"]["0,1"]
    counts = [int(w == "W"), int(w == "D"), int(w == "L")]
    data["wdl"][0][1], data["wdl"][1][0] = counts, counts[::-1]
    data["side_wdl"]["0,1"] = [counts, [0, 0, 0]]
    path = tmp_path / "crossplay.json"
    path.write_text(json.dumps(data))
    one_line_exit_2(runner.invoke(app, ["eval", "crossplay", *PAIR, f"reuse={path}", "--out", str(tmp_path / "o")]),
                    "pair 0,1 holds 1 games, not games_per_pair=2")


def test_an_intact_reuse_file_is_copied_in_a_folder_named_with_comma_equals_and_accents(played, no_games, tmp_path):
    folder = tmp_path / "a,b=c_é"
    folder.mkdir()
    (folder / "crossplay.json").write_text(json.dumps(played))
    res = runner.invoke(app, ["eval", "crossplay", *PAIR, f"reuse={folder / 'crossplay.json'}", "--json", "--out", str(tmp_path / "o")])
    assert res.exit_code == 0, res.output
    out = json.loads((tmp_path / "o" / "crossplay.json").read_text())
    assert out["outcomes"] == played["outcomes"] and out["reused"] == {"0,1": str(folder / "crossplay.json")}


def test_elo_from_a_file_refuses_options_that_only_play(played, tmp_path):
    path = tmp_path / "crossplay.json"
    path.write_text(json.dumps(played))
    one_line_exit_2(runner.invoke(app, ["eval", "elo", f"from={path}", f"reuse={tmp_path / 'missing.json'}", "--out", str(tmp_path / "o")]),
                    "reuse=", "from=")
    assert not (tmp_path / "o").exists()


def test_the_game_fingerprint_covers_the_config_tree(tmp_path, monkeypatch):
    import volleybots.paths as paths
    import volleybots.version as version

    conf = shutil.copytree(paths.conf_dir(), tmp_path / "conf")
    monkeypatch.setattr(paths, "conf_dir", lambda: conf)
    version.play_code.cache_clear()
    try:
        before = version.play_code()
        drone = next((conf / "env" / "drone").glob("*.yaml"))
        drone.write_text(drone.read_text() + "\n# a changed drone\n")
        version.play_code.cache_clear()
        assert version.play_code() != before
    finally:
        version.play_code.cache_clear()


def test_a_member_replaced_by_another_policy_under_its_label_is_refused(tiny_population, copy_run):
    from volleybots.policies import resolve_competitor

    run = copy_run(tiny_population)
    path = run / "population" / "member_001.pt"
    state = torch.load(path, weights_only=True)
    assert state["label"] == "br1"
    for v in state["algo"].values():  # another run's learner: other weights, the same label
        if isinstance(v, dict):
            for t in v.values():
                if isinstance(t, torch.Tensor) and t.is_floating_point():
                    t.add_(0.5)
    torch.save(state, path)
    with pytest.raises(ConfigError, match="member_001.pt is not the file this run wrote"):
        resolve_competitor(str(run))
    before = snapshot(run)
    one_line_exit_2(runner.invoke(app, ["train", f"resume={run}", "algo.iterations=2", "total_frames=512"]), "member_001.pt", "sha256")
    assert snapshot(run) == before


def test_a_payoff_table_whose_mirror_disagrees_is_refused(tiny_population, copy_run):
    run = copy_run(tiny_population)
    path = run / "population" / "payoffs.json"
    data = json.loads(path.read_text())
    w, d, l_ = data["wdl"][0][1]
    data["wdl"][1][0] = [w + 1, d, l_]  # no longer the mirror image
    path.write_text(json.dumps(data))
    before = snapshot(run)
    one_line_exit_2(runner.invoke(app, ["train", f"resume={run}", "algo.iterations=2", "total_frames=512"]), "payoffs.json", "mirror")
    assert snapshot(run) == before


def test_report_lists_a_run_whose_config_is_a_folder_as_failed(tiny_1v1_run, copy_run):
    from volleybots.report import find_runs

    run = copy_run(tiny_1v1_run)
    (run / "config.yaml").unlink()
    (run / "config.yaml").mkdir()
    (found,) = find_runs([run], now=0.0)  # "now" long before the run was written: it could only be running by its age
    assert found.status == "failed" and "config.yaml" in found.reason and "folder" in found.reason


def _table_with_ties(rng, n: int) -> np.ndarray:
    """A zero-sum table of n members that are copies of k < n policies, payoffs in quarters: many maximin mixtures."""
    k = int(rng.integers(2, n))
    base = np.triu(rng.choice([-1.0, -0.5, 0.0, 0.0, 0.5, 1.0], size=(k, k)), 1)
    base -= base.T
    idx = rng.integers(0, k, size=n)
    return base[np.ix_(idx, idx)]


def test_nash_of_relabelled_tables_with_ties_is_the_same_mixture():
    rng = np.random.default_rng(49)

    def entropy(x):
        x = x[x > 0]
        return float(-(x * np.log(x)).sum())

    for _ in range(120):  # before the fix about 6 % of such tables changed with the order
        n = int(rng.integers(3, 9))
        a = _table_with_ties(rng, n)
        perm = rng.permutation(n)
        x, y = nash(a), nash(a[np.ix_(perm, perm)])
        assert y == pytest.approx(x[perm], abs=1e-4), (a.tolist(), perm.tolist())
        assert entropy(y) == pytest.approx(entropy(x), abs=1e-4)
        assert (a.T @ x).min() >= -1e-6  # each is maximin: symmetric zero-sum, value 0
