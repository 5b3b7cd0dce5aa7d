"""Settings of the C backend."""

from pathlib import Path

#: Folder of the file skeletons (Jinja).
TEMPLATES = Path(__file__).with_name("templates")
#: Folder of the runtime's sources, copied verbatim into a standalone directory.
SOLVER = Path(__file__).with_name("solver")
RUNTIME = ("kinegen_solver.h", "kinegen_solver.c")
#: Statements per C function before it is split into parts (compile time grows faster than linearly with a function's length).
PART_STATEMENTS = 250
#: Flags of the standalone Makefile / CMakeLists.txt and of the runtime's compiled library.
CFLAGS = "-std=c99 -O2 -Wall -Wextra -pedantic"
