"""make_env(match, group_map="teams") (volleybots.tasks.groups, issue 55): one TorchRL group per team
with agent-level flags, passing TorchRL's own spec check, with the env's own numbers."""

from __future__ import annotations

import pytest
import torch
from torchrl.envs.utils import check_env_specs, check_marl_grouping

from volleybots import make_env
from volleybots.keys import ACTION, OBS, REWARD


@pytest.mark.parametrize("task", ["1v1", "3v3"])
def test_team_groups_pass_torchrl_spec_check_and_carry_the_envs_numbers(task):
    grouped = make_env(task, 3, seed=4, group_map="teams", episode_len=6)
    plain = make_env(task, 3, seed=4, episode_len=6)
    check_env_specs(grouped)  # TorchRL's rollout against the declared specs, nested done keys included
    size = 1 if task == "1v1" else 3
    assert grouped.group_map == {"team0": [f"blue_{i}" for i in range(size)], "team1": [f"red_{i}" for i in range(size)]}
    check_marl_grouping(grouped.group_map, [*grouped.group_map["team0"], *grouped.group_map["team1"]])
    assert ("team1", "done") in grouped.done_keys and ("team0", "_reset") in grouped.reset_keys
    grouped.set_seed(4)
    plain.set_seed(4)
    g_td, p_td = grouped.reset(), plain.reset()
    idx = {g: plain.team_index(t) for t, g in enumerate(("team0", "team1"))}
    torch.manual_seed(0)
    for t in range(8):
        action = torch.rand(3, plain.n_drones, 4) * 2 - 1
        for g, i in idx.items():
            torch.testing.assert_close(g_td.get((g, "observation")), p_td.get(OBS)[:, i])
            g_td.set((g, "action"), action[:, i])
        p_td.set(ACTION, action)
        g_td, g_next = grouped.step_and_maybe_reset(g_td)
        p_td, p_next = plain.step_and_maybe_reset(p_td)
        gn, pn = g_td.get("next"), p_td.get("next")
        for g, i in idx.items():
            torch.testing.assert_close(gn.get((g, "reward")), pn.get(REWARD)[:, i])
            for flag in ("done", "terminated", "truncated"):
                assert torch.equal(gn.get((g, flag)), pn.get(flag).unsqueeze(1).expand(3, len(i), 1))
        assert torch.equal(gn.get("done"), pn.get("done")) and bool(pn.get("done").any()) == (t == 5)
        g_td, p_td = g_next, p_next


def test_team_groups_refuse_what_has_no_teams():
    with pytest.raises(ValueError, match="group_map='teams' needs a match; task 'hover' has one team"):
        make_env("hover", 2, group_map="teams")
    with pytest.raises(ValueError, match=r"unknown group_map 'team'; allowed: \['agents', 'teams'\]"):
        make_env("1v1", 2, group_map="team")


def test_a_torchrl_marl_collector_runs_on_the_team_groups_unedited():
    """TorchRL's MARL tutorial pieces as they are: one MultiAgentMLP policy per group of env.group_map and
    its Collector; the batch has each group's agent-level flags and rewards."""
    from tensordict.nn import TensorDictModule, TensorDictSequential
    from torchrl.collectors import Collector
    from torchrl.modules import MultiAgentMLP

    torch.manual_seed(0)
    env = make_env("3v3", 4, group_map="teams", episode_len=10)
    policy = TensorDictSequential(*[
        TensorDictModule(torch.nn.Sequential(MultiAgentMLP(env.observation_spec[g, "observation"].shape[-1], 4, n_agents=len(agents),
                                                           centralised=False, share_params=True), torch.nn.Tanh()),
                         in_keys=[(g, "observation")], out_keys=[(g, "action")])
        for g, agents in env.group_map.items()])
    collector = Collector(env, policy, frames_per_batch=80, total_frames=80, auto_register_policy_transforms=False)
    batch = next(iter(collector))
    collector.shutdown()
    assert batch.batch_size == (4, 20) and batch["next", "team0", "reward"].shape == (4, 20, 3, 1)
    # episodes of 10 steps: every world ends at steps 10 and 20, all three drones of both teams at once
    done = batch["next", "team1", "done"][..., 0]
    assert done.all(-1).sum().item() == 8 and done.sum().item() == 24
    assert torch.equal(batch["next", "team0", "done"], batch["next", "team1", "done"])
