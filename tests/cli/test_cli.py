"""The `volleybots` command line on tiny budgets: what each verb writes and prints, and one clear line
with exit code 2 (and no file written) for every kind of bad input."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from helpers import snapshot
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.runs import read_metrics

TINY = [
    "task=hover", "env.num_envs=16", "algo.steps_per_batch=32", "total_frames=2048", "threads=1", "progress=false",
    "checkpoint.every=1024", "evaluation.every=1024", "evaluation.episodes=2",
    "task.episode_len=100",  # three evaluations and every `eval` of the run play 100-step episodes, not 500
    "algo.minibatches=1", "algo.epochs=1", "algo.hidden=[16]",  # one small gradient step a batch: the run dir is what is read
]
ENV = {**os.environ, "OMP_NUM_THREADS": "1"}
runner = CliRunner()


def _volleybots(*args, cwd=None, timeout=600):
    exe = shutil.which("volleybots")
    cmd = [exe] if exe else [sys.executable, "-m", "volleybots.cli"]
    return subprocess.run([*cmd, *args], cwd=cwd, env=ENV, capture_output=True, text=True, timeout=timeout)


def _verify_rrd(*paths):
    out = subprocess.run(["rerun", "rrd", "verify", *map(str, paths)], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """One tiny training run started from another directory, into the default outputs/ folder."""
    cwd = tmp_path_factory.mktemp("launch")
    res = _volleybots("train", *TINY, cwd=cwd)
    assert res.returncode == 0, res.stderr[-3000:]
    runs = [p.parent for p in (cwd / "outputs").rglob("summary.json")]
    assert len(runs) == 1 and runs[0].name.endswith("_hover_ppo"), runs
    assert str(runs[0]) in res.stdout  # the summary line names the run directory
    return runs[0]


def test_entry_point_version_and_help():
    assert shutil.which("volleybots"), "the volleybots console script is not installed"
    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0 and res.stdout.strip() == "volleybots 0.1.0"
    for verb in ("train", "eval", "replay", "list", "bench"):
        res = runner.invoke(app, [verb, "--help"])
        assert res.exit_code == 0 and "Usage" in res.stdout, verb


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_list_names_every_task_algorithm_backend_and_action_space():
    from volleybots.algos import ALGOS
    from volleybots.physics import ACTION_SPACES, BACKENDS
    from volleybots.tasks import TASKS

    res = runner.invoke(app, ["list"])
    assert res.exit_code == 0
    lines = [line.split()[0] for line in res.stdout.splitlines() if line.startswith("  ")]
    for name in [*TASKS, *ALGOS, *BACKENDS, *ACTION_SPACES]:
        assert name in lines, name
    assert "[no conf/task file]" not in res.stdout
    # each algorithm's line names the tasks it trains: the population methods the three matches
    tasks = {line.split()[0]: line.split("tasks:")[1].replace(",", " ").split() for line in res.stdout.splitlines() if "tasks:" in line}
    for name in ("sp", "fsp", "psro_uniform", "psro_nash"):
        assert tasks[name] == ["1v1", "3v3", "6v6"], (name, tasks[name])
    assert "1v1" not in tasks["ppo"] and "hover" in tasks["ppo"]


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_train_writes_a_complete_run_directory(run_dir):
    from volleybots.runs import RunDir

    cfg = RunDir(run_dir).load_config()  # the resolved config validates again
    assert cfg.task.name == "hover" and cfg.env.num_envs == 16 and cfg.total_frames == 2048
    assert (run_dir / ".hydra" / "overrides.yaml").is_file()
    rows = read_metrics(run_dir / "metrics.csv")
    train = [r for r in rows if r["phase"] == "train"]
    evals = [r for r in rows if r["phase"] == "eval"]
    assert [int(r["frames"]) for r in train] == [512, 1024, 1536, 2048]
    assert [int(r["frames"]) for r in evals] == [1024, 2048]
    for col in ("wall_time", "fps", "return", "episode_len", "distance", "r_pose", "r_up", "r_spin", "r_crash",
                "loss_objective", "loss_critic", "loss_entropy", "entropy", "eval_distance", "eval_return"):
        assert col in rows[0], col
    assert all(r["wall_time"] > 0 for r in train) and train[-1]["wall_time"] >= train[0]["wall_time"]
    # per-term returns add up to the return (every reward term is logged)
    for r in train:
        if isinstance(r["return"], float):
            assert abs(r["r_pose"] + r["r_up"] + r["r_spin"] + r["r_crash"] - r["return"]) < 1e-3 * max(1.0, abs(r["return"]))
    ckpts = sorted((run_dir / "checkpoints").iterdir())
    assert [p.name for p in ckpts] == ["best.pt", "ckpt_000000001024.pt", "final.pt"]
    for p in ckpts:
        state = torch.load(p, weights_only=True)
        assert state["task"] == "hover" and state["frames"] in (1024, 2048)
        assert state["algo"]["actor"] and state["algo"]["optim"]["state"]
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["frames"] == 2048 and summary["metric"] == "distance"
    assert summary["final_eval"]["episodes"] == 2
    assert 0.0 < summary["final_eval"]["stats"]["distance"]["mean"] < 10.0
    _verify_rrd(run_dir / "curves.rrd", run_dir / "eval_000000001024.rrd", run_dir / "eval_000000002048.rrd")


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_eval_of_a_run_prints_a_table_and_json(run_dir):
    res = runner.invoke(app, ["eval", str(run_dir), "episodes=3", "--json"])
    assert res.exit_code == 0, res.output[-2000:]
    out = json.loads(res.stdout)
    assert out["episodes"] == 3 and out["metric"] == "distance" and out["task"] == "hover"
    assert out["checkpoint"].endswith("final.pt") and out["deterministic"] is True
    import hashlib

    assert out["checkpoint_sha256"] == hashlib.sha256((run_dir / "checkpoints" / "final.pt").read_bytes()).hexdigest()
    assert out["config"]["task"]["name"] == "hover" and out["seed"] == 0  # provenance
    assert {"distance", "return", "r_pose", "r_crash"} <= set(out["stats"])
    ckpt = run_dir / "checkpoints" / "ckpt_000000001024.pt"
    res = runner.invoke(app, ["eval", str(ckpt), "episodes=2"])
    assert res.exit_code == 0, res.output
    assert "distance (metric)" in res.stdout and "ppo@1024" in res.stdout


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_eval_compare_pairs_the_episodes_and_tells_the_better_player(run_dir):
    # 150-step episodes (of 500): random play has tumbled long before, the scripted player flies on
    args = ["random", "scripted", "task=hover", "task.episode_len=150", "episodes=8", "seed=3", "--json"]
    res = runner.invoke(app, ["eval", "compare", *args])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["task"] == "hover" and out["episodes"] == 8 and out["higher_is_better"] is False
    rand, scripted = out["targets"]
    assert len(rand["per_episode"]) == 8 and "vs_baseline" not in rand
    c = scripted["vs_baseline"]
    # the scripted player flies to every target; random play tumbles: better in each of the 8 episodes
    assert (c["wins"], c["ties"], c["losses"]) == (8, 0, 0) and c["verdict"] == "better" and c["p"] < 0.01
    assert c["diff"] == pytest.approx(rand["mean"] - scripted["mean"]) and c["low"] > 0
    # a scripted baseline plays the run's task; a policy against itself ties every episode
    # (50-step episodes of the run's 100: a tie and the task carried over hold at any length)
    res = runner.invoke(app, ["eval", "compare", "scripted", str(run_dir), str(run_dir), "episodes=3", "task.episode_len=50", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["task"] == "hover" and [t["target"] for t in out["targets"]] == ["scripted", str(run_dir), str(run_dir)]
    assert out["targets"][1]["per_episode"] == out["targets"][2]["per_episode"]
    res = runner.invoke(app, ["eval", "compare", str(run_dir), str(run_dir), "episodes=3", "task.episode_len=50"])
    assert res.exit_code == 0 and "level" in res.stdout and "0/3/0" in res.stdout


def test_eval_of_random_play(tmp_path):
    res = runner.invoke(app, ["eval", "random", "task=solo_bump", "env.action_space=ctbr", "episodes=4", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["target"] == "random" and out["task"] == "solo_bump" and out["episodes"] == 4
    assert out["stats"]["episode_len"]["mean"] < 800  # random flight ends early


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_eval_of_the_scripted_pair_on_a_multi_drone_task():
    # no algo named: the multi-drone task takes the multi-agent default, and a scripted policy needs none
    # a quarter of an episode (200 of 800 steps; each touch costs the pair a lookahead search): the pair
    # still has to keep passing, 3 hits in each episode on seeds 0-2 (about 14 in a full episode)
    res = runner.invoke(app, ["eval", "scripted", "task=bump_and_pass", "task.episode_len=200", "episodes=2", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["task"] == "bump_and_pass" and out["config"]["algo"]["name"] == "mappo"
    assert out["stats"]["hits"]["mean"] >= 3  # the opening bump, a pass and its answer
    assert out["config"]["task"]["episode_len"] == 200


def test_train_cfg_prints_the_config_without_training(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # where a run's outputs/ would appear
    res = runner.invoke(app, ["train", "--cfg", "job", "task=solo_bump", "env.action_space=ctbr"])
    assert res.exit_code == 0, res.output[-2000:]
    assert "name: solo_bump" in res.stdout and "action_space: ctbr" in res.stdout and "hit_reward: 2.0" in res.stdout
    assert not any(tmp_path.iterdir())  # nothing was trained or written


def test_bench_prints_the_speed_table():
    res = runner.invoke(app, ["bench", "tasks=[hover]", "backends=[torch]", "num_envs=[4]", "devices=[cpu]", "repeats=1", "steps=5"])
    assert res.exit_code == 0, res.output
    rows = [line for line in res.stdout.splitlines() if line.startswith("| hover")]
    assert len(rows) == 1 and "| torch |" in rows[0]


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_multirun_sweeps_seeds(tmp_path):
    res = runner.invoke(app, ["train", "-m", "seed=0,1", *[o for o in TINY if not o.startswith("total_frames")], "total_frames=512",
                              "evaluation.episodes=1", "evaluation.record=false", f"hydra.sweep.dir={tmp_path / 'sweep'}"])
    assert res.exit_code == 0, res.output[-2000:]
    seeds = sorted(json.loads((p / "summary.json").read_text())["seed"] for p in (tmp_path / "sweep").iterdir() if p.is_dir())
    assert seeds == [0, 1]


def _bad_cases(run_dir: Path, tmp: Path):
    mismatched = tmp / "mismatched.pt"
    state = torch.load(run_dir / "checkpoints" / "final.pt", weights_only=True)
    state["config"]["task"] = {"name": "solo_bump", "reward_shaping": True, "episode_len": None, "hit_reward": 2.0, "height_reward": 8.0}
    torch.save(state, mismatched)
    state = torch.load(run_dir / "checkpoints" / "final.pt", weights_only=True)
    state["config"]["task"]["target"] = [0.0, 0.0, 2.0]  # hover with a fixed target: other episodes than the run's
    torch.save(state, tmp / "fixed_target.pt")
    (tmp / "not_a_ckpt.pt").write_text("hello")
    (tmp / "empty_run").mkdir()
    shutil.copy(run_dir / "config.yaml", tmp / "empty_run" / "config.yaml")
    import importlib.util

    no_wandb = [(["train", "logger=wandb"], ["wandb", "logger=csv"])] if importlib.util.find_spec("wandb") is None else []
    return no_wandb + [
        (["train", "task=hovr"], ["hovr", "hover", "solo_bump"]),
        (["train", "algo=nope"], ["nope", "ppo", "mappo"]),
        (["train", "env=gpu"], ["gpu", "cpu", "cuda"]),
        (["train", "env.num_envz=3"], ["env.num_envz", "num_envs"]),
        (["train", "env.num_envs=lots"], ["env.num_envs", "lots"]),
        (["train", "task=3v3", "algo=ppo"], ["ppo", "3v3", "mappo"]),
        (["train", "algo=dqn", "env.action_space=prt"], ["dqn", "prt", "discrete"]),
        (["train", "algo=sac", "env.action_space=discrete"], ["sac", "discrete", "prt"]),
        (["train", "seed=0,1"], ["seed=0,1", "-m"]),
        (["train", "--frames", "3"], ["--frames", "--multirun"]),
        (["train", "-m", "seed=0,1", "--cfg", "job"], ["--cfg", "-m"]),
        (["train", f"hydra.run.dir={run_dir}"], [str(run_dir), "resume="]),
        (["train", f"resume={tmp / 'nowhere'}"], ["nowhere", "not a run directory"]),
        (["train", f"resume={run_dir}"], ["total_frames"]),
        (["train", f"resume={run_dir}", "algo.gamma=0.9"], ["algo.gamma", "total_frames"]),
        (["eval", str(tmp / "nowhere")], ["nowhere", "scripted", "random"]),
        (["eval", str(tmp / "not_a_ckpt.pt")], ["not_a_ckpt.pt", "not a volleybots checkpoint"]),
        (["eval", str(tmp / "empty_run")], ["empty_run", "no checkpoint"]),
        (["eval", str(mismatched)], ["mismatched.pt", "does not match", "solo_bump"]),
        (["eval", str(run_dir), "task=solo_bump"], ["task", "episodes"]),
        (["eval", str(run_dir), "episodes=0"], ["episodes", ">= 1"]),
        (["eval", "random", "task=nope"], ["nope", "hover"]),
        (["eval", "compare", "scripted", "episodes=2"], ["compare", "baseline", "scripted"]),
        (["eval", "compare", str(run_dir), str(mismatched), "episodes=2"], ["one task", "hover", "solo_bump"]),
        (["eval", "compare", str(run_dir), str(tmp / "fixed_target.pt"), "episodes=2"], ["fixed_target.pt", "did not play the episodes"]),
        (["eval", "compare", "scripted", str(run_dir), "--out", "x"], ["--out", "--json"]),
        (["eval", "compare", "scripted", str(run_dir), "sed=3"], ["sed=3", "no option 'sed'", "seed"]),
        (["replay", "random", "--out", str(run_dir / "curves.rrd")], ["curves.rrd", "exists"]),
        (["replay", "random", "--out", str(tmp / "x.txt")], ["x.txt", ".rrd"]),
        (["bench", "speed=3"], ["speed", "num_envs"]),
    ]


def test_bad_input_exits_2_with_one_line_and_writes_nothing(run_dir, tmp_path):
    cases = _bad_cases(run_dir, tmp_path)
    before = snapshot(run_dir), snapshot(tmp_path)
    for args, words in cases:
        res = runner.invoke(app, args)
        assert res.exit_code == 2, (args, res.exit_code, res.output)
        err = res.stderr.strip()
        assert "Traceback" not in res.output and len(err.splitlines()) == 1, (args, res.output)
        assert err.startswith("error: ")
        for w in words:
            assert w in err, (args, w, err)
    assert (snapshot(run_dir), snapshot(tmp_path)) == before


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_bad_input_from_a_real_process_has_no_traceback(tmp_path):
    res = _volleybots("train", "task=hovr", cwd=tmp_path)
    assert res.returncode == 2 and res.stderr.strip().startswith("error: unknown task 'hovr'")
    assert len(res.stderr.strip().splitlines()) == 1 and not any(tmp_path.iterdir())
