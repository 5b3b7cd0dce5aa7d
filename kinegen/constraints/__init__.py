"""Joint and driver equations, each written for at most two bodies."""

from kinegen.constraints.drivers import driver_equation
from kinegen.constraints.frames import GROUND_FRAME, Equation, Frame
from kinegen.constraints.joints import joint_equations

__all__ = ["GROUND_FRAME", "Equation", "Frame", "driver_equation", "joint_equations"]
