"""The env contract: specs, sizes, determinism, partial reset, and the single-drone tasks' logic."""

import pytest
import torch
from torchrl.envs.utils import check_env_specs

import volleybots
from volleybots.tasks import TASKS

SINGLE = ["hover", "back_and_forth", "hit_the_ball", "solo_bump"]
OBS = {"hover": (26, 22), "back_and_forth": (26, 22), "hit_the_ball": (32, 28), "solo_bump": (32, 28)}


@pytest.mark.parametrize("action_space", ["prt", "ctbr", "discrete"])
@pytest.mark.parametrize("task", SINGLE)
def test_specs_and_observation_sizes(task, action_space):
    env = volleybots.make_env(task, num_envs=3, action_space=action_space)
    check_env_specs(env)
    td = env.reset()
    prt, ctbr = OBS[task]
    assert td["agents", "observation"].shape == (3, 1, ctbr if action_space == "ctbr" else prt)
    act = env.action_spec["agents", "action"]
    if action_space == "discrete":
        assert act.shape == (3, 1) and act.space.n == 16
    else:
        assert act.shape == (3, 1, 4)


def test_make_env_rejects_bad_names():
    with pytest.raises(ValueError, match="allowed: .*solo_bump"):
        volleybots.make_env("solo_bumb")
    with pytest.raises(ValueError, match="'prt', 'ctbr', 'discrete'"):
        volleybots.make_env("hover", action_space="rpm")
    with pytest.raises(ValueError, match="allowed: .*torch"):
        volleybots.make_env("hover", physics="bullet")
    with pytest.raises(ValueError, match="allowed: .*iris"):
        volleybots.make_env("hover", drone="nope")


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_ten_thousand_random_steps_stay_finite():
    env = volleybots.make_env("solo_bump", num_envs=64, seed=3)
    td = env.reset()
    for _ in range(10_000 // 64 * 4):  # 625 steps x 64 envs = 40k env-steps
        td = env.rand_action(td)
        out, td = env.step_and_maybe_reset(td)
        assert torch.isfinite(out["next", "agents", "observation"]).all()
        assert torch.isfinite(out["next", "agents", "reward"]).all()
    s = env.physics.state
    for v in s.tensors().values():
        assert torch.isfinite(v).all()


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("task", SINGLE)
def test_random_rollouts_finite_every_task(task):
    env = volleybots.make_env(task, num_envs=16, action_space="ctbr", seed=1)
    td = env.rollout(200, break_when_any_done=False)
    assert torch.isfinite(td["next", "agents", "observation"]).all()
    assert torch.isfinite(td["next", "agents", "reward"]).all()


def rollout_obs(seed):
    env = volleybots.make_env("solo_bump", num_envs=8, seed=seed)
    torch.manual_seed(seed)
    return env.rollout(60, break_when_any_done=False)["next", "agents", "observation"]


def test_same_seed_same_trajectory():
    a, b, c = rollout_obs(5), rollout_obs(5), rollout_obs(6)
    assert torch.equal(a, b)
    assert not torch.equal(a, c)


def test_partial_reset_leaves_other_envs_untouched():
    env = volleybots.make_env("solo_bump", num_envs=4, seed=0)
    td = env.reset()
    for _ in range(10):
        td = env.rand_step(td)["next"].exclude("agents", "stats").update({"agents": {"action": env.action_spec.rand()["agents", "action"]}})
    before = {k: v.clone() for k, v in env.physics.state.tensors().items()}
    t_before = env.t.clone()
    mask = torch.tensor([False, True, False, True]).unsqueeze(-1)
    out = env.reset(td.update({"_reset": mask}))
    after = env.physics.state.tensors()
    keep = ~mask.squeeze(-1)
    for k in before:
        assert torch.equal(after[k][keep], before[k][keep]), k
    assert not torch.equal(after["ball_pos"][~keep], before["ball_pos"][~keep])
    assert torch.equal(env.t[keep], t_before[keep]) and (env.t[~keep] == 0).all()
    assert torch.allclose(out["agents", "observation"][~keep][:, 0, 2], after["pos"][~keep][:, 0, 2])


def test_truncation_at_episode_limit_is_not_termination():
    env = volleybots.make_env("hover", num_envs=2, episode_len=7, target=(0.0, 0.0, 2.0))
    td = env.reset()
    hover = torch.tensor(env.params.drone.hover_command).expand(2, 1, 4)
    for i in range(7):
        td["agents", "action"] = hover.clone()
        td = env.step(td)
        nxt = td["next"]
        if i < 6:
            assert not nxt["done"].any()
        td = nxt
    assert td["truncated"].all() and not td["terminated"].any() and td["done"].all()
    assert (td["stats", "episode_len"] == 7).all()


def test_reward_shaping_switch_removes_shaping_terms():
    on = volleybots.make_env("solo_bump", num_envs=4, seed=0)
    off = volleybots.make_env("solo_bump", num_envs=4, seed=0, reward_shaping=False)
    torch.manual_seed(0)
    a = on.rollout(5, break_when_any_done=False)
    torch.manual_seed(0)
    b = off.rollout(5, break_when_any_done=False)
    ra, rb = a["next", "agents", "reward"], b["next", "agents", "reward"]
    shaping = a["next", "stats", "r_dist_to_ball"][:, -1] + a["next", "stats", "r_ball_height"][:, -1]
    assert (shaping > 0).all()
    assert torch.allclose(ra.sum(1).squeeze(-1).squeeze(-1) - rb.sum(1).squeeze(-1).squeeze(-1), shaping.squeeze(-1), atol=1e-4)


def test_registry_has_single_drone_tasks():
    assert set(SINGLE) <= set(TASKS)


# ------------------------------------------------------------------------ task logic from constructed states

@pytest.mark.parametrize("stay,bonus", [(2.5, 0.0), (0.0, 50.0)])
def test_back_and_forth_counts_stays_and_swaps_target(stay, bonus):
    env = volleybots.make_env("back_and_forth", num_envs=1, stay_reward=stay, target_reward=bonus)
    td = env.reset()
    hover = torch.tensor(env.params.drone.hover_command).expand(1, 1, 4)
    reached = []
    for target in [(9.0, 4.5, 2.0), (4.5, 0.0, 2.0), (9.0, 4.5, 2.0)]:
        for _ in range(5):
            env.place_drones(torch.ones(1, dtype=torch.bool), torch.tensor(target).expand(1, 1, 3))
            td = env.step(td.set(("agents", "action"), hover.clone()))["next"]
        reached.append(td["stats", "targets"].item())
    assert reached == [1.0, 2.0, 3.0]
    assert td["stats", "r_target_stay"].item() == pytest.approx(15 * stay)
    assert td["stats", "r_target_reached"].item() == pytest.approx(3 * bonus)  # paid on the step a stay completes


def test_hit_the_ball_distance_from_ballistic_crossing():
    env = volleybots.make_env("hit_the_ball", num_envs=1)
    td = env.reset()
    hover = torch.tensor(env.params.drone.hover_command).expand(1, 1, 4)
    mask = torch.ones(1, dtype=torch.bool)
    # pretend the drone has hit once: ball leaves (4.5, 0, 2.3) at (-6, 0, 5) m/s
    env.referee.hits[:] = 0
    env.referee.hits[0, 0] = 1
    env.place_ball(mask, (4.5, 0.0, 2.3), (-6.0, 0.0, 5.0))
    env.referee.prev_ball_x[:] = 4.5
    env.prev_ball[:] = torch.tensor([4.5, 0.0, 2.3])
    for _ in range(200):
        td = env.step(td.set(("agents", "action"), hover.clone()))["next"]
        if td["done"].item():
            break
    # ballistic: z = 2.3 + 5 t - 4.905 t^2 = 2 -> t = 1.0777 s; x = 4.5 - 6 t
    t = (5 + (25 + 4 * 4.905 * 0.3) ** 0.5) / (2 * 4.905)
    assert td["terminated"].item()
    assert td["stats", "distance"].item() == pytest.approx(6 * t, abs=0.05)
    assert td["stats", "r_distance"].item() == pytest.approx(2 * 6 * t, abs=0.1)


def _solo_bump_past_apex(apex, hit_ok, **task):
    """One step of two Solo Bump envs whose bumps are just past their apex ``apex`` [2], struck where
    ``hit_ok`` [2] says (within 1 m of the anchor or not); returns the step's stats."""
    env = volleybots.make_env("solo_bump", num_envs=2, **task)
    td = env.reset()
    everyone = torch.ones(2, dtype=torch.bool)
    env.pending[:] = True
    env.hit_ok[:] = torch.tensor(hit_ok)
    env.apex[:] = torch.tensor(apex)
    env.place_ball(everyone, (4.5, 0.0, 2.9), (0.0, 0.0, -0.1))
    env.place_drones(everyone, torch.tensor([4.5, 0.0, 2.0]).expand(2, 1, 3))
    hover = torch.tensor(env.params.drone.hover_command).expand(2, 1, 4)
    return env.step(td.set(("agents", "action"), hover.clone()))["next"]["stats"]


def test_solo_bump_counts_successful_apex_only():
    stats = _solo_bump_past_apex([4.0, 3.0], [True, True])  # apex 4.0 (success) and 3.0 (too low)
    assert stats["bumps"].squeeze(-1).tolist() == [1.0, 0.0]
    assert stats["r_success_height"].squeeze(-1).tolist() == [8.0, 0.0]


@pytest.mark.parametrize("strict,paid", [(False, [8.0, 8.0]), (True, [8.0, 0.0])])
def test_solo_bump_strict_bumps_pays_only_the_bumps_the_metric_counts(strict, paid):
    # two apexes of 4 m: the first bump struck at the anchor, the second more than 1 m away from it
    stats = _solo_bump_past_apex([4.0, 4.0], [True, False], strict_bumps=strict)
    assert stats["bumps"].squeeze(-1).tolist() == [1.0, 0.0]
    assert stats["r_success_height"].squeeze(-1).tolist() == paid


def _solo_bump_starts(**task):
    env = volleybots.make_env("solo_bump", num_envs=2000, seed=3, **task)
    env.reset()
    pos = env.physics.state.pos[:, 0]
    return pos, (pos[:, :2] - torch.tensor([4.5, 0.0])).norm(dim=-1)


def test_solo_bump_far_starts_draw_the_openings_far_from_the_ball():
    box_lo, box_hi = torch.tensor([4.0, -0.5, 1.8]), torch.tensor([5.0, 0.5, 2.2])
    pos, off = _solo_bump_starts()
    assert 0.18 < float((off >= 0.5).float().mean()) < 0.25  # the spec's box: 1 - pi / 4 of it
    pos_far, off_far = _solo_bump_starts(far_starts=1.0)
    assert bool((off_far >= 0.5 - 1e-5).all()) and bool(((pos_far >= box_lo) & (pos_far <= box_hi)).all())
    assert torch.equal(pos_far[:, 2], pos[:, 2])  # the heights come from the same draws
    _, off_half = _solo_bump_starts(far_starts=0.5)
    assert 0.55 < float((off_half >= 0.5).float().mean()) < 0.66  # half far, half from the whole box
