"""Packages: kinegen's, plus the repository's models/ folder shipped as kinegen.models and its
generated/ folder as kinegen.generated (package data), so that the main job runs from an installed
wheel without building its modules again. Everything else is in pyproject.toml."""

from setuptools import find_namespace_packages, setup

setup(packages=[*find_namespace_packages(include=["kinegen*"]), "kinegen.models", "kinegen.generated"],
      package_dir={"kinegen.models": "models", "kinegen.generated": "generated"})
