"""Settings of the Python backend."""

from pathlib import Path

#: File name suffix of the generated module.
SUFFIX = ".py"
#: Folder of the file skeletons (Jinja).
TEMPLATES = Path(__file__).with_name("templates")
#: Statements per function before it is split into parts (Python's compiler memory grows with it).
PART_STATEMENTS = 5000
#: Kernels that also get a plain-float function of one configuration (``math``, lists in and out:
#: several times faster than NumPy on one configuration, what a Newton step in Python calls).
SCALAR_KERNELS = ("phi_jac", "nu", "gamma")
