"""The serve recorder and the drills' ball bank (HCSP's stage III: drills fine-tuned on the serves they meet)."""

import pytest
import torch

import volleybots
from volleybots.config import load
from volleybots.play.serves import record_serves, write_bank
from volleybots.policies import resolve_competitor
from volleybots.tasks.drills import BANK_FORMAT, SERVE_BALL, read_ball_bank


@pytest.mark.slow  # plays 3v3 games
def test_recorded_serves_of_the_scripted_team_are_its_serve_as_the_drills_model_it():
    """The scripted 3v3 team serves in two touches; the recorder keeps the teammate's hit over, which
    the drills' ``SERVE_BALL`` models (from x -3.25..-3.05, z 2.6..2.8, at about (4.2, 0, 6.7) m/s), in
    the receiver's frame on either side."""
    cfg = load(["task=3v3"])
    receiver, server = resolve_competitor("zoo:3v3/hcsp_return"), resolve_competitor("scripted")
    balls = record_serves(cfg, receiver, server, 8, seed=3, batch=4)
    assert balls.shape == (8, 6)  # every scripted serve comes over
    (lo_x, _, lo_z), (hi_x, _, hi_z) = SERVE_BALL[0], SERVE_BALL[1]
    assert ((balls[:, 0] > lo_x - 0.1) & (balls[:, 0] < hi_x + 0.1)).all(), balls[:, 0]
    assert ((balls[:, 2] > lo_z - 0.1) & (balls[:, 2] < hi_z + 0.1)).all(), balls[:, 2]
    assert ((balls[:, 3] - 4.2).abs() < 0.3).all() and ((balls[:, 5] - 6.7).abs() < 0.4).all(), balls[:, 3:]
    # the same call, the same balls: seeded by its seed alone
    assert torch.equal(balls, record_serves(cfg, receiver, server, 8, seed=3, batch=4))


def test_a_drill_draws_its_serves_from_a_bank(tmp_path):
    balls = torch.tensor([[-5.0, 0.5, 2.2, 5.8, 0.0, 5.6], [-4.0, -1.0, 2.0, 5.0, 0.3, 6.0]])
    path = tmp_path / "bank.pt"
    write_bank(path, balls, source="test")
    assert torch.equal(read_ball_bank(path), balls)
    for name in ("attack", "pass"):
        env = volleybots.make_env(name, num_envs=64, seed=2, serves=0.5, serve_bank=str(path))
        env.reset()
        s = env.physics.state
        served = env.served
        assert 10 < int(served.sum()) < 54
        got = torch.cat((s.ball_pos[served], s.ball_vel[served]), -1)
        # every served ball is one of the bank's, and both are drawn
        match = (got.unsqueeze(1) - balls.unsqueeze(0)).abs().amax(-1) < 1e-5
        assert match.any(1).all() and match.any(0).all()
        assert not env.referee.may_hit[served, 0].any()  # the opponents' until it crosses


def test_a_bad_bank_is_one_line(tmp_path):
    bad = tmp_path / "bad.pt"
    torch.save({"format": BANK_FORMAT, "balls": torch.zeros(3, 5)}, bad)
    with pytest.raises(ValueError, match="is no ball bank"):
        read_ball_bank(bad)
    own = tmp_path / "own.pt"
    write_bank(own, torch.tensor([[1.0, 0.0, 2.0, 0.0, 0.0, 0.0]]))
    with pytest.raises(ValueError, match="not in the opponents' half"):
        read_ball_bank(own)
    with pytest.raises(ValueError, match="no readable ball bank"):
        read_ball_bank(tmp_path / "missing.pt")
