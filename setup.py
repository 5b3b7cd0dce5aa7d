"""Packages: kinegen's, plus the repository's models/ folder shipped as kinegen.models (package
data), so that the main job runs from an installed wheel. Everything else is in pyproject.toml."""

from setuptools import find_namespace_packages, setup

setup(packages=[*find_namespace_packages(include=["kinegen*"]), "kinegen.models"], package_dir={"kinegen.models": "models"})
