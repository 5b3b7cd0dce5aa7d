"""Loading generated modules and solving position, velocity and acceleration over time."""

from kinegen.runtime.results import Results
from kinegen.runtime.solver import Solver, SolverOptions, check_initial_pose, check_source, solve
from kinegen.runtime.system import NumericSystem, from_module, load_module

__all__ = ["NumericSystem", "Results", "Solver", "SolverOptions", "check_initial_pose", "check_source", "from_module", "load_module", "solve"]
