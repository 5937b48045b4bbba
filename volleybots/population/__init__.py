"""Populations of policies and the loop that grows them (docs/competitive.md).

Self-play, fictitious self-play and PSRO are one loop (OpenSpiel's psro_v2 shape): an oracle trains a
best response against the population's meta-strategy, the learner joins the population, the payoff
table gains a row and a column from games played, and a meta-solver recomputes the mixture.
"""
