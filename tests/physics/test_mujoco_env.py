"""Every task runs on the MuJoCo backend with the same specs as on torch; the contact tuning holds."""

import math

import mujoco
import pytest
import torch
from torchrl.envs.utils import check_env_specs

import volleybots
from volleybots.physics import WorldParams
from volleybots.physics.mujoco_backend import build_model, solref_for, unilateral_restitution
from volleybots.tasks import TASKS

pytestmark = pytest.mark.mujoco


def test_check_env_specs_on_mujoco():
    env = volleybots.make_env("solo_bump", num_envs=3, physics="mujoco", seed=1)
    check_env_specs(env)


@pytest.mark.parametrize("task", sorted(TASKS))
def test_task_runs_on_mujoco_like_on_torch(task):
    envs = {b: volleybots.make_env(task, num_envs=2, physics=b, action_space="ctbr", seed=3) for b in ("torch", "mujoco")}
    tds = {b: e.reset() for b, e in envs.items()}
    # same seed, same reset: the backends start from the same observation
    assert torch.allclose(tds["torch"]["agents", "observation"], tds["mujoco"]["agents", "observation"], atol=1e-5)
    action = envs["torch"].full_action_spec.zero()
    for b, env in envs.items():
        td = tds[b].update(action)
        for _ in range(3):
            td = env.step(td)
            obs = td["next", "agents", "observation"]
            assert obs.shape == (2, env.n_drones, env.obs_dim) and torch.isfinite(obs).all()
            td = td["next"].update(action)
        tds[b] = td
    # three steps of flight without contact: the observations still agree closely
    assert torch.allclose(tds["torch"]["agents", "observation"], tds["mujoco"]["agents", "observation"], atol=1e-3)


def test_solref_inverts_the_unilateral_restitution():
    for e in (0.5, 0.8, 0.9):
        k, b = solref_for(e)
        zeta = -b / (2 * math.sqrt(-k))
        assert unilateral_restitution(zeta) == pytest.approx(e, abs=1e-6)
    # the release before the spring is back at rest makes the bounce livelier than exp(-pi zeta / ...)
    z = 0.1
    assert unilateral_restitution(z) > math.exp(-math.pi * z / math.sqrt(1 - z * z))


def bounce(model, speed, gap):
    """Speed ratio of the ball hitting the held drone's racket (no gravity), starting ``gap`` above it."""
    model.opt.gravity[:] = 0.0
    d = mujoco.MjData(model)
    p = WorldParams()
    d.qpos[:3] = (0.0, 0.0, 2.0)
    d.qpos[7:10] = (0.0, 0.0, 2.0 + p.drone.racket_offset + p.ball.radius + gap)
    d.qvel[8] = -speed
    hold = d.qpos[:7].copy()
    for _ in range(200):
        mujoco.mj_step(model, d)
        d.qpos[:7], d.qvel[:6] = hold, 0.0  # an immovable racket
        if d.qvel[8] > 0 and d.ncon == 0:
            break
    return d.qvel[8] / speed


@pytest.mark.parametrize("speed", [2.0, 6.0])
def test_racket_restitution_on_the_sub_step(speed):
    """Averaged over where in a sub-step the contact begins, the racket's restitution is 0.8 at any speed."""
    model = build_model(WorldParams(), 1)
    h = model.opt.timestep
    es = [bounce(model, speed, speed * h * (k + 0.5) / 8) for k in range(8)]
    assert sum(es) / len(es) == pytest.approx(0.8, abs=0.02)
    assert max(es) - min(es) < 0.08


def test_optional_net_stops_the_ball():
    from volleybots.physics.mujoco_backend import MujocoPhysics

    p = WorldParams()
    hover = torch.tensor(p.drone.hover_command).expand(1, 1, 4)
    end_x = {}
    for net in (None, (9.0, 2.43)):
        ph = MujocoPhysics(p, 1, 1, net=net)
        m = torch.ones(1, dtype=torch.bool)
        ph.set_state(
            m, pos=torch.tensor([[[5.0, 0.0, 2.0]]]), ball_pos=torch.tensor([[-1.0, 0.0, 1.5]]), ball_vel=torch.tensor([[6.0, 0.0, 3.0]])
        )
        for _ in range(15):  # 0.3 s: the ball reaches x = 0 after 0.15 s, below the net top
            ph.step(lambda s: hover)
        end_x[net is not None] = ph.state.ball_pos[0, 0].item()
    assert end_x[False] > 0.5  # without a net it flies on to the other side
    assert end_x[True] < -0.1  # the net sends it back


def test_rollout_pool_follows_torch_threads_and_never_changes_results():
    """The pool defaults to torch's thread count; any pool size (0: the calling thread) steps alike."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        env = volleybots.make_env("3v3", num_envs=6, physics="mujoco", seed=3)
    finally:
        torch.set_num_threads(before)
    assert env.physics.nthread == 1 and len(env.physics.datas) == 1
    finals = []
    for nthread in (0, 1, 3):
        env.physics.set_threads(nthread)
        assert env.physics.nthread == nthread and len(env.physics.datas) == max(nthread, 1)
        env.set_seed(3)
        td = env.reset()
        torch.manual_seed(0)
        for _ in range(10):
            td = env.step(td.update(env.full_action_spec.rand()))["next"]
        finals.append(env.physics.state.pos.clone())
    assert torch.equal(finals[0], finals[1]) and torch.equal(finals[0], finals[2])
