"""The hierarchical 3v3 policy (scripted/hierarchical.py): the high level's assignment for each event
on constructed states, the events read from observations, games in which the team never touches
twice in a row with one drone, the competitor seam (3v3 only, trained drills from a YAML file), and
the decision log of replays."""

import pytest
import torch
from helpers import FakeRec
from tensordict import TensorDict
from torchrl.envs.utils import step_mdp
from typer.testing import CliRunner

import volleybots
from volleybots.cli import app
from volleybots.config import ConfigError
from volleybots.policies import BUILTIN, hierarchical_member, resolve_competitor
from volleybots.replay import EpisodeRecorder
from volleybots.scripted.hierarchical import ATTACK, DRILL_LABELS, HOVER, PASS, SERVE, SET, HighLevel
from volleybots.scripted.policies import SCRIPTED_POLICIES
from volleybots.tasks import TASKS
from volleybots.tasks.drills import BACK, FRONT_LEFT, FRONT_RIGHT
from volleybots.tasks.multi import TeamPolicies

N = 64
ALL = torch.ones(N, dtype=torch.bool)


def high_level():
    return HighLevel(N, "cpu", torch.Generator().manual_seed(0))


def row(*drills):
    return torch.tensor(drills).expand(N, 3)


def test_serve_gives_the_back_drone_serve_and_the_others_hover():
    h = high_level()
    serving = torch.arange(N) % 2 == 0
    h.on_rally(ALL, serving)
    assert torch.equal(h.drill[serving], row(HOVER, HOVER, SERVE)[serving])
    assert torch.equal(h.drill[~serving], row(HOVER, HOVER, HOVER)[~serving])
    h.on_own_touch(serving, torch.full((N,), BACK))  # the serve is made: everyone hovers
    assert (h.drill == HOVER).all()


def test_opponent_hit_first_and_second_touch():
    h = high_level()
    h.on_rally(ALL, torch.zeros(N, dtype=torch.bool))
    h.on_opponent_hit(ALL)
    assert torch.equal(h.drill, row(HOVER, HOVER, PASS))
    h.on_own_touch(ALL, torch.full((N,), BACK))  # the pass
    assert torch.equal(h.drill, row(SET, HOVER, HOVER))
    h.on_own_touch(ALL, torch.full((N,), FRONT_LEFT))  # the set
    assert torch.equal(h.drill, row(HOVER, ATTACK, HOVER))
    assert 0 < int(h.side.sum()) < N  # a random side, both drawn
    h.on_own_touch(ALL, torch.full((N,), FRONT_RIGHT))  # the attack
    assert (h.drill == HOVER).all()
    h.on_opponent_hit(ALL)  # a new possession: the back drone may pass again
    assert torch.equal(h.drill, row(HOVER, HOVER, PASS))


def test_a_touch_goes_to_a_drone_that_has_not_touched():
    h = high_level()
    h.on_opponent_hit(ALL)
    h.on_own_touch(ALL, torch.full((N,), FRONT_LEFT))  # the front-left took the first ball
    assert torch.equal(h.drill, row(HOVER, SET, HOVER))  # so the front-right sets
    h.on_own_touch(ALL, torch.full((N,), FRONT_RIGHT))
    assert torch.equal(h.drill, row(HOVER, HOVER, ATTACK))  # and the back attacks


def parts_of(ball, vel, may, turn, opponents_near=False):
    """A team's observation parts [N, 3, size] for a constructed state (own team at its anchors)."""
    anchors = torch.tensor(((3.0, -1.5, 2.0), (3.0, 1.5, 2.0), (6.0, 0.0, 2.0)))
    pos = anchors.expand(N, 3, 3)
    opp = ball.unsqueeze(1) + torch.tensor(((0.0, 0.0, -0.2), (2.0, 0, 0), (3.0, 0, 0))) if opponents_near else -anchors.expand(N, 3, 3)
    positions = torch.cat((pos, opp.expand(N, 3, 3)), 1).flatten(1).unsqueeze(1).expand(N, 3, 18)
    flag = lambda f: torch.stack((f.float(), 1.0 - f.float()), -1)  # noqa: E731
    root = torch.cat((pos, torch.zeros(N, 3, 20)), -1)
    return {
        "root": root,
        "anchor": torch.zeros(N, 3, 3),
        "ball": ball.unsqueeze(1) - pos,
        "ball_vel": vel.unsqueeze(1).expand(N, 3, 3),
        "turn": flag(turn).unsqueeze(1).expand(N, 3, 2),
        "id": torch.eye(3).expand(N, 3, 3),
        "may_hit": flag(may),
        "positions": positions,
    }


def test_events_are_read_from_observations():
    h = high_level()
    dt_g = torch.tensor((0.0, 0.0, -9.81 * 0.02))
    ball = torch.tensor((6.0, 0.0, 5.0)).expand(N, 3)
    may = torch.tensor((False, False, True)).expand(N, 3)
    # a new rally: the ball at rest over the own back drone, the team's turn
    h.update(parts_of(ball, torch.zeros(N, 3), may, torch.ones(N, dtype=torch.bool)))
    assert torch.equal(h.drill, row(HOVER, HOVER, SERVE))
    # free flight: no event
    h.update(parts_of(ball, dt_g.expand(N, 3), may, torch.ones(N, dtype=torch.bool)))
    assert torch.equal(h.drill, row(HOVER, HOVER, SERVE))
    # the serve: the back drone's may-hit flag falls, the ball jumps
    h.update(
        parts_of(ball, torch.tensor((-5.0, 0.0, 7.0)).expand(N, 3), torch.zeros(N, 3, dtype=torch.bool), torch.ones(N, dtype=torch.bool))
    )
    assert (h.drill == HOVER).all()
    # an opponent (next to the ball, on its side) hits it back
    far = torch.tensor((-3.0, 0.0, 2.7)).expand(N, 3)
    h.update(
        parts_of(
            far, torch.tensor((-4.0, 0.0, -5.0)).expand(N, 3), torch.zeros(N, 3, dtype=torch.bool), torch.zeros(N, dtype=torch.bool), True
        )
    )
    h.update(
        parts_of(
            far, torch.tensor((4.0, 0.0, 6.0)).expand(N, 3), torch.zeros(N, 3, dtype=torch.bool), torch.zeros(N, dtype=torch.bool), True
        )
    )
    assert torch.equal(h.drill, row(HOVER, HOVER, PASS))


def touches(env, policies, steps, n):
    """Play ``steps`` steps of a 3v3 match; per env the touches (drone, drill code) of the first rally."""
    pol = TeamPolicies(env, policies)
    td = env.reset()
    seq = [[] for _ in range(n)]
    over = torch.zeros(n, dtype=torch.bool)
    for _ in range(steps):
        td = pol(td)
        codes = td["agents", "drill"].clone()
        td = env.step(td)
        hit = env.last_events.hit
        for i, k in torch.nonzero(hit & ~over.unsqueeze(1)).tolist():
            seq[i].append((k, int(codes[i, k]), bool(env.last_events.wrong_hit[i, k])))
        over |= td["next", "done"].reshape(-1)
        if over.all():
            break
        td = step_mdp(td, keep_other=True, exclude_action=True)
    return seq


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_hierarchical_team_never_touches_twice_in_a_row_with_one_drone():
    torch.manual_seed(0)
    n = 6
    env = volleybots.make_env("3v3", num_envs=n, seed=2, serve=1)  # the scripted team serves: the hierarchical team must rally
    hier = resolve_competitor("hierarchical").team_policy(env)
    seq = touches(env, (hier, resolve_competitor("scripted").team_policy(env)), 500, n)
    own = [[(k, c) for k, c, wrong in s if k < 3] for s in seq]
    assert sum(map(len, own)) >= 2 * n  # rallies happened
    for s in seq:
        drones = [k for k, _, _ in s]
        assert all(a != b for a, b in zip(drones, drones[1:], strict=False)), s
        assert not any(wrong for k, _, wrong in s if k < 3), s  # no wrong-turn or too-soon touches of its own
    # each touch was made by the drone the high level had given that drill: pass by the back, set by the front-left, ...
    label = {BACK: {"pass", "serve"}, FRONT_LEFT: {"set"}, FRONT_RIGHT: {"attack left", "attack right"}}
    made = [(k, DRILL_LABELS[c]) for s in own for k, c in s]
    assert sum(lab in label[k] for k, lab in made) >= 0.8 * len(made), made
    assert any(len(s) >= 3 for s in own)  # a whole pass, set, attack


def test_hierarchical_is_a_3v3_competitor_only():
    assert "hierarchical" in BUILTIN
    comp = resolve_competitor("hierarchical")
    comp.check_fits("3v3", "prt", 57)
    with pytest.raises(ConfigError, match="3v3"):
        comp.check_fits("1v1", "prt", 39)
    env = volleybots.make_env("1v1", num_envs=2)
    with pytest.raises(ConfigError, match="3v3"):
        comp.team_policy(env)
    out = CliRunner().invoke(app, ["train", "task=1v1", "opponent=hierarchical"])
    assert out.exit_code == 2 and "3v3" in out.stderr and len(out.stderr.strip().splitlines()) == 1


def test_trained_drills_from_a_yaml_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(
        app,
        [
            "train",
            "task=attack",
            "algo=ppo",
            "total_frames=512",
            "env.num_envs=8",
            "threads=1",
            "progress=false",
            "evaluation.every=0",
            "evaluation.episodes=2",  # the final evaluation is not under test: 2 unrecorded episodes, not 16 recorded
            "evaluation.record=false",
            "task.episode_len=50",  # ... of 50 steps
            "algo.minibatches=1",  # the run dir is what the team reads: one small gradient step
            "algo.epochs=1",
            "algo.hidden=[16]",
            "checkpoint.every=0",
        ],
    )
    assert res.exit_code == 0, res.output
    run = next(p for p in tmp_path.rglob("config.yaml")).parent
    drills = tmp_path / "team.yaml"
    drills.write_text(f"hierarchical:\n  attack: {run}\n")
    comp = resolve_competitor(f"mine={drills}")
    assert comp.label == "mine" and comp.members[0].source["drills"] == {"attack": str(run)}
    env = volleybots.make_env("3v3", num_envs=2, seed=0)
    policy = comp.team_policy(env)
    low = policy.policies[0].lows
    assert type(low["attack"]).__name__ != "AttackPlayer" and type(low["set"]).__name__ == "SetPlayer"
    td = TeamPolicies(env, (policy, policy))(env.reset())
    assert torch.isfinite(td["agents", "action"]).all()
    bad = tmp_path / "bad.yaml"
    bad.write_text(f"hierarchical:\n  spike: {run}\n")
    with pytest.raises(ConfigError, match="spike"):
        resolve_competitor(str(bad)).team_policy(env)
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text(f"hierarchical:\n  serve: {run}\n")  # an attack checkpoint for the serve
    with pytest.raises(ConfigError, match="attack"):
        resolve_competitor(str(wrong)).team_policy(env)


def test_replay_logs_the_high_levels_decisions():
    torch.manual_seed(0)
    env = volleybots.make_env("3v3", num_envs=2, seed=0, serve=0)
    comp = hierarchical_member()
    pol = TeamPolicies(env, (comp.make(env), resolve_competitor("random").team_policy(env)))
    rec = FakeRec()
    recorder = EpisodeRecorder(rec, env, env_index=0)
    td = env.reset()
    for _ in range(3):
        td = pol(td)
        td = env.step(td)
        recorder(env, td, td["next"])
        td = step_mdp(td, keep_other=True, exclude_action=True)
    recorder.flush()  # the recorder sends its columns when the episode ends or on flush
    texts = [str(t.text.as_arrow_array().to_pylist()[0]) for t in rec.at("decisions")]
    assert "step 0: drone 2 -> serve" in texts and "step 0: drone 0 -> hover" in texts
    assert len(texts) == 3  # logged when a drill changes, not every step; the other team is not driven
    assert len(rec.at("drill/drone_2")) == 3 and not rec.at("drill/drone_3")


def one_drone_actions(policy, obs: torch.Tensor) -> torch.Tensor:
    """A drill policy's actions [n, 4] for one drone's observations [n, obs] (n envs of the drill)."""
    n = obs.shape[0]
    out = policy(TensorDict({"agents": TensorDict({"observation": obs.unsqueeze(1)}, [n, 1])}, [n]))
    return (out if isinstance(out, torch.Tensor) else out["agents", "action"]).reshape(n, -1)


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_a_trained_drill_drives_its_drone_on_the_drill_observation(tmp_path):
    """A team with a trained Serve: while the back drone serves, its action is the checkpoint policy's
    mean action on the Serve observation built from its match observation by part names (also where
    the team is asked for sampled play), not the scripted serve's; the other drones hover as scripted."""
    torch.set_num_threads(1)
    res = CliRunner().invoke(
        app,
        [
            "train",
            "task=serve",
            "algo=bc",
            "total_frames=512",
            "env.num_envs=8",
            "algo.steps_per_batch=64",
            "threads=1",
            "progress=false",
            "evaluation.every=0",
            "evaluation.episodes=2",
            "evaluation.record=false",
            "task.episode_len=50",  # the drill's policy is under test, not its final evaluation: keep that short
            "checkpoint.every=0",
            f"hydra.run.dir={tmp_path / 'serve'}",
        ],
    )
    assert res.exit_code == 0, res.output
    n = 4
    env = volleybots.make_env("3v3", num_envs=n, seed=0, serve=0)  # team 0 serves: its back drone plays the Serve
    ckpt = resolve_competitor(str(tmp_path / "serve")).members[0].make(volleybots.make_env("serve", num_envs=n), True)
    scripted_serve, hover = (SCRIPTED_POLICIES[d]("prt", env.params) for d in ("serve", "hover"))
    team = hierarchical_member({"serve": str(tmp_path / "serve")}).make(env, False)
    pol = TeamPolicies(env, (team, resolve_competitor("random").team_policy(env)))
    layout, serve_layout, hover_layout = env.layout, *(TASKS[d].obs_layout(env.with_throttle) for d in ("serve", "hover"))
    td = env.reset()
    for _ in range(3):
        obs = td["agents", "observation"][:, :3].clone()  # team 0: drones 0-2 are front-left, front-right, back
        td = pol(td)
        assert (td["agents", "drill"][:, :3] == torch.tensor([1, 1, 2])).all()  # hover, hover, serve
        parts = layout.split(obs[:, BACK])
        drill_obs = serve_layout.build(**{k: parts[k] for k in serve_layout.names})
        got = td["agents", "action"][:, BACK]
        torch.testing.assert_close(got, one_drone_actions(ckpt, drill_obs))
        assert (got - one_drone_actions(scripted_serve, drill_obs)).abs().max() > 1e-3  # the checkpoint, not the scripted serve
        front = layout.split(obs[:, FRONT_LEFT])
        hover_obs = hover_layout.build(root=front["root"], target=front["anchor"])
        torch.testing.assert_close(td["agents", "action"][:, FRONT_LEFT], one_drone_actions(hover, hover_obs))
        td = env.step(td)
        td = step_mdp(td, keep_other=True, exclude_action=True)


def test_a_chooser_may_call_the_receiver_only_for_a_ball_coming_to_the_own_half():
    """The 3v3 scripted team serves with a toss to itself: with ``receive_coming`` the toss calls no
    receiver, the hit over does; without it (the rules) the toss does."""
    from volleybots.scripted.hierarchical import RuleChooser

    class Coming(RuleChooser):
        receive_coming = True

    nobody = torch.zeros(N, 3, dtype=torch.bool)
    theirs = torch.zeros(N, dtype=torch.bool)
    ball = torch.tensor((-3.0, 0.0, 2.7)).expand(N, 3)
    toss = torch.tensor((-1.0, 0.0, 6.0)).expand(N, 3)  # comes down in their own half
    over = torch.tensor((4.2, 0.0, 6.7)).expand(N, 3)  # comes down 2.5 m behind our side of the net
    for chooser, after_toss in ((Coming(), HOVER), (None, PASS)):
        h = HighLevel(N, "cpu", chooser=chooser)
        h.update(parts_of(ball, torch.zeros(N, 3), nobody, theirs, True))  # a new rally, their serve
        h.update(parts_of(ball, toss, nobody, theirs, True))
        assert (h.drill[:, BACK] == after_toss).all()
        h.update(parts_of(ball, over, nobody, theirs, True))
        assert (h.drill[:, BACK] == PASS).all()


def test_a_chooser_may_have_a_front_drone_return_the_ball_at_once():
    """With ``receive_attack`` a front drone called to receive plays the attack drill on the side the
    chooser picks among its own two, and its touch ends the possession; the back drone still passes."""
    from volleybots.scripted.hierarchical import RuleChooser

    class FrontReturns(RuleChooser):
        receive_attack = True

        def __call__(self, kind, feats, legal, mask):
            if kind == "receive":  # even envs: the front-right receives; odd: the back
                return torch.where(torch.arange(feats.shape[0]) % 2 == 0, FRONT_RIGHT, BACK)
            if kind == "attack" and bool(mask.any()):  # the receiver's own two sides only
                assert (legal.sum(1)[mask] == 2).all() and legal[mask][:, 2 * FRONT_RIGHT:2 * FRONT_RIGHT + 2].all()
            return super().__call__(kind, feats, legal, mask)

    h = HighLevel(N, "cpu", torch.Generator().manual_seed(0), chooser=FrontReturns(torch.Generator().manual_seed(1)))
    h.on_rally(ALL, torch.zeros(N, dtype=torch.bool))
    h.on_opponent_hit(ALL)
    even = torch.arange(N) % 2 == 0
    assert torch.equal(h.drill[even], row(HOVER, ATTACK, HOVER)[even])
    assert torch.equal(h.drill[~even], row(HOVER, HOVER, PASS)[~even])
    assert 0 < int(h.side[even].sum()) < int(even.sum())  # both sides chosen
    h.on_own_touch(ALL, torch.where(even, FRONT_RIGHT, BACK))
    assert (h.drill[even] == HOVER).all()  # the return ends the possession
    assert torch.equal(h.drill[~even], row(SET, HOVER, HOVER)[~even])
