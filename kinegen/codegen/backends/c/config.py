"""Settings of the C backend."""

import re
from pathlib import Path

#: Folder of the file skeletons (Jinja).
TEMPLATES = Path(__file__).with_name("templates")
#: Folder of the runtime's sources, copied verbatim into a standalone directory.
SOLVER = Path(__file__).with_name("solver")
RUNTIME = ("kinegen_solver.h", "kinegen_solver.c", "kinegen_interval.h")
#: A body's velocity coordinates at most for the C solver's pin reactions (its KINEGEN_MAX_BODY_COORDINATES, read
#: from its source: one statement of the bound).
MAX_BODY_COORDINATES = int(re.search(r"^#define KINEGEN_MAX_BODY_COORDINATES (\d+)$", (SOLVER / "kinegen_solver.c").read_text(), re.MULTILINE).group(1))
#: Statements per C function before it is split into parts (compile time grows faster than linearly with a function's length).
PART_STATEMENTS = 250
#: Statements of section functions per part of a model's C compiled apart (in parallel) by the runtime.
FILE_STATEMENTS = 2000
#: Flags of the standalone Makefile / CMakeLists.txt and of the runtime's compiled library.
CFLAGS = "-std=c99 -O2 -Wall -Wextra -pedantic"


def source_parts(text: str) -> list[int]:
    """The values of ``KINEGEN_PART`` a generated ``<stem>.c`` is split by (empty: compile it whole)."""
    return sorted({int(k) for k, _ in _PART.findall(text)})


def sensitivity_parts(text: str) -> list[int]:
    """Those of :func:`source_parts` that only the sensitivity kernels need (``-DKINEGEN_NO_SENSITIVITIES``
    leaves them out, with those kernels and their table entries in part 0)."""
    return sorted({int(k) for k, without in _PART.findall(text) if without})


def has_sensitivity_parts(text: str) -> bool:
    """Whether :func:`sensitivity_parts` is not empty, by a plain search (a model's C is megabytes:
    the pattern's scan took 15 ms on the excavator's, at every case a solve sets up)."""
    return _SENSITIVITY_GUARD in text


_SENSITIVITY_GUARD = ") && !defined(KINEGEN_NO_SENSITIVITIES)\n"


_PART = re.compile(r"^#if \(?!defined\(KINEGEN_PART\) \|\| KINEGEN_PART == (\d+)(\) && !defined\(KINEGEN_NO_SENSITIVITIES\))?$", re.MULTILINE)
