"""Analyses on top of the symbolic system and the runtime: exact inspection."""

from kinegen.analysis.inspect import Inspection, inspect

__all__ = ["Inspection", "inspect"]
