"""The stack a C function can use, from gcc's call graph (``-fcallgraph-info=su``: every function's
frame and every call it makes): the deepest chain of frames from an entry point, and a
recursion found on the way. Calls through pointers (the generated kernels) lead to
``__indirect_call`` and count nothing; add the largest kernel's frame to bound them."""

from __future__ import annotations

import re
from pathlib import Path


class CallGraph:
    """Frames [bytes] and calls of the functions of one or more ``.ci`` files (gcc's VCG output)."""

    def __init__(self, *files: str | Path) -> None:
        self.frames: dict[str, int] = {}
        self.calls: dict[str, set[str]] = {}
        for file in files:
            for line in Path(file).read_text().splitlines():
                if node := re.match(r'node: \{ title: "([^"]+)" label: "[^"]*\\n(\d+) bytes', line):
                    self.frames[node.group(1)] = int(node.group(2))
                elif edge := re.match(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"', line):
                    self.calls.setdefault(edge.group(1), set()).add(edge.group(2))
        self._deepest: dict[str, int] = {}

    def functions(self, prefix: str) -> list[str]:
        """The functions whose name (without its file) starts with ``prefix``."""
        return [name for name in self.frames if name.split(":")[-1].startswith(prefix)]

    def deepest(self, name: str, path: tuple[str, ...] = ()) -> int:
        """The largest sum of frames along a chain of calls from ``name`` [bytes]; ValueError on a
        recursion (a function reached again through its own calls)."""
        if name in path:
            raise ValueError(f"recursion: {' -> '.join((*path, name))}")
        if name not in self._deepest:
            below = (self.deepest(callee, (*path, name)) for callee in self.calls.get(name, ()))
            self._deepest[name] = self.frames.get(name, 0) + max(below, default=0)
        return self._deepest[name]
