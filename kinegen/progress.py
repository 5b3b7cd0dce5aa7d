"""Progress bars for long work (tqdm): on stderr, and only when stderr is a terminal -- a
pipe, a log file or a test sees nothing. The bars start no thread (tqdm's monitor, which only
retunes how often a bar redraws, is off): a build shares its printing with a forked process only
while no other thread runs (:func:`kinegen.codegen.forked.may_fork`)."""

from __future__ import annotations

import functools
import sys
from collections.abc import Iterable, Iterator
from typing import Any, TypeVar

T = TypeVar("T")


@functools.cache
def _bar() -> type:
    """tqdm's bar without its monitor thread."""
    from tqdm import tqdm

    class Bar(tqdm):
        monitor_interval = 0

    return Bar


def progress(items: Iterable[T], description: str, total: int | None = None, unit: str = "it") -> Iterator[T]:
    """``items``, with a bar while they are consumed (removed when done)."""
    yield from _bar()(items, desc=description, total=total, unit=unit, disable=None, leave=False, dynamic_ncols=True)


def counter(description: str, total: int, unit: str = "it", delay: float = 0.0, show: bool | None = None, leave: bool = False) -> Any:
    """A bar counted by hand (``update(n)``, then ``close()``, or as a context manager): for loops
    that advance in pieces. With ``delay`` (s) it appears only when the work lasts longer than that;
    ``show`` True/False forces it on/off (None: on a terminal); ``leave`` keeps its last line."""
    return _bar()(total=total, desc=description, unit=unit, disable=None if show is None else not show, leave=leave,
                dynamic_ncols=True, delay=delay)  # fmt: skip


class Stages:
    """A bar over named stages of one long job (a build, a benchmark): ``stage(name)`` finishes
    the last stage and names the next one; ``write(line)`` prints a line of results to stdout
    above the bar. Use as a context manager."""

    def __init__(self, description: str, count: int, unit: str = "stages") -> None:
        self.description = description
        self.bar = _bar()(total=count, desc=description, disable=None, leave=False, dynamic_ncols=True,
                        bar_format=f"{{desc}}[{{n}}/{{total}} {unit}, {{elapsed}}]")  # fmt: skip
        self.started = False

    def write(self, line: str) -> None:
        self.bar.write(line, file=sys.stdout)

    def stage(self, name: str) -> None:
        if self.started:
            self.bar.update(1)
        self.started = True
        self.bar.set_description(f"{self.description}: {name}")

    def __enter__(self) -> Stages:
        return self

    def __exit__(self, *_exc) -> None:
        self.bar.close()
