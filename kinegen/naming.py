"""The generated module's file name: one rule for the builder and for everyone who looks a module up
(a command finds a model's module without importing the code generator)."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from kinegen.model import Model
    from kinegen.rotations import Parametrization


def module_name(model: Model, parametrization: Parametrization) -> str:
    """File stem of the generated module, e.g. ``boom_quaternion``."""
    return f"{model.name}_{parametrization.file_tag}"
