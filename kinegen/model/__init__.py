"""Model files: safe expression parsing, loading and validation."""

from kinegen.model.loader import ModelWarning, load, loads
from kinegen.model.schema import GROUND, Body, Case, DesignParameter, Driver, Joint, Model, PointRef

__all__ = ["GROUND", "Body", "Case", "DesignParameter", "Driver", "Joint", "Model", "ModelWarning", "PointRef", "load", "loads"]
