"""The video frames of ``render_mode="rgb_array"`` (issue 55): drawn into pixels in milliseconds, with a
ball marker where the ball projects and a header whose score follows the match; the vector envs
render their first world, so SB3's ``VecVideoRecorder`` records them."""

from __future__ import annotations

import numpy as np
import pytest

from volleybots.integrations import VolleyGymEnv, VolleyParallelEnv, VolleyVectorEnv
from volleybots.integrations.match_env import VolleyMatchVectorEnv
from volleybots.replay.raster import HEADER, HEIGHT, WIDTH, View, draw_frame
from volleybots.replay.style import BALL_COLOUR, TEAM_COLOURS


def test_the_ball_marker_is_where_the_ball_projects():
    env = VolleyGymEnv("solo_bump", render_mode="rgb_array")
    env.reset(seed=3)
    for _ in range(10):
        env.step(np.zeros(4, np.float32))
    frame = env.render()
    assert frame.shape == (HEIGHT, WIDTH, 3) and frame.dtype == np.uint8
    trail = env._trail
    ball = trail.ball[-1]
    c, r = np.rint(trail._view.project(ball)).astype(int)
    assert 0 <= c < WIDTH and HEADER <= r < HEIGHT
    assert tuple(frame[r, c]) == BALL_COLOUR  # the marker's centre, drawn on top of everything
    # the drone's square, in its team's colour, where the drone projects
    drone = np.rint(trail._view.project(trail.pos[-1][0])).astype(int)
    assert tuple(frame[drone[1], drone[0]]) == TEAM_COLOURS[0]


def test_the_camera_is_one_projection():
    view = View((6.0, 3.0, 2.43))
    corners = view.project([[3.0, 1.5, 0.0], [-3.0, -1.5, 0.0], [0.0, 0.0, 2.43]])
    assert ((corners[:, 0] > 0) & (corners[:, 0] < WIDTH) & (corners[:, 1] > HEADER) & (corners[:, 1] < HEIGHT)).all()
    assert view.project([0.0, 0.0, 2.0])[1] < view.project([0.0, 0.0, 0.0])[1]  # up is up on the screen
    pos, ball = np.zeros((1, 1, 3)), np.array([[0.0, 0.0, 3.0]])
    frame = draw_frame(view, pos, ball, (0,))
    c, r = np.rint(view.project(ball[0])).astype(int)
    assert tuple(frame[r, c]) == BALL_COLOUR


def test_the_score_region_follows_the_score():
    env = VolleyParallelEnv("1v1", render_mode="rgb_array")
    env.reset(seed=0)
    before = env.render()
    assert "blue 0 - 0 red" in env._trail.header("1v1")
    env._trail.end({"winner": 1.0})  # red wins a rally
    env._trail.end({"winner": -1.0})  # a draw: no point
    after = env.render()
    assert env._trail.points == [0, 1] and "blue 0 - 1 red" in env._trail.header("1v1")
    assert not np.array_equal(before[:HEADER], after[:HEADER])  # the score's pixels changed
    np.testing.assert_array_equal(before[HEADER:], after[HEADER:])  # and nothing else did


def test_a_match_vector_env_tallies_world_0s_points():
    env = VolleyMatchVectorEnv("1v1", 4, opponent="scripted", render_mode="rgb_array", seed=2)
    env.reset(seed=2)
    rng, won = np.random.default_rng(0), [0, 0]
    for _ in range(150):
        _, _, term, trunc, info = env.step(rng.uniform(-1, 1, (env.num_envs, 4)).astype(np.float32))
        if term[0] or trunc[0]:
            winner = int(info["final_stats"]["winner"][0])
            won[winner] += winner in (0, 1)
            assert len(env._trail.ball) == 1  # the next episode's trail begins at its first state
    assert env._trail.points == won
    [frame] = env.render()
    assert frame.shape == (HEIGHT, WIDTH, 3)


@pytest.mark.parametrize("mode", ["same_step", "next_step"])
def test_the_vector_env_renders_its_first_world(mode):
    env = VolleyVectorEnv("hover", 3, render_mode="rgb_array", autoreset_mode=mode, episode_len=5)
    assert env.metadata["render_fps"] == 50 and "rgb_array" in env.metadata["render_modes"]
    env.reset(seed=0)
    for _ in range(12):  # past two episode ends of every world
        env.step(np.zeros((3, 4), np.float32))
        assert 1 <= len(env._trail.ball) <= 6
    [frame] = env.render()
    assert frame.shape == (HEIGHT, WIDTH, 3) and frame.dtype == np.uint8
    assert VolleyVectorEnv("hover", 2).render() is None


def test_sb3_vec_video_recorder_records_the_vector_envs(tmp_path):
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("moviepy")
    from stable_baselines3.common.vec_env import VecVideoRecorder

    from volleybots.integrations import VolleyMatchSB3VecEnv, VolleySB3VecEnv

    for name, venv in (("single", VolleySB3VecEnv("solo_bump", 2, render_mode="rgb_array")),
                       ("match", VolleyMatchSB3VecEnv("1v1", 2, opponent="scripted", render_mode="rgb_array"))):
        rec = VecVideoRecorder(venv, str(tmp_path / name), record_video_trigger=lambda s: s == 0, video_length=6, name_prefix=name)
        rec.reset()
        frame = rec.render()
        assert frame.shape == (HEIGHT, WIDTH, 3) and frame.dtype == np.uint8
        for _ in range(4):
            rec.step(np.zeros((venv.num_envs, 4), np.float32))
        assert len(rec.recorded_frames) == 5 and all(f.shape == (HEIGHT, WIDTH, 3) for f in rec.recorded_frames)
        rec.close()  # writes the video of the frames so far
        [video] = list((tmp_path / name).glob("*.mp4"))
        assert video.stat().st_size > 1000
    with pytest.raises(ValueError, match="without render_mode='rgb_array'"):
        VolleySB3VecEnv("hover", 2).get_images()
