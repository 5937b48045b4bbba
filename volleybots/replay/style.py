"""The colours and names a recording and a still share (a leaf of the replay package)."""

from volleybots.keys import TEAM_NAMES  # noqa: F401 - the agents' names too (volleybots.tasks.groups)

TEAM_COLOURS = ((40, 110, 230), (225, 60, 50))  # team 0 (+x half) blue, team 1 (-x half) red
BALL_COLOUR = (250, 210, 40)
HIT_COLOUR, FAULT_COLOUR = (60, 220, 90), (240, 40, 40)
