"""Printing a kernel description as C: ``<stem>.h`` / ``<stem>.c`` (the model: kernels of every
case, their factorization plans, names, points, actuators), and for the standalone target the
runtime (``kinegen_solver.h/.c``), a ``Makefile``, a ``CMakeLists.txt`` and ``example_main.c``.

Every section is one straight-line ``static`` function (split into parts of at most
:data:`config.PART_STATEMENTS` statements, which keeps compile time linear in the model's
size); a case's kernels call the sections in turn. C99 and ``math.h`` only.

A large model's ``<stem>.c`` is still one file that compiles whole, but its section functions
are grouped under ``#if !defined(KINEGEN_PART) || KINEGEN_PART == k`` (k = 1, 2, ...; the
tables and kernels under k = 0), so that the runtime compiles the parts in parallel
(:func:`config.source_parts`); the grouped functions then have external linkage and the stem as prefix.
The sections only the sensitivity kernels (phi_p, dvel, dacc, frames_d, points_p:
:data:`kinegen.interface.SENSITIVITY_ONLY`) call come in groups of their own,
last, which ``-DKINEGEN_NO_SENSITIVITIES`` leaves out with those kernels and their table entries
(:func:`config.sensitivity_parts`): the runtime's first library compiles without them, and the
sensitivities' library when they are first asked for.
"""

from __future__ import annotations

import bisect
import itertools
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import sympy as sp
from sympy.printing.codeprinter import CodePrinter

import kinegen.codegen.backends.c.config as config
from kinegen.codegen.backends.c.printer import CPrinter
from kinegen.codegen.intervals import IntervalProgram
from kinegen.codegen.kernels import Enclosure, Kernel, ModuleDescription, Plan, Zeros
from kinegen.codegen.shapes import Block, Group, Printing, eliminate
from kinegen.codegen.sharing import SharedTexts
from kinegen.codegen.templates import environment
from kinegen.integrity import c_string
from kinegen.interface import SENSITIVITY_ONLY
from kinegen.model.expressions import T
from kinegen.symbolic import engine

TEXT = 1  # position of the printed text in a Block's temporaries (after the name)


@dataclass
class _Function:
    """One generated C function for a template macro."""

    name: str
    params: list[str]
    prologue: list[str] = field(default_factory=list)
    statements: list[str] = field(default_factory=list)
    doc: str = ""
    static: bool = True
    sensitivity: bool = False  #: only the sensitivity kernels need it: left out under KINEGEN_NO_SENSITIVITIES


def _parameter(slot: str) -> str:
    return "double t" if slot == "t" else f"const double *{slot}"


def _int_array(values) -> str:
    values = list(values)
    return "{" + ", ".join(str(int(v)) for v in values) + "}" if values else "{0}"


def _unpermuted(col_order) -> list[str]:
    """x[col_order[j]] = y[j] for every position j, written out six to a line: a written solve's last
    statements (its loop over col_order read an index a value: 4 % of the excavator's step)."""
    stores = [f"x[{int(c)}] = y[{j}];" for j, c in enumerate(col_order)]
    return [" ".join(stores[k : k + 6]) for k in range(0, len(stores), 6)]


def _string_array(values) -> str:
    values = list(values)
    return "{" + ", ".join(c_string(v) for v in values) + "}" if values else "{0}"


def _double(value: float) -> str:
    value = float(value)
    if not np.isfinite(value):
        return "NAN" if np.isnan(value) else ("INFINITY" if value > 0 else "-INFINITY")
    text = repr(value)
    return text if any(c in text for c in ".en") else text + ".0"


def _double_array(values) -> str:
    values = list(values)
    return "{" + ", ".join(_double(v) for v in values) + "}" if values else "{0.0}"


@dataclass(frozen=True)
class _PlanArrays:
    """A case's plan as the arrays of ``kinegen_model``."""

    block_start: list[int]
    block_store: list[int]
    n_store: int
    row_order: list[int]
    col_order: list[int]
    diag_value: list[int]
    diag_slot: list[int]
    off_start: list[int]
    off_col: list[int]
    off_value: list[int]


def plan_arrays(rows: tuple[int, ...], cols: tuple[int, ...], plan: Plan, name: str) -> _PlanArrays:
    """Where each value of a matrix given at the pattern (``rows``, ``cols``) goes (a case's Phi_q,
    the statics' matrix ``name``): into a diagonal block's dense storage (column-major) or, below
    the blocks, into the list of its permuted row."""
    n = len(plan.row_order)
    position_of_row = [0] * n
    position_of_col = [0] * n
    for i, r in enumerate(plan.row_order):
        position_of_row[r] = i
    for j, c in enumerate(plan.col_order):
        position_of_col[c] = j
    block_of = [0] * n
    stores, offset = [], 0
    for b, (start, end) in enumerate(zip(plan.block_start, plan.block_start[1:])):
        for i in range(start, end):
            block_of[i] = b
        stores.append(offset)
        offset += (end - start) ** 2
    diag_value, diag_slot = [], []
    below: list[list[tuple[int, int]]] = [[] for _ in range(n)]
    for k, (r, c) in enumerate(zip(rows, cols)):
        i, j = position_of_row[r], position_of_col[c]
        b = block_of[i]
        if block_of[j] == b:
            start, size = plan.block_start[b], plan.block_start[b + 1] - plan.block_start[b]
            diag_value.append(k)
            diag_slot.append(stores[b] + (i - start) + (j - start) * size)
        elif block_of[j] < b:
            below[i].append((j, k))
        else:  # pragma: no cover -- block_triangular guarantees a lower block-triangular form
            raise ValueError(f"{name}: entry ({r}, {c}) above the block diagonal")
    off_start, off_col, off_value = [0], [], []
    for entries in below:
        for j, k in sorted(entries):
            off_col.append(j)
            off_value.append(k)
        off_start.append(len(off_col))
    return _PlanArrays(list(plan.block_start), stores, offset, list(plan.row_order), list(plan.col_order),
                       diag_value, diag_slot, off_start, off_col, off_value)  # fmt: skip


#: the largest plan whose block solve the C backend writes out straight-line (operations: its blocks'
#: n^2 values, the values below them and its n rows); a larger one is solved by the solver's loop
STRAIGHT_SOLVE_LIMIT = 50_000


def straight_solve(arrays: _PlanArrays) -> tuple[list[list[str]], list[list[str]], list[int]] | None:
    """The block solves y = M^-1 b and w <- M^-T w (in the plan's permuted order) for a plan's factors,
    written out: the bodies of C functions of (``A`` the blocks' LU factors, ``off`` the values below
    them, ``perm`` the blocks' row permutations, then ``b`` and ``y``, or ``w``), called in order. kinegen_solver.c's
    ``solve`` and ``solve_transposed`` loops with every index a constant -- per block its rows'
    right-hand sides less the entries below the blocks, the block's row permutation (:func:`_gather`), L's and U's
    substitutions (transposed: the blocks from the last, U^T, L^T, the permutation's transpose, then the entries
    below the block) --, cut at block boundaries into functions of at most about
    :data:`config.PART_STATEMENTS` statements (the generated kernels' length, which keeps the compile
    time linear); then the first (permuted) row of each forward function, where a right-hand side
    that is zero in the rows before it may start (``solve_from``). None for a plan over
    :data:`STRAIGHT_SOLVE_LIMIT`."""
    starts, stores = arrays.block_start, arrays.block_store
    if sum((b - a) ** 2 for a, b in itertools.pairwise(starts)) + len(arrays.off_col) + starts[-1] > STRAIGHT_SOLVE_LIMIT:
        return None
    forward, transposed = [], []
    for block, (first, end) in enumerate(itertools.pairwise(starts)):
        n, base = end - first, stores[block]
        lines = []
        for row in range(first, end):
            entries = range(arrays.off_start[row], arrays.off_start[row + 1])
            if entries:
                lines.append(f"{{ double acc = b[{arrays.row_order[row]}];"
                             + "".join(f" acc -= off[{e}] * y[{arrays.off_col[e]}];" for e in entries) + f" y[{row}] = acc; }}")  # fmt: skip
            else:
                lines.append(f"y[{row}] = b[{arrays.row_order[row]}];")
        if n > 1:
            lines.append(_gather("y", first, end))
            for k in range(n):
                lines += [f"y[{first + i}] -= A[{base + i + k * n}] * y[{first + k}];" for i in range(k + 1, n)]
        for k in range(n - 1, -1, -1):
            lines.append(f"y[{first + k}] *= 1.0 / A[{base + k + k * n}];")
            lines += [f"y[{first + i}] -= A[{base + i + k * n}] * y[{first + k}];" for i in range(k)]
        forward.append(lines)
        lines = []
        for k in range(n):  # U^T
            lines.append(f"{{ double acc = w[{first + k}];" + "".join(f" acc -= A[{base + i + k * n}] * w[{first + i}];" for i in range(k))
                         + f" w[{first + k}] = acc * (1.0 / A[{base + k + k * n}]); }}")  # fmt: skip
        for k in range(n - 1, -1, -1):  # L^T
            if k + 1 < n:
                lines.append(f"{{ double acc = w[{first + k}];" + "".join(f" acc -= A[{base + i + k * n}] * w[{first + i}];" for i in range(k + 1, n))
                             + f" w[{first + k}] = acc; }}")  # fmt: skip
        if n > 1:
            lines.append(_scatter("w", first, end))
        for row in range(first, end):
            lines += [f"w[{arrays.off_col[e]}] -= off[{e}] * w[{row}];" for e in range(arrays.off_start[row], arrays.off_start[row + 1])]
        transposed.append(lines)
    pieces, first_blocks = _pieces(forward)
    return pieces, _pieces(transposed[::-1])[0], [starts[block] for block in first_blocks]


def _gather(vector: str, first: int, end: int) -> str:
    """One block's row permutation applied to ``vector`` (positions first .. end-1): position k takes
    position first + perm[k] (kinegen_solver.perms). Every value is read before any is written, so no
    read waits on the store before it (the interchanges one by one did: 6 % of the excavator's step)."""
    loads = ", ".join(f"g{k - first} = {vector}[{first} + perm[{k}]]" for k in range(first, end))
    return f"{{ double {loads};" + "".join(f" {vector}[{k}] = g{k - first};" for k in range(first, end)) + " }"


def _scatter(vector: str, first: int, end: int) -> str:
    """The transpose of :func:`_gather`: position first + perm[k] takes position k."""
    loads = ", ".join(f"g{k - first} = {vector}[{k}]" for k in range(first, end))
    return f"{{ double {loads};" + "".join(f" {vector}[{first} + perm[{k}]] = g{k - first};" for k in range(first, end)) + " }"


def _pieces(blocks: list[list[str]]) -> tuple[list[list[str]], list[int]]:
    """Consecutive blocks' statements in functions of at most about :data:`config.PART_STATEMENTS`
    statements (a block's are never cut), each opening with ``(void)`` of the arguments it does not
    read; and the index of each function's first block."""
    pieces: list[list[str]] = [[]]
    first_blocks = [0]
    for block, lines in enumerate(blocks):
        if pieces[-1] and sum(line.count(";") for line in pieces[-1] + lines) > config.PART_STATEMENTS:
            pieces.append([])
            first_blocks.append(block)
        pieces[-1] += lines
    for piece in pieces:
        text = "\n".join(piece)
        piece[:0] = [f"(void){name};" for name in ("A", "off", "perm") if f"{name}[" not in text]
    return pieces, first_blocks


def input_pieces(arrays: _PlanArrays, piece_rows: list[int], n_inputs: int) -> list[int]:
    """Per driver input, the forward function of a plan's written solve (:func:`straight_solve`) whose
    rows hold its driver's row: the drivers' rows are the last ``n_inputs`` of Phi_q, in the inputs'
    order (kinegen_model), so the column of Phi_q^-1 Phi_u for an input is zero before it."""
    rows = len(arrays.row_order)
    position = {row: k for k, row in enumerate(arrays.row_order)}
    return [bisect.bisect_right(piece_rows, position[rows - n_inputs + k]) - 1 for k in range(n_inputs)]


def _enclosure_plan(program: IntervalProgram) -> tuple[dict[int, tuple[float, int]], set[int], dict[int, tuple[int, int]]]:
    """How an interval program's registers are printed in C, the same bits as one helper each: ``scaled``,
    the products of a point constant [c, c] and a register (kinegen_iv_scale: c and that register); ``pairs``,
    at the first of the sine and the cosine of one register, both (kinegen_iv_sincos: sine, cosine); ``printed``,
    the registers that get a line -- not a constant used only as a scale factor, nor a pair's second."""
    operations = program.operations
    scaled: dict[int, tuple[float, int]] = {}
    for k, operation in enumerate(operations):
        if operation.op == "mul":
            for position, a in enumerate(operation.args):
                factor = operations[a]
                if factor.op == "const" and factor.value[0] == factor.value[1]:
                    scaled[k] = (factor.value[0], operation.args[1 - position])
                    break
    used = {r for r in program.outputs if r is not None}
    for k, operation in enumerate(operations):
        used.update((scaled[k][1],) if k in scaled else operation.args)
    trig: dict[int, dict[str, int]] = {}
    for k, operation in enumerate(operations):
        if operation.op in ("sin", "cos"):
            trig.setdefault(operation.args[0], {})[operation.op] = k
    pairs = {min(both.values()): (both["sin"], both["cos"]) for both in trig.values() if len(both) == 2}
    seconds = {max(both) for both in pairs.values()}
    printed = {k for k, operation in enumerate(operations) if k > 0 and k not in seconds and (operation.op != "const" or k in used)}
    return scaled, printed, pairs


class _Model:
    """The C functions and tables of one model."""

    def __init__(self, description: ModuleDescription, stem: str) -> None:
        self.d = description
        self.stem = stem
        self.printing: Printing = description.shapes.printing((CPrinter(),))
        self.functions: list[_Function] = []  # kernels and frames
        self.section_functions: list[_Function] = []
        self.sections: dict[str, list[str]] = {}
        self.shared = SharedTexts()  # a section's functions by their text (section)
        self.tables: list[str] = []  # the kernel tables (kernel_table)
        self.callers: dict[str, set[str]] = {}  # section function -> the kernels (by name) that call it

    def slot_symbols(self, slot: str, case: str | None) -> tuple[sp.Symbol, ...]:
        if case is not None and slot in self.d.cases[case].slots:
            return self.d.cases[case].slots[slot]
        return self.d.slots[slot]

    def prologue(self, slots: tuple[str, ...], block: Block, case: str | None) -> list[str]:
        """Reads of the used arguments, the definitions the block uses, its temporaries;
        ``(void)`` for arguments it does not use (the code compiles with -Wextra -Werror)."""
        used = set(block.symbols)
        defined, needs = self.printing.definitions(self.d.definitions, used)
        used |= needs
        lines = []
        for slot in slots:
            symbols = self.slot_symbols(slot, case)
            if slot == "t":
                if T not in used:
                    lines.append("(void)t;")
                continue
            reads = [f"const double {s} = {slot}[{i}];" for i, s in enumerate(symbols) if s in used]
            lines += reads or [f"(void){slot};"]
        lines += [f"const double {name} = {texts[0]};" for name, *texts in defined]
        lines += [f"const double {name} = {texts[0]};" for name, *texts in block.temporaries]
        return lines

    def section(self, name: str, case: str | None) -> list[str]:
        """The function(s) of a section, made once; returns the names to call, in order (one per part).
        A section whose functions would be another's word for word (the same drivers in several cases:
        the excavator's seven digging-like cases) calls that one's, its doc naming both
        (:class:`~kinegen.codegen.sharing.SharedTexts`): the C compiles each text once."""
        if name in self.sections:
            return self.sections[name]
        section = self.d.sections[name]
        block = self.printing.block(section.groups, "c")
        params = [*(_parameter(s) for s in section.slots), "double *out"]
        parts = block.parts(config.PART_STATEMENTS)
        names = [f"compute_{name}"] if len(parts) == 1 else [f"compute_{name}_part{k}" for k in range(len(parts))]
        made = []
        for function_name, part in zip(names, parts):
            statements = [f"out[{part.offset + i}] = {'0.0' if texts is None else texts[0]};" for i, texts in enumerate(part.outputs)]
            if not part.outputs:
                statements.append("(void)out;")
            doc = section.doc if len(parts) == 1 else f"{section.doc} Rows {part.offset} to {part.offset + len(part) - 1}."
            made.append(_Function(function_name, params, self.prologue(section.slots, part, case), statements, doc))
        kept = self.shared.share(tuple((tuple(f.params), tuple(f.prologue), tuple(f.statements)) for f in made), made, name)
        if kept is made:
            self.section_functions += made
        self.sections[name] = [f.name for f in kept]
        return self.sections[name]

    def enclosure(self, enclosure: Enclosure) -> list[str]:
        """The function of an interval program (kinegen_interval.h's helpers), made once: from
        ``span`` = (t0, t1) the lower bounds of its outputs, then their upper bounds."""
        name = f"compute_{enclosure.name}"
        if enclosure.name not in self.sections:
            program = enclosure.program
            scaled, printed, pairs = _enclosure_plan(program)
            lines = ["const kinegen_interval r0 = kinegen_iv_const(span[0], span[1]);"]
            for k, operation in enumerate(program.operations[1:], start=1):
                op, args = operation.op, ", ".join(f"r{a}" for a in operation.args)
                if k not in printed:
                    continue
                if k in pairs:  # sin and cos of one interval: one call
                    sine, cosine = pairs[k]
                    lines += [f"kinegen_interval r{sine}, r{cosine};", f"kinegen_iv_sincos({args}, &r{sine}, &r{cosine});"]
                    continue
                if k in scaled:
                    factor, other = scaled[k]
                    call = f"kinegen_iv_scale({_double(factor)}, r{other})"
                elif op == "const":
                    call = f"kinegen_iv_const({_double(operation.value[0])}, {_double(operation.value[1])})"
                elif op == "powi":
                    call = f"kinegen_iv_powi({args}, {operation.value})"
                elif op == "powr":
                    call = f"kinegen_iv_powr({args}, {_double(operation.value[0])}, {_double(operation.value[1])})"
                else:
                    call = f"kinegen_iv_{op}({args})"
                lines.append(f"const kinegen_interval r{k} = {call};")
            n = len(program.outputs)
            statements = []
            for i, register in enumerate(program.outputs):
                lower, upper = ("-INFINITY", "INFINITY") if register is None else (f"r{register}.lo", f"r{register}.hi")
                statements += [f"out[{i}] = {lower};", f"out[{n + i}] = {upper};"]
            if not statements:
                statements.append("(void)out;")
            if n == 0:
                lines = ["(void)span;"]
            self.section_functions.append(_Function(name, ["const double *span", "double *out"], lines, statements, enclosure.doc))
            self.sections[enclosure.name] = [name]
        return self.sections[enclosure.name]

    def kernel_table(self, table: str, kernels: list[tuple[str, Kernel]]) -> None:
        """The kernels as data (``kinegen_kernel``, kinegen_solver.h): per kernel an entry point
        of the one fixed signature calling its function, its output names and sizes, then the
        table ``table`` listing them -- what the runtime binds by, never a copy."""
        entries = []
        for function, kernel in kernels:
            arguments = ", ".join([*(f"x[{k}][0]" if s == "t" else f"x[{k}]" for k, s in enumerate(kernel.slots)),
                                   *(f"y[{k}]" for k in range(len(kernel.outputs)))])  # fmt: skip
            sensitivity = kernel.name in SENSITIVITY_ONLY
            self.functions.append(_Function(f"call_{function}", ["const double *const *x", "double *const *y"],
                                            statements=[f"{function}({arguments});"], doc=f"{kernel.name} as a kinegen_kernel entry point.",
                                            sensitivity=sensitivity))  # fmt: skip
            lines = [
                f"static const char *const outputs_{function}[] = {_string_array(o.name for o in kernel.outputs)};",
                f"static const int sizes_{function}[] = {_int_array(o.size for o in kernel.outputs)};",
            ]
            entry = [f"    {{.name = {c_string(kernel.name)}, .slots = {c_string(','.join(kernel.slots))}, .n_outputs = {len(kernel.outputs)}, "
                     f".output_names = outputs_{function}, .output_sizes = sizes_{function}, .call = call_{function}}},"]  # fmt: skip
            self.tables += _without_sensitivities(lines) if sensitivity else lines
            entries += _without_sensitivities(entry) if sensitivity else entry
        self.tables += [f"static const kinegen_kernel {table}[] = {{", *entries, "};"]

    def kernel(self, name: str, kernel, case: str | None, static: bool = True) -> None:
        """A kernel: its outputs filled section by section (zeros where the description says so)."""
        params = [*(_parameter(s) for s in kernel.slots), *(f"double *{o.name}" for o in kernel.outputs)]
        statements: list[str] = []
        for output in kernel.outputs:
            offset = 0
            for part in output.parts:
                if isinstance(part, Zeros):
                    statements.append(f"for (int i = 0; i < {part.size}; ++i) {output.name}[{offset} + i] = 0.0;")
                    offset += part.size
                    continue
                if part in self.d.enclosures:
                    (function,) = self.enclosure(self.d.enclosures[part])
                    statements.append(f"{function}(span, {f'{output.name} + {offset}' if offset else output.name});")
                    offset += self.d.enclosures[part].size
                    continue
                section = self.d.sections[part]
                for function in self.section(part, case):
                    args = ", ".join([*section.slots, f"{output.name} + {offset}" if offset else output.name])
                    statements.append(f"{function}({args});")
                offset += section.size
            if offset == 0:
                statements.append(f"(void){output.name};")
        used = {s for o in kernel.outputs for p in o.parts if not isinstance(p, Zeros)
                for s in (("span",) if p in self.d.enclosures else self.d.sections[p].slots)}  # fmt: skip
        for line in statements:
            called = line.partition("(")[0]
            if called.startswith("compute_"):
                self.callers.setdefault(called, set()).add(kernel.name)
        statements = [f"(void){s};" for s in kernel.slots if s not in used] + statements
        self.functions.append(_Function(name, params, [], statements, kernel.doc, static, kernel.name in SENSITIVITY_ONLY))

    def source_groups(self) -> list[list[_Function]]:
        """The section functions in groups of about :data:`config.FILE_STATEMENTS` statements
        (one group: a small model, all ``static`` as they are), those that only the sensitivity
        kernels call in groups of their own after the others (each function's ``sensitivity``
        set); with more than one group, the functions are made external with the stem as prefix
        and the kernels' calls renamed."""
        for f in self.section_functions:
            callers = self.callers.get(f.name, set())
            f.sensitivity = bool(callers) and callers <= set(SENSITIVITY_ONLY)
        groups: list[list[_Function]] = [[]]
        size = 0
        for f in sorted(self.section_functions, key=lambda f: f.sensitivity):  # (stable: the order within each kind)
            length = len(f.prologue) + len(f.statements)
            if groups[-1] and (size + length > config.FILE_STATEMENTS or f.sensitivity != groups[-1][0].sensitivity):
                groups.append([])
                size = 0
            groups[-1].append(f)
            size += length
        if len(groups) == 1:
            return groups
        renamed = {f.name: f"{self.stem}_{f.name}" for f in self.section_functions}
        for f in self.section_functions:
            f.name, f.static = renamed[f.name], False
        for f in self.functions:
            f.statements = [_renamed_call(line, renamed) for line in f.statements]
        return groups

    def statics(self, cases: list[SimpleNamespace]) -> SimpleNamespace | None:
        """The force solve's table (``kinegen_statics``): names, patterns, the matrix's plan and
        kinegen_forces' work (its kernels are the layout table's actuation, loads and inertia: the
        solver finds them by role)."""
        d = self.d
        statics = d.statics
        if statics is None:
            return None
        nv = len(d.velocity_names)
        arrays = None
        if statics.elements:
            if statics.plan is None:
                raise ValueError(f"{d.model}: the C target needs a square, structurally regular force matrix "
                                 f"(joint rows and {len(statics.elements)} actuation elements for {nv} velocity coordinates)")  # fmt: skip
            arrays = plan_arrays(statics.matrix_rows, statics.matrix_cols, statics.plan, f"{d.model}: the force matrix")
        nb = len(d.bodies)
        nvb = nv // max(nb, 1)
        if nb and (any(offset != b * nvb for b, (_, _, offset) in enumerate(d.bodies)) or nvb > config.MAX_BODY_COORDINATES):
            raise ValueError(f"{d.model}: the C target's pin reactions need every body's {nvb} velocity coordinates in body order "
                             f"(at most {config.MAX_BODY_COORDINATES})")  # fmt: skip
        starts, norm_starts = [0], [0]
        for joint in statics.joints:
            starts.append(starts[-1] + len(joint[5]))
        for rows in statics.norm_rows:
            norm_starts.append(norm_starts[-1] + len(rows))
        largest_jac = max(len(c.case.jac_rows) for c in cases)
        reactions = SimpleNamespace(
            names=[j[0] for j in statics.joints], body=[j[1] for j in statics.joints], sign=[j[2] for j in statics.joints],
            point_body=[j[3] for j in statics.joints], local=[x for j in statics.joints for x in j[4]], row_start=starts,
            rows=[r for j in statics.joints for r in j[5]], norm_start=norm_starts, norm_rows=[r for rows in statics.norm_rows for r in rows],
            hydraulics=[x for h in statics.hydraulics for x in h], largest_jac=largest_jac,
        )  # fmt: skip
        return SimpleNamespace(
            s=statics, plan=arrays, reactions=reactions, joint_rows=d.joint_rows,
        )  # fmt: skip

    def render(self, templates) -> dict[str, str]:
        d, stem = self.d, self.stem
        cases = []
        solves: dict[tuple, str | None] = {}  # a plan's solve, written once: the cases sharing a plan share its function
        piece_rows: dict[tuple, list[int]] = {}
        for name, case in d.cases.items():
            if case.plan is None:
                raise ValueError(
                    f"{d.model}/{name}: the C target needs a square, structurally regular Phi_q "
                    "(this case's is redundant or structurally singular)"
                )
            for kernel in case.kernels.values():
                self.kernel(f"{kernel.name}_{name}", kernel, name)
            self.kernel_table(f"kernels_{name}", [(f"{kernel.name}_{name}", kernel) for kernel in case.kernels.values()])
            arrays = plan_arrays(case.jac_rows, case.jac_cols, case.plan, f"{d.model}/{name}: Phi_q")
            values = max((len(rows) for rows, _ in case.patterns.values()), default=0)  # the largest sensitivity kernel's
            key = tuple(map(tuple, (arrays.block_start, arrays.block_store, arrays.row_order, arrays.col_order, arrays.off_start, arrays.off_col)))
            written = None
            if key not in solves:
                written = straight_solve(arrays)
                solves[key] = None if written is None else name
                if written is not None:
                    piece_rows[key] = written[2]
            pieces = input_pieces(arrays, piece_rows[key], len(case.drivers)) if solves[key] else None
            cases.append(SimpleNamespace(case=case, plan=arrays, sensitivity_values=values, written=written, solve=solves[key],
                                         input_pieces=pieces))  # fmt: skip
        shared = []
        for kernel in d.kernels.values():
            function = f"{stem}_frames" if kernel.name == "frames" else f"shared_{kernel.name}"
            self.kernel(function, kernel, None, static=kernel.name != "frames")
            shared.append((function, kernel))
        self.kernel_table("kernels", shared)
        statics = self.statics(cases)
        points, index = [], {}
        bodies = [b for b, _, _ in d.bodies]
        for body, named in d.points.items():
            for point, local in named.items():
                index[body, point] = len(points)
                points.append((bodies.index(body), f"{body}.{point}", local))
        for point, position in d.ground_points.items():
            index["ground", point] = len(points)
            points.append((-1, f"ground.{point}", position))
        actuators = [(name, index[p1], index[p2], limits) for name, p1, p2, limits in d.actuators]
        macros = templates.get_template("functions.c.jinja").module
        groups = self.source_groups()
        context = {
            "d": d, "stem": stem, "prefix": stem.upper(), "cases": cases, "points": points, "actuators": actuators,
            "param": d.parametrization, "retract": retract_lines(d.parametrization),
            "functions": [(macros.function(f), f.sensitivity) for f in self.functions], "sympy_version": sp.__version__,
            "symengine_version": engine.VERSION, "tables": self.tables,
            "groups": [([macros.function(f) for f in group], group[0].sensitivity if group else False) for group in groups],
            "prototypes": [macros.prototype(f) for group in groups for f in group] if len(groups) > 1 else [],
            "sensitivity_values": max(c.sensitivity_values for c in cases),
            "max_inputs": max(1, *(len(c.case.drivers) for c in cases)), "statics": statics,
        }  # fmt: skip
        return {
            f"{stem}.h": templates.get_template("model.h.jinja").render(context),
            f"{stem}.c": templates.get_template("model.c.jinja").render(context),
        }


def retract_lines(parametrization) -> list[str]:
    """The body of ``retract_body(double *q, const double *step)``: the parametrization's
    symbolic update of one body (:meth:`~kinegen.rotations.base.Parametrization.retraction`),
    its common subexpressions eliminated, printed by the C printer (a small-step branch as a
    conditional expression: only the branch taken is evaluated)."""
    q = sp.symbols(f"q0:{parametrization.nq}", real=True)
    step = sp.symbols(f"step0:{parametrization.nv}", real=True)
    moved = parametrization.retraction(sp.Matrix(q), sp.Matrix(step))
    statements = eliminate(moved)
    printer = CPrinter()
    used = statements.used
    lines = [f"const double {s} = q[{i}];" for i, s in enumerate(q) if s in used]
    lines += [f"const double {s} = step[{i}];" for i, s in enumerate(step) if s in used]
    lines += [f"const double {name} = {' '.join(printer.doprint(value).split())};" for name, value in statements.temporaries]
    changed = [(i, e) for i, e in enumerate(statements.outputs) if e != q[i]]
    lines += [f"const double moved{i} = {' '.join(printer.doprint(e).split())};" for i, e in changed]
    lines += [f"q[{i}] = moved{i};" for i, _ in changed]
    return lines


def _without_sensitivities(lines: list[str]) -> list[str]:
    """``lines`` (of the sensitivity kernels) left out of a compile with ``-DKINEGEN_NO_SENSITIVITIES``."""
    return ["#ifndef KINEGEN_NO_SENSITIVITIES", *lines, "#endif"]


def _renamed_call(line: str, renamed: dict[str, str]) -> str:
    """``line`` with the function it calls (a statement ``name(args);``) renamed."""
    name, paren, rest = line.partition("(")
    return f"{renamed[name]}{paren}{rest}" if paren and name in renamed else line


def printers() -> tuple[CodePrinter, ...]:
    """The printer of every section."""
    return (CPrinter(),)


def jobs(description: ModuleDescription) -> list[tuple[CodePrinter, Group]]:
    """What the model's C prints, as (printer, group): every section (a section still None is still being
    derived: see kernels.describe's ``meanwhile``)."""
    (printer,) = printers()
    return [(printer, group) for section in description.sections.values() if section is not None for group in section.groups]


def render(description: ModuleDescription, stem: str, standalone: bool = True) -> dict[str, str]:
    """The model's C (``<stem>.h``, ``<stem>.c``) and, ``standalone``, everything that builds it
    into a program with nothing but a C99 compiler: the runtime, a Makefile, a CMakeLists.txt
    and example_main.c."""
    templates = environment(config.TEMPLATES)
    templates.filters.update(FILTERS)
    files = _Model(description, stem).render(templates)
    if standalone:
        for name in config.RUNTIME:
            files[name] = (config.SOLVER / name).read_text()
        context = {"stem": stem, "prefix": stem.upper(), "d": description, "cases": list(description.cases), "cflags": config.CFLAGS}
        for name in ("Makefile", "CMakeLists.txt", "example_main.c"):
            files[name] = templates.get_template(f"{name}.jinja").render(context)
    return files


def _largest(names: list[str], prefix: str) -> str:
    """The largest of the macros ``prefix + name``, as KINEGEN_MAX nested in halves (an integer constant
    expression; each level doubles the preprocessor's copies of its arguments, so balanced: ~2n of n)."""
    if len(names) == 1:
        return f"{prefix}{names[0]}"
    half = (len(names) + 1) // 2
    return f"KINEGEN_MAX({_largest(names[:half], prefix)}, {_largest(names[half:], prefix)})"


FILTERS = {"c_string": c_string, "int_array": _int_array, "unpermuted": _unpermuted, "string_array": _string_array, "double": _double, "double_array": _double_array,
           "largest": _largest}  # fmt: skip
