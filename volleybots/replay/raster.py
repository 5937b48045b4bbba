"""A video frame of an episode so far, drawn directly into pixels (Pillow's C drawing on a fixed
orthographic view): the court and net, each drone's path and where it is now in its team colour, the
ball's flight with its touches and faults, a ball marker where the ball is, and a header with the
task, the step, the score of a match (points of the rallies the env played) or the task's metric.

Why not the replay's still (``still.still_frame``, matplotlib's 3D axes): a matplotlib frame costs
about 70 ms, so a video of one episode took a minute and recording during training was out of the
question. Here the court and net, which never move, are drawn once into a background (``View``) and
each frame copies it and draws the paths and markers on top: a few milliseconds a frame
(``benchmarks/speed/render_frame.py`` measures both). The still stays for ``replay --still``, where
its axes and legend are worth the time.

``View.project`` is the camera: a world point (m) to its pixel (column, row), the same orthographic
projection for every element, so a test can find the ball marker where the ball projects.
"""

from __future__ import annotations

import math

import numpy as np

from volleybots.replay.style import BALL_COLOUR, FAULT_COLOUR, HIT_COLOUR, TEAM_COLOURS, TEAM_NAMES

WIDTH, HEIGHT = 640, 368  # even sides, as video encoders want (the still's frame size, kept for old videos)
HEADER = 26  # pixel rows of the header (task, step, score) above the court
ELEV, AZIM = 22.0, -62.0  # the still's view (degrees): from above the +x, -y corner, looking at the court
TOP = 6.0  # m of height the view keeps room for: above the net and a bump's apex (4.5 m); higher balls leave the frame
PAD = 0.5  # m around the court's lines
BALL_RADIUS = 6  # px of the ball marker
DRONE_HALF = 5  # px, half the side of a drone's square


def _light(c, k: float = 0.55) -> tuple[int, int, int]:
    """``c`` blended towards white by ``k`` (a path or a tinted half: lighter than the marker it leads to)."""
    return tuple(int(round(x + (255 - x) * k)) for x in c)


class View:
    """The camera and the background of one court (``court``: length, width, net height in m)."""

    def __init__(self, court: tuple[float, float, float], width: int = WIDTH, height: int = HEIGHT):
        self.court, self.width, self.height = tuple(float(x) for x in court), int(width), int(height)
        e, a = math.radians(ELEV), math.radians(AZIM)
        # orthographic camera: screen right and screen up as world directions (the eye looks along -forward)
        self.right = np.array([-math.sin(a), math.cos(a), 0.0])
        self.up = np.array([-math.sin(e) * math.cos(a), -math.sin(e) * math.sin(a), math.cos(e)])
        length, width_m, _ = self.court
        lx, ly = length / 2 + PAD, width_m / 2 + PAD
        box = np.array([[x, y, z] for x in (-lx, lx) for y in (-ly, ly) for z in (0.0, TOP)])
        u, v = box @ self.right, box @ self.up
        margin = 8  # px between the box and the frame's edges
        self.scale = min((self.width - 2 * margin) / np.ptp(u), (self.height - HEADER - 2 * margin) / np.ptp(v))
        self.u0 = (self.width - self.scale * (u.max() + u.min())) / 2
        self.v0 = HEADER + margin + self.scale * v.max() + ((self.height - HEADER - 2 * margin) - self.scale * np.ptp(v)) / 2
        self.background = self._background()

    def project(self, p) -> np.ndarray:
        """World points [..., 3] (m) to pixels [..., 2] (column, row; row 0 at the top), as floats."""
        p = np.asarray(p, dtype=np.float64)
        return np.stack([self.u0 + self.scale * (p @ self.right), self.v0 - self.scale * (p @ self.up)], -1)

    def _xy(self, pts) -> list[tuple[float, float]]:
        return [tuple(q) for q in self.project(pts).tolist()]

    def _background(self):
        """The court, its halves tinted in the defending team's colour, the centre line and the net."""
        from PIL import Image, ImageDraw

        length, width_m, net = self.court
        lx, ly = length / 2, width_m / 2
        img = Image.new("RGB", (self.width, self.height), (255, 255, 255))
        draw = ImageDraw.Draw(img)
        for team, sign in ((0, 1.0), (1, -1.0)):
            half = [(0, -ly, 0), (sign * lx, -ly, 0), (sign * lx, ly, 0), (0, ly, 0)]
            draw.polygon(self._xy(half), fill=_light(TEAM_COLOURS[team], 0.88))
        draw.line(self._xy([(-lx, -ly, 0), (lx, -ly, 0), (lx, ly, 0), (-lx, ly, 0), (-lx, -ly, 0)]), fill=(115, 115, 115), width=2)
        draw.line(self._xy([(0, -ly, 0), (0, ly, 0)]), fill=(115, 115, 115), width=1)
        draw.polygon(self._xy([(0, -ly, 0), (0, ly, 0), (0, ly, net), (0, -ly, net)]), fill=(218, 218, 218), outline=(170, 170, 170))
        draw.line(self._xy([(0, -ly, net), (0, ly, net)]), fill=(77, 77, 77), width=2)
        return img


def _finite(path: np.ndarray) -> np.ndarray:
    return path[np.isfinite(path).all(-1)]


def draw_frame(view: View, pos: np.ndarray, ball: np.ndarray, teams, hits=(), faults=(), header: str = "") -> np.ndarray:
    """The frame of an episode so far as an RGB array [H, W, 3] uint8.

    Args:
        view: the court's camera and background.
        pos: drone positions [T, D, 3] over the steps so far (the last row is now).
        ball: ball positions [T, 3] (NaN rows: no ball in the task; nothing drawn).
        teams: each drone's team.
        hits: the steps of touches (green markers on the ball's path).
        faults: the steps of faults (red markers).
        header: the text of the header line (task, step, score).
    """
    from PIL import ImageDraw

    img = view.background.copy()
    draw = ImageDraw.Draw(img)
    seen = _finite(ball)
    if len(seen) > 1:
        shadow = seen.copy()
        shadow[:, 2] = 0.0
        draw.line(view._xy(shadow), fill=(200, 200, 200), width=1)  # the ball's track on the floor
    for d, team in enumerate(teams):
        colour = TEAM_COLOURS[int(team) % len(TEAM_COLOURS)]
        if len(pos) > 1:
            draw.line(view._xy(pos[:, d]), fill=_light(colour), width=1)
    if len(seen) > 1:
        draw.line(view._xy(seen), fill=BALL_COLOUR, width=2)
    for steps, colour in ((hits, HIT_COLOUR), (faults, FAULT_COLOUR)):
        for (c, r) in view.project(_finite(ball[list(steps)])).tolist() if len(steps) else []:
            draw.ellipse((c - 3, r - 3, c + 3, r + 3), fill=colour, outline=(0, 0, 0))
    for d, team in enumerate(teams):  # the drones where they are now
        c, r = view.project(pos[-1, d]).tolist()
        draw.rectangle((c - DRONE_HALF, r - DRONE_HALF, c + DRONE_HALF, r + DRONE_HALF),
                       fill=TEAM_COLOURS[int(team) % len(TEAM_COLOURS)], outline=(0, 0, 0))
    if np.isfinite(ball[-1]).all():  # the ball marker last: on top of everything, where the ball is now
        c, r = view.project(ball[-1]).tolist()
        draw.ellipse((c - BALL_RADIUS, r - BALL_RADIUS, c + BALL_RADIUS, r + BALL_RADIUS), fill=BALL_COLOUR, outline=(0, 0, 0))
    if header:
        draw.text((8, 6), header, fill=(20, 20, 20), font=_font())
    return np.asarray(img)


def score_text(points) -> str:
    """A match's score line, team 0 first: ``blue 2 - 1 red``."""
    return f"{TEAM_NAMES[0]} {int(points[0])} - {int(points[1])} {TEAM_NAMES[1]}"


_FONT = None


def _font():
    """Pillow's built-in font at a readable size (loaded once: loading costs more than a frame)."""
    global _FONT
    if _FONT is None:
        from PIL import ImageFont

        try:
            _FONT = ImageFont.load_default(size=15)
        except TypeError:  # Pillow < 10.1 has one bitmap size
            _FONT = ImageFont.load_default()
    return _FONT


__all__ = ["HEIGHT", "WIDTH", "View", "draw_frame", "score_text"]
