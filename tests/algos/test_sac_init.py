"""`algo=sac init=RUN` from a bc (or ppo / mappo) run: SAC keeps the run's actor frozen as a guide
(exactly the saved weights) and learns a residual on it, which starts at zero (the actor is the clone,
with `algo.guide_noise` of noise), plays it in the warm-up, then fits only the critics for
`algo.actor_freeze_updates` steps; the guide survives `resume=`.
A source that does not fit is still refused with one line, exit 2."""

from __future__ import annotations

import math

import pytest
import torch
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import load
from volleybots.errors import ConfigError
from volleybots.report import _flat  # nested dicts as dotted keys
from volleybots.runs import RunDir, read_metrics
from volleybots.train import Trainer, check_init, collect, resume, train

QUIET = ["threads=1", "progress=false", "evaluation.episodes=2", "evaluation.record=false", "seed=3"]
BC = ["task=solo_bump", "algo=bc", "env.num_envs=8", "algo.steps_per_batch=16", "algo.batch_size=64",
      "algo.expert_frames=256", "algo.actor_lr=3e-3", "total_frames=512", *QUIET,
      "task.episode_len=50"]  # init= checks the task's name only; short episodes keep the final evaluation cheap
# 8 envs x 8 steps = 64 frames a batch, which fills the warm-up (2 x 32); then 8 x 64 / 32 = 16 gradient steps a batch
SAC = ["task=solo_bump", "algo=sac", "env.num_envs=8", "algo.steps_per_batch=8", "algo.batch_size=32", "algo.warmup_batches=2",
       "algo.buffer_size=4096", "algo.guide_warmup=64", "algo.hidden=[32,32]", "evaluation.every=0", *QUIET]
FPB = 64


@pytest.fixture(scope="module")
def bc_run(tmp_path_factory):
    torch.set_num_threads(1)
    path = tmp_path_factory.mktemp("sac_init") / "bc"
    train(load(BC), path)
    return path


def _trainer(path, overrides) -> Trainer:
    cfg = load(overrides)
    run = RunDir(path)
    run.create(cfg)
    return Trainer(cfg, run)


def _copy(module) -> dict:
    return {k: v.clone() for k, v in module.state_dict().items()}


def _moved(old: dict, module) -> bool:
    return any(not torch.equal(old[k], v) for k, v in module.state_dict().items())


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_the_guide_is_exactly_the_saved_actor_and_drives_the_warm_up(bc_run, tmp_path):
    saved = torch.load(bc_run / "checkpoints" / "final.pt", weights_only=True)["algo"]
    tr = _trainer(tmp_path / "sac", [*SAC, f"init={bc_run}", "algo.guide_noise=0.01"])
    sac = tr.algo
    assert tr.init_info["loaded"] == ["guide"] and tr.init_info["algo"] == "bc"
    guide = sac.guide.actor.state_dict()
    assert guide.keys() == saved["actor"].keys()
    for k in guide:
        assert torch.equal(guide[k], saved["actor"][k]), k
    assert not any(p.requires_grad for p in sac.guide.parameters())
    # the warm-up plays the guide's mean action (here with little noise), not uniform noise
    td = tr.env.reset()
    obs = td.get(("agents", "observation"))
    action = sac.policy()(td).get(("agents", "action"))
    assert (action - sac.guide(obs)).abs().mean() < 0.02  # the clone, with noise of std 0.01 before the tanh
    assert action.abs().max() > 0.05  # the clone acts: the comparison is not of zeros
    # without init= nothing of the guide exists (and the columns are today's)
    plain = _trainer(tmp_path / "plain", SAC).algo
    assert plain.guide is None and "guide" not in plain.state_dict()
    assert not {"guide_mse", "actor_frozen"} & set(plain.log_keys())


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_with_a_guide_the_warm_up_lasts_guide_warmup_transitions(bc_run, tmp_path):
    # SAC's own warm-up is 2 x 32 = 64 transitions (one batch); the guide's play lasts 3 batches
    tr = _trainer(tmp_path / "long", [*SAC, f"init={bc_run}", f"algo.guide_warmup={3 * FPB}"])
    sac, env, td = tr.algo, tr.env, tr.env.reset()
    steps = []
    for _ in range(4):
        batch, td = collect(env, sac.policy(), td, 8)
        steps.append(sac.update(batch)["grad_steps"])
    assert steps == [0, 0, 16, 32]
    plain = _trainer(tmp_path / "plain", [*SAC, f"algo.guide_warmup={3 * FPB}"]).algo
    assert plain.warmup_frames == 64  # without a guide the key is not read
    capped = _trainer(tmp_path / "capped", [*SAC, f"init={bc_run}", "algo.guide_warmup=5000"]).algo
    assert capped.warmup_frames == 4096  # algo.buffer_size


def _guided(bc_run, tmp_path, freeze: int):
    """A guided SAC after its warm-up batch (16 gradient steps), its env and env input, the logs,
    and a fresh SAC's and the guided one's largest gap to the guide's action on that batch."""
    tr = _trainer(tmp_path / "guided", [*SAC, f"init={bc_run}", f"algo.actor_freeze_updates={freeze}"])
    sac, env = tr.algo, tr.env
    batch, td = collect(env, sac.policy(), env.reset(), 8)
    obs = batch.get(("agents", "observation")).reshape(-1, sac.obs_dim)
    fresh = _trainer(tmp_path / "fresh", SAC).algo
    with torch.no_grad():
        gaps = [(a.greedy(obs) - sac.guide(obs)).abs().max().item() for a in (fresh, sac)]
        _, scale = sac.head(obs)
    logs = sac.update(batch)
    return sac, env, td, logs, gaps, scale


def test_the_residual_actor_starts_as_the_guide(bc_run, tmp_path):
    sac, _, _, logs, (fresh, guided), scale = _guided(bc_run, tmp_path, freeze=1000)
    # atanh(tanh(x)) is exact but for actions clipped at +-(1 - 1e-3)
    assert guided <= 1.01e-3 and fresh > 0.3, (fresh, guided)
    assert torch.allclose(scale, torch.full_like(scale, 0.1), atol=1e-5)  # algo.guide_noise
    assert logs["grad_steps"] == 16 and logs["guide_mse"] < 1e-6 and logs["actor_frozen"] == 1.0


def test_the_critic_warm_up_leaves_the_actor_and_temperature_alone(bc_run, tmp_path):
    # 32 frozen steps: the first batch's 16 and the second's
    sac, env, td, _, _, _ = _guided(bc_run, tmp_path, freeze=32)

    def step():
        nonlocal td
        actor, critic = _copy(sac.head), {k: v.clone() for k, v in sac.loss.qvalue_network_params.items(True, True)}
        alpha = sac.loss.log_alpha.detach().clone()
        batch, td = collect(env, sac.policy(), td, 8)
        logs = sac.update(batch)
        critic_moved = any(not torch.equal(v, critic[k]) for k, v in sac.loss.qvalue_network_params.items(True, True))
        return logs, _moved(actor, sac.head), critic_moved, not torch.equal(alpha, sac.loss.log_alpha)

    logs, actor, critic, alpha = step()
    assert (actor, critic, alpha) == (False, True, False) and logs["actor_frozen"] == 1.0 and math.isnan(logs["loss_actor"])
    logs, actor, critic, alpha = step()
    assert (actor, critic, alpha) == (True, True, True) and logs["actor_frozen"] == 0.0 and math.isfinite(logs["loss_actor"])


def test_a_source_that_does_not_fit_is_refused(bc_run, tmp_path):
    with pytest.raises(ConfigError) as e:
        check_init(load([*SAC, "env.action_space=ctbr", f"init={bc_run}"]))
    assert "\n" not in str(e.value) and "algo bc" in str(e.value) and "the action space differs" in str(e.value)
    out = tmp_path / "refused"
    # in this process (a child process costs a fresh import of torch); tests/cli/test_cli.py checks a real one's exit
    args = [
        "train",
        *[o for o in SAC if not o.startswith("task=")],
        "task=hover",
        "total_frames=64",
        f"init={bc_run}",
        f"hydra.run.dir={out}",
    ]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 2, res.output[-2000:]
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert "algo bc, task solo_bump" in lines[0] and "algo sac, task hover" in lines[0] and "the task differs" in lines[0]
    assert not out.exists()


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_resume_keeps_the_guide_and_repeats_the_uninterrupted_run(bc_run, tmp_path):
    common = [
        *SAC,
        f"init={bc_run}",
        "algo.actor_freeze_updates=24",
        "algo.guide_coeff=1.0",
        "algo.checkpoint_buffer=true",
        f"checkpoint.every={2 * FPB}",
    ]
    train(load([*common, f"total_frames={4 * FPB}"]), tmp_path / "full")
    train(load([*common, f"total_frames={2 * FPB}"]), tmp_path / "half")
    resume(tmp_path / "half", [f"total_frames={4 * FPB}"])
    saved = torch.load(bc_run / "checkpoints" / "final.pt", weights_only=True)["algo"]["actor"]
    a = torch.load(tmp_path / "full" / "checkpoints" / "final.pt", weights_only=True)["algo"]
    b = torch.load(tmp_path / "half" / "checkpoints" / "final.pt", weights_only=True)["algo"]
    assert b["guide"]["net"] == a["guide"]["net"]
    for k, v in saved.items():
        assert torch.equal(b["guide"]["weights"][f"actor.{k}"], v), k
    for part in ("loss", "guide"):  # the same networks: the resumed actor is the same residual on the same guide
        fa, fb = _flat(a[part]), _flat(b[part])
        assert fa.keys() == fb.keys()
        for k in fa:
            assert torch.equal(fa[k], fb[k]) if isinstance(fa[k], torch.Tensor) else fa[k] == fb[k], (part, k)
    rows = [r for r in read_metrics(tmp_path / "half" / "metrics.csv") if r["phase"] == "train"]
    assert [r["actor_frozen"] for r in rows] == [1.0, 0.5, 0.0, 0.0]  # 24 frozen steps: 16, then 8 of 16


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_a_guided_sac_run_passes_its_guide_on(bc_run, tmp_path):
    train(load([*SAC, f"init={bc_run}", "algo.actor_freeze_updates=0", f"total_frames={3 * FPB}"]), tmp_path / "first")
    tr = _trainer(tmp_path / "second", [*SAC, f"init={tmp_path / 'first'}"])
    first = _trainer(tmp_path / "again", [*SAC, f"init={bc_run}"]).algo
    first.load_state_dict(torch.load(tmp_path / "first" / "checkpoints" / "final.pt", weights_only=True)["algo"])
    obs = tr.env.reset().get(("agents", "observation"))
    with torch.no_grad():
        assert tr.algo.guide is not None and torch.equal(tr.algo.greedy(obs), first.greedy(obs))
        assert (first.greedy(obs) - first.guide(obs)).abs().max() > 1e-3  # it learned: the residual matters
    assert tr.init_info["loaded"] == ["actor", "critic"]
