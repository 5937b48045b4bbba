"""Packaging detail pyproject.toml cannot express: the top-level conf/ (design card) ships inside the
wheel as the package ``volleybots.conf`` so configs are found wherever volleybots is installed."""

from setuptools import find_packages, setup

setup(
    packages=find_packages(include=["volleybots", "volleybots.*"]) + ["volleybots.conf"],
    package_dir={"volleybots.conf": "conf"},
    # the zoo's weights-only checkpoints, a mixture's member files (<task>/<method>/*.pt, a hierarchical member's drills in
    # <task>/<method>/drills/) and their cards ship inside the package
    package_data={"volleybots.conf": ["**/*.yaml"], "volleybots": ["catalogue.json"], "volleybots.zoo": ["*/*.pt", "*/*/*.pt", "*/*/*/*.pt", "*/*.yaml"]},
)
