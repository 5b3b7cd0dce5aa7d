"""Typed errors raised by kinegen. Each carries a message meant for a person, and the exit code
the ``kinegen`` command ends with (:class:`ExitCode`, the one table of them)."""

from __future__ import annotations

import reprlib
from enum import IntEnum
from typing import Any


class ExitCode(IntEnum):
    """How the ``kinegen`` command ends: one code per kind of failure (docs/errors.md, "Errors and exit
    codes"). A subclass of an error shares its parent's code (an UnreachableError is a
    ConvergenceError); a BranchError shares 3 with a singular Phi_q: the motion cannot go on."""

    OK = 0
    ERROR = 1  #: any other kinegen error
    MODEL = 2  #: a malformed model, or a time function leaving its domain
    SINGULAR = 3  #: Phi_q singular, or a step that cannot be certified to continue the motion
    NO_CONVERGENCE = 4  #: Newton did not converge, the pose cannot be assembled or reached
    GENERATED_MODULE = 5  #: a generated module missing, stale, edited or foreign
    IO = 6  #: reading or writing a file failed
    COMPILE = 7  #: no usable C compiler, or the generated C did not compile
    EXPLORATION = 8  #: an exploration's output folder cannot be used as asked
    USAGE = 64  #: a command-line argument is wrong (sysexits' EX_USAGE)
    BROKEN_PIPE = 141  #: standard output's reader left early (128 + SIGPIPE), quietly


def bodies_in(combinations: list[str]) -> list[str]:
    """Bodies named in coordinate combinations such as ``upper.alpha - 0.5*upper.gamma``."""
    return sorted(
        {term.split("*")[-1].split(".")[0].lstrip("+- ") for combo in combinations for term in combo.split(" ") if "." in term}
    )


class KinegenError(Exception):
    """Base class of every error kinegen raises on purpose."""

    exit_code = ExitCode.ERROR


class RequestError(KinegenError, ValueError):
    """A request the model cannot answer as asked; ``option`` is the command line's option it
    concerns (``--load``, ``--case``, ...), ``problem`` what is wrong. The command line reports it
    as a usage error (exit 64)."""

    exit_code = ExitCode.USAGE

    def __init__(self, option: str, problem: str) -> None:
        self.option = option
        self.problem = problem
        super().__init__(f"{option}: {problem}")


class ModelError(KinegenError):
    """A model file is malformed: the message names the file, the line (where known), the
    entry (a dotted path such as ``joints.pivot.axis``) and the problem:
    ``models/boom.yaml:21: joints.pivot.axes: ...`` (the line as compilers print it)."""

    exit_code = ExitCode.MODEL

    def __init__(self, file: str, entry: str, problem: str, line: int | None = None) -> None:
        self.file = file
        self.line = line
        self.entry = _shortened(" ".join(entry.split()), 200)
        self.problem = _shortened(" ".join(problem.split()), 400)  # one line, whatever a parser's message held
        shown_file = printable(file)  # a file name may hold newlines and control characters
        where = shown_file if line is None else f"{shown_file}:{line}"
        super().__init__(f"{where}: {self.entry}: {self.problem}")


class OverConstrainedError(ModelError):
    """A model whose joints leave fewer degrees of freedom than its drivers (or its motors and
    hydraulic actuators) by count. ``stand_in``: a model of its bodies and joints, from which
    :func:`kinegen.symbolic.rank.explain` finds which joints' equations repeat each other (the
    command line and :class:`kinegen.api.Session` say it that way); ``count`` and ``what``: the
    elements the joints leave too little freedom for."""

    def __init__(self, file: str, entry: str, problem: str, line: int | None, stand_in: Any, count: int, what: str) -> None:
        super().__init__(file, entry, problem, line)
        self.stand_in, self.count, self.what = stand_in, count, what


class _BoundedRepr(reprlib.Repr):
    """``reprlib`` limits, plus integers shown by their size: ``repr`` of a 10,000-digit
    integer is quadratic work (and refused beyond Python's 4,300-digit limit)."""

    def repr_int(self, x: int, level: int) -> str:
        if x.bit_length() > 128:
            return f"<integer of {int(x.bit_length() * 0.30103) + 1} digits>"
        return super().repr_int(x, level)


_REPR = _BoundedRepr()
_REPR.maxlevel = 2
_REPR.maxdict = _REPR.maxlist = _REPR.maxtuple = _REPR.maxset = 4
_REPR.maxstring = _REPR.maxother = 80


def shown(value: Any) -> str:
    """A short ``repr`` of a value from a model file, bounded in the work it does as well as
    in its length: nested containers (which YAML aliases can make enormous when expanded)
    are cut after 2 levels and 4 items, strings after 80 characters, huge integers shown by
    their number of digits."""
    return _REPR.repr(value)


def printable(text: str) -> str:
    """``text`` with every character that is not printable (control characters, newlines, escape
    sequences a terminal would act on) shown as its Python escape, e.g. ``\\x1b``."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def _shortened(text: str, limit: int) -> str:
    """``text`` cut in the middle when longer than ``limit`` (a model may hold enormous values)."""
    if len(text) <= limit:
        return text
    return f"{text[: limit * 3 // 4]} …[{len(text)} characters]… {text[-limit // 8 :]}"


class ExpressionError(ValueError):
    """An expression string is not allowed (raised inside the parser, wrapped in ModelError)."""


class SingularJacobianError(KinegenError):
    """Phi_q is singular (rank-deficient) at time ``t``."""

    exit_code = ExitCode.SINGULAR

    def __init__(
        self,
        t: float,
        rank: int,
        size: tuple[int, int],
        dependent_constraints: list[str],
        null_space: list[str],
        detail: str = "",
    ) -> None:
        self.t = t
        self.rank = rank
        self.size = size
        self.dependent_constraints = dependent_constraints
        self.null_space = null_space
        self.bodies = bodies_in(null_space)
        lines = [
            f"singular Jacobian at t = {t:.6g}: rank {rank} of {size[0]}x{size[1]}" + (f" ({detail})" if detail else ""),
            "  dependent constraints: " + (", ".join(dependent_constraints) or "-"),
            "  null space (coordinates that move without changing Phi): " + ("; ".join(null_space) or "-"),
            "  bodies whose coordinates are in the null space: " + (", ".join(self.bodies) or "-"),
        ]
        super().__init__("\n".join(lines))


def _listed(worst: list[tuple[str, float]]) -> str:
    return ", ".join(f"{name} = {value:.3e}" for name, value in worst)


class ConvergenceError(KinegenError):
    """Newton-Raphson did not reach the tolerance within the iteration limit."""

    exit_code = ExitCode.NO_CONVERGENCE

    def __init__(
        self, t: float, iterations: int, residual: float, worst: list[tuple[str, float]], message: str | None = None
    ) -> None:
        self.t = t
        self.iterations = iterations
        self.residual = residual
        self.worst = worst
        super().__init__(
            message
            or f"Newton-Raphson did not converge at t = {t:.6g} after {iterations} iterations: "
            f"max |Phi| = {residual:.3e}; worst constraints: {_listed(worst)}"
        )


class UnreachableError(ConvergenceError):
    """No configuration satisfies Phi: the least-squares closest one leaves a residual."""

    def __init__(self, t: float, iterations: int, residual: float, worst: list[tuple[str, float]]) -> None:
        super().__init__(
            t, iterations, residual, worst,
            f"no configuration satisfies the constraints at t = {t:.6g}: the target is outside the workspace "
            f"(or, from a rough start, beyond a local minimum). The closest reachable configuration (least squares, "
            f"{iterations} iterations, joints kept assembled) leaves max |Phi| = {residual:.3e}; "
            f"constraints that cannot be met: {_listed(worst)}",
        )  # fmt: skip


class PrecisionError(ConvergenceError):
    """The tolerance is below what double precision resolves in the model's units: the residual
    left is the rounding of the coordinates themselves (a model measured in units far too small for
    its size: a 10^12 m boom in metres)."""

    def __init__(self, t: float, iterations: int, residual: float, rounding: float, largest: float, tolerance: float) -> None:
        super().__init__(
            t, iterations, residual, [],
            f"the constraints cannot be met to max |Phi| <= {tolerance:.1e} at t = {t:.6g}: rounding the coordinates alone "
            f"leaves about {rounding:.1e} (coordinates up to {largest:.3g}, which double precision resolves to "
            f"{largest * 2.2e-16:.1e}); {iterations} iterations reached max |Phi| = {residual:.3e}. Measure the model in larger "
            f"units, or raise the tolerance (SolverOptions.tolerance) above {10 * rounding:.1e}",
        )  # fmt: skip


class BranchError(KinegenError):
    """A step could not be certified to continue the solution, however small: a diagonal block
    of Phi_q changes its assembly mode (a toggle or dead point lies within the step) or the
    continuation bound fails (the inputs move faster than the solver can follow). ``observed``
    says which, with the figures."""

    exit_code = ExitCode.SINGULAR

    def __init__(self, t0: float, t1: float, step: float, observed: str = "") -> None:
        self.t0, self.t1, self.step, self.observed = t0, t1, step, observed
        self.t = t0  #: where the run stops (as the other solve errors' t)
        super().__init__(
            f"the solve cannot follow the motion from t = {t0:.6g} to t = {t1:.6g}: {observed}, even over a step of "
            f"{step:.2e} s; no row on another branch is returned: the run stops at t = {t0:.6g}"
        )


class UnassembledError(BranchError):
    """The motion asks for a pose the linkage cannot take: with the drivers at their values, no
    configuration closes every joint (a link too short or too long for the motion). Said in the
    mechanism's words first -- which joints' loop stays open and by how much -- then what the solver
    observed (``cause``). ``gaps``: (joint, how far it stays open: its points' distance [m] or, for a
    joint without point rows, its largest residual) at ``t1``; ``widest``: (time, total gap) the
    widest on the rest of the grid."""

    def __init__(self, t0: float, t1: float, inputs: str, gaps: list[tuple[str, float]], widest: tuple[float, float] | None,
                 cause: BranchError | ConvergenceError) -> None:  # fmt: skip
        self.gaps, self.widest, self.cause = gaps, widest, cause
        total = sum(g for _, g in gaps)
        names = [j for j, _ in gaps]
        loop = f"joint {names[0]} cannot close" if len(names) == 1 else f"the loop through joints {', '.join(names)} cannot close"
        later = f"; at t = {widest[0]:.6g} s, {widest[1]:.3g} m" if widest is not None and widest[1] > total else ""
        each = "" if len(gaps) == 1 else " (" + ", ".join(f"{j} {g:.2g}" for j, g in gaps) + ")"
        observed = (f"the linkage cannot assemble at t = {t1:.6g} s: with {inputs}, {loop} -- its points stay at least "
                    f"{total:.3g} m apart{each}{later}. A link is too short or too long for this motion, or the motion asks "
                    f"for a pose beyond the mechanism's reach. The solver saw: {cause}")  # fmt: skip
        KinegenError.__init__(self, observed)
        self.t0, self.t1, self.t = t0, t1, t0
        self.step = getattr(cause, "step", t1 - t0)
        self.observed = observed


class GeneratedModuleError(KinegenError):
    """A generated module is missing, stale or was not written by kinegen."""

    exit_code = ExitCode.GENERATED_MODULE


class ChangedFileError(GeneratedModuleError):
    """A generated file (module, C) whose bytes kinegen did not write: changed since it wrote it, or
    planted. Refused before anything in it runs, never rebuilt over silently (:mod:`kinegen.integrity`)."""


class AssemblyError(ConvergenceError):
    """The initial pose does not satisfy Phi and no assembled pose was found from it."""

    def __init__(self, t: float, residual: float, worst: list[tuple[str, float]], cause: str) -> None:
        self.cause = cause
        super().__init__(
            t, 0, residual, worst,
            f"initial pose cannot be assembled at t = {t:.6g}: max |Phi| = {residual:.3e} at the given pose; "
            f"largest residuals: {_listed(worst)}\n  assembly solve: {cause}",
        )  # fmt: skip
