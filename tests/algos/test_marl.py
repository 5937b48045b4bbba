"""The cooperative MARL algorithms (qmix, maddpg, happo, mat): tiny runs on Bump and Pass that write
checkpoints and metrics and resume bit for bit; HAPPO's sequential ratio weighting against a
hand-computed batch; MAT's causal decoder; QMIX's monotonic mixer; refusals of what they cannot
train; and one contract test over the whole registry (every algorithm on every task kind it claims)."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import pytest
import torch
from helpers import flat
from tensordict import TensorDict
from typer.testing import CliRunner

from volleybots.algos import ALGOS, is_population
from volleybots.algos.base import TASK_KINDS
from volleybots.cli import app
from volleybots.config import ConfigError, load
from volleybots.eval import evaluate
from volleybots.runs import read_metrics
from volleybots.train import resume, train

MARL = ("qmix", "maddpg", "happo", "mat")
ENVS, STEPS = 4, 8
FPB = ENVS * STEPS  # frames per batch
TASK_OF_KIND = {"single": "hover", "cooperative": "bump_and_pass", "competitive": "1v1"}
RUN = [
    f"env.num_envs={ENVS}", f"algo.steps_per_batch={STEPS}", "task.episode_len=30", "seed=2", "threads=1", "progress=false",
    "checkpoint.keep=5", "evaluation.every=0", "evaluation.episodes=2", "evaluation.record=false",
]


def tiny(name: str) -> list[str]:
    """Overrides that make any registered algorithm small and quick to warm up (by its config's keys)."""
    small = {
        "minibatches": 2, "hidden": "[16,16]", "batch_size": 8, "buffer_size": 512, "warmup_batches": 1,
        "embed_dim": 16, "n_heads": 2, "n_blocks": 1, "mixing_embed_dim": 8, "checkpoint_buffer": "true",
        "teacher_replan": STEPS,  # bc's lookahead teacher searches once a batch, not every step
    }
    keys = {f.name for f in dataclasses.fields(ALGOS[name].config_cls)}
    return [f"algo.{k}={v}" for k, v in small.items() if k in keys]


def _train_rows(run):
    return [r for r in read_metrics(run / "metrics.csv") if r["phase"] == "train"]


# ------------------------------------------------------------------------------------ runs, resume
@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("name", MARL)
def test_a_tiny_run_on_bump_and_pass_checkpoints_and_resumes_bit_for_bit(name, tmp_path):
    common = ["task=bump_and_pass", f"algo={name}", *RUN, *tiny(name), f"checkpoint.every={2 * FPB}"]
    full = train(load([*common, f"total_frames={4 * FPB}"]), tmp_path / "full")
    assert full["frames"] == 4 * FPB and full["algo"] == name
    rows = _train_rows(tmp_path / "full")
    assert [r["frames"] for r in rows] == [float(FPB * i) for i in range(1, 5)]
    losses = [k for k in rows[-1] if k.startswith("loss_")]
    assert losses and all(isinstance(rows[-1][k], float) and math.isfinite(rows[-1][k]) for k in losses), rows[-1]
    ck = tmp_path / "full" / "checkpoints"
    assert sorted(p.name for p in ck.iterdir()) == ["best.pt", f"ckpt_{2 * FPB:012d}.pt", "final.pt"]
    a = torch.load(ck / "final.pt", weights_only=True)
    assert a["config"]["algo"]["name"] == name and a["n_agents"] == 2

    # interrupted at the periodic checkpoint, then resumed: the same run
    train(load([*common, f"total_frames={2 * FPB}"]), tmp_path / "half")
    resumed = resume(tmp_path / "half", [f"total_frames={4 * FPB}"])
    assert resumed["frames"] == 4 * FPB
    b = torch.load(tmp_path / "half" / "checkpoints" / "final.pt", weights_only=True)
    fa, fb = flat(a["algo"]), flat(b["algo"])
    assert fa.keys() == fb.keys()
    for k in fa:
        assert torch.equal(fa[k], fb[k]) if isinstance(fa[k], torch.Tensor) else fa[k] == fb[k], k
    rb = _train_rows(tmp_path / "half")
    assert [r["frames"] for r in rb] == [r["frames"] for r in rows]
    for col in losses:
        assert [r[col] for r in rb] == [r[col] for r in rows], col
    assert a["evals"][-1] == b["evals"][-1]

    # the run evaluates through the same entry point as every other algorithm
    ev = evaluate(str(tmp_path / "full"), episodes=2)
    assert ev["episodes"] == 2 and math.isfinite(ev["stats"]["return"]["mean"])


def test_replay_records_a_mat_run(tmp_path):
    """MAT acts through its own auto-regressive loop: the replay command drives it like any policy."""
    train(load(["task=bump_and_pass", "algo=mat", *RUN, *tiny("mat"), "checkpoint.every=0", f"total_frames={FPB}"]), tmp_path / "run")
    out = tmp_path / "ep.rrd"
    res = CliRunner().invoke(app, ["replay", str(tmp_path / "run"), "--out", str(out), "--no-viewer"])
    assert res.exit_code == 0, res.output[-2000:]
    assert out.is_file() and out.stat().st_size > 1000


# -------------------------------------------------------------------------------------- refusals
@pytest.mark.parametrize(
    "overrides, message",
    [
        (["algo=qmix", "task=bump_and_pass", "env.action_space=prt"], "allowed: discrete"),
        (["algo=happo", "task=hover"], "allowed tasks: bump_and_pass, set_and_spike_easy, set_and_spike_hard"),
        (["algo=mat", "task=1v1"], "task '1v1' is competitive"),
        (["algo=maddpg", "task=solo_bump"], "trains cooperative tasks"),
        (["algo=qmix", "task=bump_and_pass", "algo.double_q=true"], "algo.double_q"),
        (["algo=mat", "task=bump_and_pass", "algo.n_heads=3"], "multiple of algo.n_heads"),
    ],
)
def test_what_an_algorithm_cannot_train_is_refused(overrides, message):
    with pytest.raises(ConfigError, match=message):
        load(overrides)


def test_the_cli_refuses_in_one_line_with_exit_2_and_writes_nothing(tmp_path):
    run = tmp_path / "run"
    res = CliRunner().invoke(app, ["train", "algo=happo", "task=hover", f"hydra.run.dir={run}"])
    assert res.exit_code == 2
    assert len(res.stderr.strip().splitlines()) == 1 and "bump_and_pass" in res.stderr
    assert not run.exists()


def test_qmix_selects_the_discrete_action_space_by_itself():
    assert load(["algo=qmix", "task=set_and_spike_easy"]).env.action_space == "discrete"


# ------------------------------------------------------------------------------------ HAPPO
def _fake_env(n_agents: int, obs_dim: int = 6, continuous: bool = True):
    actions = SimpleNamespace(continuous=continuous, dim=4, n=0 if continuous else 16)
    return SimpleNamespace(device=torch.device("cpu"), n_drones=n_agents, obs_dim=obs_dim, actions=actions)


def _synthetic_batch(algo, n_envs: int, steps: int, obs_dim: int):
    """A [N, T] batch in the collector's layout, actions drawn by the algorithm's own policy."""
    a = algo.n_agents
    obs = torch.randn(n_envs, steps + 1, a, obs_dim)
    act = algo.policy()
    out = []
    for t in range(steps):
        td = TensorDict({"agents": TensorDict({"observation": obs[:, t]}, [n_envs, a])}, [n_envs])
        td = act(td)
        done = torch.zeros(n_envs, 1, dtype=torch.bool)
        td["next"] = TensorDict(
            {
                "agents": TensorDict({"observation": obs[:, t + 1], "reward": torch.randn(n_envs, a, 1)}, [n_envs, a]),
                "done": done, "terminated": done.clone(), "truncated": done.clone(),
            },
            [n_envs],
        )
        out.append(td)
    return torch.stack(out, 1)


def _log_prob_by_hand(actor, obs, action):
    """log N(action; loc, scale) summed over the action's dimensions, from the actor's outputs."""
    with torch.no_grad():
        out = actor(TensorDict({"observation": obs}, [obs.shape[0]]))
    return torch.distributions.Normal(out["loc"], out["scale"]).log_prob(action).sum(-1)


def test_happo_weights_each_drone_by_the_ratios_of_the_drones_before_it_in_the_drawn_order():
    torch.manual_seed(0)
    algo_cls = ALGOS["happo"]
    cfg = algo_cls.config_cls(hidden=[16], epochs=2, minibatches=2, actor_lr=5e-3)
    algo = algo_cls(cfg, _fake_env(3), seed=7)
    batch = _synthetic_batch(algo, n_envs=8, steps=8, obs_dim=6)
    expected_order = torch.randperm(3, generator=torch.Generator().manual_seed(7)).tolist()

    seen = []  # (agent, factor it was trained with, its ratio on every sample after its update)
    train_agent = algo.train_agent

    def spy(a, td):
        logs = train_agent(a, td)
        new = _log_prob_by_hand(algo.actor.actors[a], td["observation"], td["action"])
        seen.append((a, td["factor"].clone(), (new - td["action_log_prob"]).exp()))
        return logs

    algo.train_agent = spy
    algo.update(batch)
    assert [a for a, _, _ in seen] == expected_order
    product = torch.ones(64)
    for _, factor, ratio in seen:
        torch.testing.assert_close(factor, product, rtol=1e-5, atol=1e-6)
        assert (ratio - 1).abs().max() > 1e-3, "every drone's policy moved"
        product = product * ratio
    assert (seen[2][1] - 1).abs().max() > 1e-3  # the third drone's weights are not all one


def test_happo_surrogate_is_the_clipped_objective_scaled_by_the_factor():
    """One drone's loss on a hand-made batch against min(r A, clip(r) A) x M computed by hand."""
    torch.manual_seed(1)
    algo_cls = ALGOS["happo"]
    cfg = algo_cls.config_cls(hidden=[8], clip_epsilon=0.1, entropy_coeff=0.0)
    algo = algo_cls(cfg, _fake_env(2), seed=0)
    n = 6
    obs, action = torch.randn(n, 6), torch.randn(n, 4)
    new = _log_prob_by_hand(algo.actor.actors[1], obs, action)
    ratio = torch.tensor([0.5, 0.95, 1.0, 1.05, 1.3, 2.0])  # inside and outside [0.9, 1.1]
    old = new - ratio.log()
    adv = torch.tensor([1.0, -2.0, 0.5, 3.0, -1.0, 2.0])
    factor = torch.tensor([1.0, 0.5, 2.0, 1.5, 0.8, 1.2])
    flat = TensorDict(
        {"agents": TensorDict({"observation": torch.stack([obs, obs], 1), "action": torch.stack([action, action], 1),
                               "action_log_prob": torch.stack([old, old], 1)}, [n, 2])},
        [n],
    )
    td = algo.agent_batch(flat, 1, adv, factor)
    loss = float(algo.agent_losses[1](td)["loss_objective"].detach())
    by_hand = -(factor * torch.minimum(ratio * adv, ratio.clamp(0.9, 1.1) * adv)).mean()
    assert loss == pytest.approx(float(by_hand), rel=1e-5)


# -------------------------------------------------------------------------------------- MAT
@pytest.mark.parametrize("continuous", [True, False])
def test_mat_decoder_is_causal(continuous):
    """Drone i's action parameters depend on the representations of drones <= i and the actions of
    drones < i only: changing a later drone's input leaves them unchanged (an earlier one does not)."""
    torch.manual_seed(0)
    algo_cls = ALGOS["mat"]
    cfg = algo_cls.config_cls(embed_dim=16, n_heads=2, n_blocks=2)
    algo = algo_cls(cfg, _fake_env(4, continuous=continuous), seed=0)
    dec = algo.decoder
    rep = torch.randn(5, 4, 16)
    action = torch.randn(5, 4, 4) if continuous else torch.randint(16, (5, 4))
    with torch.no_grad():
        base = dec(rep, action)
        for i in range(4):
            later_rep, later_act = rep.clone(), action.clone()
            later_rep[:, i + 1 :] += torch.randn_like(later_rep[:, i + 1 :])
            later_act[:, i:] = torch.randn_like(later_act[:, i:]) if continuous else (later_act[:, i:] + 5) % 16
            out = dec(later_rep, later_act)
            torch.testing.assert_close(out[:, : i + 1], base[:, : i + 1], rtol=0, atol=1e-5)
            if i > 0:
                earlier = action.clone()
                earlier[:, i - 1] = earlier[:, i - 1] + 1.0 if continuous else (earlier[:, i - 1] + 5) % 16
                assert (dec(rep, earlier)[:, i] - base[:, i]).abs().max() > 1e-4


def test_mat_acting_is_auto_regressive_and_matches_the_teacher_forced_log_probs():
    torch.manual_seed(0)
    algo_cls = ALGOS["mat"]
    algo = algo_cls(algo_cls.config_cls(embed_dim=16, n_heads=2, n_blocks=1), _fake_env(3), seed=0)
    obs = torch.randn(6, 3, 6)
    td = algo.policy()(TensorDict({"agents": TensorDict({"observation": obs}, [6, 3])}, [6]))
    action, log_prob = td["agents", "action"], td["agents", "action_log_prob"]
    with torch.no_grad():
        dist = algo.actor.get_dist(td.clone())
    torch.testing.assert_close(dist.log_prob(action), log_prob, rtol=1e-4, atol=1e-4)
    # greedy acting chose each drone's mean with zeros in place of the later drones' actions; the
    # teacher-forced pass, which sees every drone's chosen action, gives the same means
    greedy = algo.policy(deterministic=True)(TensorDict({"agents": TensorDict({"observation": obs}, [6, 3])}, [6]))
    with torch.no_grad():
        loc = algo.decoder(algo.encoder(obs), greedy["agents", "action"])
    torch.testing.assert_close(greedy["agents", "action"], loc, rtol=1e-4, atol=1e-5)


# -------------------------------------------------------------------------------------- QMIX
def test_qmix_mixer_is_monotonic_in_every_drones_q():
    torch.manual_seed(0)
    algo_cls = ALGOS["qmix"]
    algo = algo_cls(algo_cls.config_cls(hidden=[32, 16], mixing_embed_dim=8), _fake_env(3, continuous=False), seed=0)
    obs = torch.randn(256, 3, 6)
    q = (torch.randn(256, 3, 1) * 5).requires_grad_(True)
    q_tot = algo.mixer(q, obs)
    assert q_tot.shape == (256, 1)
    (grad,) = torch.autograd.grad(q_tot.sum(), q)
    assert (grad >= 0).all() and (grad > 1e-6).float().mean() > 0.5
    with torch.no_grad():
        for a in range(3):
            up = q.detach().clone()
            up[:, a] += torch.rand(256, 1) * 3
            assert (algo.mixer(up, obs) >= algo.mixer(q.detach(), obs) - 1e-6).all()
    # the team's greedy joint action is every drone's own greedy action
    with torch.no_grad():
        qs = algo.qnet(obs)  # [256, 3, 16]
        best = algo.mixer(qs.max(-1, keepdim=True).values, obs)
        other = algo.mixer(qs.gather(-1, torch.randint(16, (256, 3, 1))), obs)
    assert (best >= other - 1e-6).all()


# --------------------------------------------------------------------------------- the contract
@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("name", list(ALGOS))
def test_every_algorithm_trains_every_task_kind_it_claims_and_refuses_the_others(name, tmp_path):
    cls = ALGOS[name]
    for kind in TASK_KINDS:
        if kind in cls.supported_kinds() and is_population(cls):
            continue  # trained by the population loop, not `train`: tests/population/test_population.py runs it
        overrides = [f"algo={name}", f"task={TASK_OF_KIND[kind]}", *RUN, *tiny(name), "checkpoint.every=0", f"total_frames={2 * FPB}"]
        if kind == "competitive" and getattr(cls, "needs_seat_on_matches", False):
            with pytest.raises(ConfigError, match="opponent="):  # it learns one team: refused without a seat
                load(overrides)
            overrides.append("opponent=random")
        if kind not in cls.supported_kinds():
            with pytest.raises(ConfigError):
                load(overrides)
            continue
        cfg = load(overrides)
        assert cfg.env.action_space in cls.action_spaces
        summary = train(cfg, tmp_path / kind)
        rows = _train_rows(tmp_path / kind)
        assert summary["frames"] == 2 * FPB and len(rows) == 2
        state = torch.load(tmp_path / kind / "checkpoints" / "final.pt", weights_only=True)
        assert state["frames"] == 2 * FPB and state["task"] == TASK_OF_KIND[kind]
        assert math.isfinite(summary["final_eval"]["stats"]["return"]["mean"])
    assert cls.supported_kinds(), name
