"""Model files: safe expression parsing, loading and validation."""

from kinegen.model.loader import ModelWarning, load, loads
from kinegen.model.schema import GROUND, Body, Case, Driver, Joint, Model, PointRef

__all__ = ["GROUND", "Body", "Case", "Driver", "Joint", "Model", "ModelWarning", "PointRef", "load", "loads"]
