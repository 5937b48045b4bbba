"""The referee from constructed states: debouncing, turns, violations, blame."""

import torch

from volleybots.rules import COURTS, Referee, RefereeConfig


def ref(n_drones=1, team=None, **kw):
    r = Referee(RefereeConfig(**kw), 1, team or [0] * n_drones)
    r.reset(torch.ones(1, dtype=torch.bool), torch.tensor([[4.5, 0.0, 4.0]]))
    return r


def step(r, pos, ball=(4.5, 0.0, 3.0), racket=None, body=None):
    d = r.n_drones
    pos = torch.tensor(pos, dtype=torch.float32).reshape(1, d, 3)
    racket = torch.tensor(racket or [False] * d).reshape(1, d)
    body = torch.tensor(body or [False] * d).reshape(1, d)
    return r.update(pos, torch.tensor([ball], dtype=torch.float32), racket, body)


def test_contact_spread_over_steps_counts_once():
    r = ref()
    p = [[4.5, 0.0, 2.0]]
    hits = [step(r, p, racket=[True]).hit.item() for _ in range(3)]
    assert hits == [True, False, False]  # one touch over 3 consecutive steps
    step(r, p)
    assert step(r, p, racket=[True]).hit.item() is False  # 2 steps since the last contact: still the same touch
    for _ in range(2):
        step(r, p)
    assert step(r, p, racket=[True]).hit.item() is True  # 3 steps since the last contact: a new touch


def test_second_touch_too_soon():
    r = ref(min_hit_gap=25)
    p = [[4.5, 0.0, 2.0]]
    assert not step(r, p, racket=[True]).too_soon.item()
    for _ in range(5):
        step(r, p)
    ev = step(r, p, racket=[True])
    assert ev.hit.item() and ev.too_soon.item() and ev.wrong_hit.item()
    for _ in range(30):
        step(r, p)
    ev = step(r, p, racket=[True])
    assert ev.hit.item() and not ev.too_soon.item()


def test_body_hit_is_wrong_hit_racket_is_not():
    r = ref()
    ev = step(r, [[4.5, 0.0, 2.0]], body=[True])
    assert ev.body_hit.item() and ev.wrong_hit.item() and not ev.racket_hit.item()
    r = ref()
    ev = step(r, [[4.5, 0.0, 2.0]], racket=[True])
    assert ev.racket_hit.item() and not ev.wrong_hit.item()


def test_alternate_turns():
    r = ref(2, turns="alternate")
    p = [[4.5, -2.5, 2.0], [4.5, 2.5, 2.0]]
    assert r.may_hit.tolist() == [[True, False]]
    ev = step(r, p, racket=[True, False])
    assert not ev.wrong_turn.any()
    assert r.may_hit.tolist() == [[False, True]]
    for _ in range(4):
        step(r, p)
    ev = step(r, p, racket=[True, False])  # drone 0 again: wrong turn
    assert ev.wrong_turn.tolist() == [[True, False]]


def test_sequence_turns_then_nobody():
    r = ref(2, turns="sequence", order=(0, 1))
    p = [[2.0, -2.5, 2.5], [2.0, 2.5, 3.5]]
    step(r, p, racket=[True, False])
    for _ in range(4):
        step(r, p)
    ev = step(r, p, racket=[False, True])
    assert not ev.wrong_turn.any()
    assert not r.may_hit.any()
    for _ in range(4):
        step(r, p)
    assert step(r, p, racket=[True, False]).wrong_turn[0, 0].item()


def test_possession_one_touch_each_and_server_first():
    r = Referee(RefereeConfig(court=COURTS["3v3"], turns="possession"), 1, [0, 0, 0, 1, 1, 1])
    r.reset(torch.ones(1, dtype=torch.bool), torch.tensor([[6.0, 0.0, 5.0]]), first=torch.tensor([2]))
    pos = [[3, -1.5, 2], [3, 1.5, 2], [6, 0, 2], [-3, 1.5, 2], [-3, -1.5, 2], [-6, 0, 2]]
    assert r.may_hit.tolist() == [[False, False, True, False, False, False]]
    assert step(r, pos, ball=(6, 0, 2.3), racket=[True, False, False, False, False, False]).wrong_turn[0, 0].item()
    r.reset(torch.ones(1, dtype=torch.bool), torch.tensor([[6.0, 0.0, 5.0]]), first=torch.tensor([2]))
    ev = step(r, pos, ball=(6, 0, 2.3), racket=[False, False, True, False, False, False])
    assert not ev.wrong_turn.any()
    assert r.may_hit.tolist() == [[True, True, False, False, False, False]]
    for _ in range(4):
        step(r, pos, ball=(3, 0, 3))
    step(r, pos, ball=(3, 0, 3), racket=[True, False, False, False, False, False])
    assert r.may_hit.tolist() == [[False, True, False, False, False, False]]
    ev = step(r, pos, ball=(-1, 0, 3))  # the ball crosses: team 1's possession
    assert ev.ball_crossed.item()
    assert r.may_hit.tolist() == [[False, False, False, True, True, True]]


def test_drone_violations():
    r = ref(2, team=[0, 1], drone_min_z=0.4, drone_max_z=5.0)
    ev = step(r, [[0.1, 0.0, 1.0], [0.5, 0.0, 5.5]])
    assert ev.drone_net.tolist() == [[True, False]]
    assert ev.drone_cross.tolist() == [[False, True]]  # team 1 belongs on -x
    assert ev.drone_high.tolist() == [[False, True]]
    ev = step(r, [[3.0, 0.0, 0.3], [-3.0, 0.0, 2.0]])
    assert ev.drone_low.tolist() == [[True, False]] and not ev.drone_net.any() and not ev.drone_cross.any()
    ev = step(r, [[0.1, 0.0, 3.0], [-3.0, 0.0, 2.0]])  # above the net top: no net touch
    assert not ev.drone_net.any()


def test_ball_violations_and_out_modes():
    r = ref()
    assert step(r, [[4.5, 0, 2]], ball=(0.2, 0.0, 2.0)).ball_net.item()
    assert not step(r, [[4.5, 0, 2]], ball=(0.2, 0.0, 2.6)).ball_net.item()
    assert step(r, [[4.5, 0, 2]], ball=(10.0, 0.0, 3.0)).ball_out.item()  # any height
    r = ref(out_at_any_height=False)
    assert not step(r, [[4.5, 0, 2]], ball=(10.0, 0.0, 3.0)).ball_out.item()
    ev = step(r, [[4.5, 0, 2]], ball=(10.0, 0.0, 0.1))
    assert ev.ball_out.item() and ev.ball_landed.item() and ev.landed_side.item() == -1
    ev = step(r, [[4.5, 0, 2]], ball=(-3.0, 0.0, 0.1))
    assert ev.landed_side.item() == 1 and not ev.ball_out.item()


def test_outcome_blame_and_draw():
    r = Referee(RefereeConfig(court=COURTS["1v1"], turns="alternate"), 1, [0, 1])
    r.reset(torch.ones(1, dtype=torch.bool), torch.tensor([[1.5, 0.0, 3.5]]))
    pos = [[1.5, 0, 2], [-1.5, 0, 2]]
    ev = step(r, pos, ball=(1.5, 0, 2.2), racket=[True, False])
    assert r.outcome(ev).winner.item() == -1
    ev = step(r, pos, ball=(0.1, 0, 1.5))  # team 0 hit it into the net
    out = r.outcome(ev)
    assert out.winner.item() == 1 and Referee.FAULTS[out.reason.item()] == "ball_net"
    ev = step(r, [[-0.5, 0, 2], [0.5, 0, 2]], ball=(1.0, 0, 3))  # both cross: draw
    out = r.outcome(ev)
    assert out.draw.item() and out.winner.item() == -1 and out.ended.item()
    ev = step(r, pos, ball=(-1.0, 0, 0.1))  # lands in team 1's half
    out = r.outcome(ev)
    assert out.winner.item() == 0 and Referee.FAULTS[out.reason.item()] == "landed"
