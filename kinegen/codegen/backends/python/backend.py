"""Printing a kernel description as one Python module.

Per section two styles: NumPy code for one configuration or a batch (``q`` of shape (n, K),
inputs (nd,) or (nd, K); outputs with the row or Jacobian entry first) and plain ``math``
code for one configuration (lists of floats in and out, several times faster on scalars:
what a Newton step on one configuration needs). The joint sections are printed once and
joined with each case's driver sections. Functions of more than
:data:`~kinegen.codegen.shapes.PART_STATEMENTS` statements are split into parts.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import sympy as sp
from sympy.printing.codeprinter import CodePrinter

import kinegen.codegen.backends.python.config as config
from kinegen.codegen.backends.python.printer import ModulePrinter, ScalarPrinter, used_numpy_names
from kinegen.codegen.kernels import Enclosure, Kernel, ModuleDescription, Output, Section, Zeros
from kinegen.codegen.shapes import Block, Group, Printing
from kinegen.codegen.sharing import SharedTexts
from kinegen.codegen.templates import environment
from kinegen.interface import FRAME_FIELDS
from kinegen.symbolic import engine

ARRAY, SCALAR = 1, 2  # text positions in a Block's temporaries / outputs (after the name)


#: The module's printers: NumPy (every section), plain ``math`` (the sections of SCALAR_KERNELS).
PRINTERS = (ModulePrinter(), ScalarPrinter())


def scalar_sections(description: ModuleDescription) -> set[str]:
    """The sections the plain-float functions compute (those of config.SCALAR_KERNELS' kernels)."""
    return {part for case in description.cases.values() for name in config.SCALAR_KERNELS if name in case.kernels
            for output in case.kernels[name].outputs for part in output.parts if isinstance(part, str)}  # fmt: skip


def printers() -> tuple[CodePrinter, ...]:
    """The printers of every section: NumPy's (the scalar ones are also printed in ``math``: :func:`jobs`)."""
    return PRINTERS[:1]


def jobs(description: ModuleDescription) -> list[tuple[CodePrinter, Group]]:
    """What the module prints, as (printer, group): every section in NumPy, the scalar ones also in ``math``
    (a section still None is still being derived: see kernels.describe's ``meanwhile``)."""
    scalar, array = scalar_sections(description), printers()
    return [(printer, group) for name, section in description.sections.items() if section is not None for group in section.groups
            for printer in (PRINTERS if name in scalar else array)]  # fmt: skip


@dataclass
class _Function:
    """One generated function for a template macro."""

    kind: str  # macro name in functions.py.jinja
    name: str
    args: list[str]
    doc: str
    prologue: list[str] = field(default_factory=list)
    outputs: list[tuple[int, str]] = field(default_factory=list)
    allocate: str = ""
    parts: list[str] = field(default_factory=list)
    results: list[str] = field(default_factory=list)
    result: str = ""


class _Module:
    """The functions of one module, rendered in order."""

    def __init__(self, description: ModuleDescription) -> None:
        self.d = description
        self.printing: Printing = description.shapes.printing(PRINTERS)
        #: sections only NumPy functions compute (not those of SCALAR_KERNELS): printed in that style alone
        self.array_printing: Printing = description.shapes.printing(PRINTERS[:1])
        self.scalar_sections = scalar_sections(description)
        self.functions: list[_Function] = []
        self.blocks: dict[tuple[str, str], Block] = {}
        self.made: dict[str, str] = {}  # functions made once for every case (section and scalar): name -> the one to call
        self.texts = SharedTexts()  # a section's functions by their text (shared)

    def block(self, name: str, prefix: str = "c") -> Block:
        """The section's printed block, temporaries ``<prefix>0, ...`` (functions computing several
        sections give each its own prefix)."""
        if (name, prefix) not in self.blocks:
            printing = self.printing if name in self.scalar_sections else self.array_printing
            self.blocks[name, prefix] = printing.block(self.d.sections[name].groups, prefix)
        return self.blocks[name, prefix]

    def slots(self, section: Section | tuple[str, ...], case: str | None) -> list[tuple[str, tuple[sp.Symbol, ...]]]:
        names = section.slots if isinstance(section, Section) else section
        case_slots = self.d.cases[case].slots if case else {}
        return [(n, case_slots.get(n, self.d.slots.get(n, ()))) for n in names]

    def prologue(self, args: list[tuple[str, tuple[sp.Symbol, ...]]], blocks: list[Block], style: int) -> list[str]:
        """Unpacking of the arguments and the definitions the blocks use, then their temporaries."""
        used = set().union(*(b.symbols for b in blocks))
        defined, needs = (self.printing if style == SCALAR else self.array_printing).definitions(self.d.definitions, used)
        used |= needs
        lines = []
        for arg, symbols in args:
            if any(s in used for s in symbols):
                targets = ", ".join(str(s) if s in used else "_" for s in symbols)
                if targets != arg:
                    lines.append(f"{targets}{',' if len(symbols) == 1 else ''} = {arg}")
        lines += [f"{name} = {texts[style - 1]}" for name, *texts in defined]
        for block in blocks:
            lines += [f"{name} = {texts[style - 1]}" for name, *texts in block.temporaries]
        return lines

    def array(self, name: str, doc: str, section: str, case: str | None, allocate: str) -> None:
        """NumPy function filling an array (one configuration or a batch), skipping exact zeros."""
        block = self.block(section)
        args = self.slots(self.d.sections[section], case)
        arg_names = [a for a, _ in args]
        parts = block.parts(config.PART_STATEMENTS)
        allocation = allocate.format(m=len(block))
        if len(parts) == 1:
            outputs = [(i, texts[ARRAY - 1]) for i, texts in enumerate(block.outputs) if texts is not None]
            self.functions.append(_Function("array", name, arg_names, doc, self.prologue(args, [block], ARRAY), outputs, allocation))
            return
        names = [f"{name}_part{k}" for k in range(len(parts))]
        self.functions.append(_Function("array_parts", name, arg_names, doc, allocate=allocation, parts=names))
        for part_name, part in zip(names, parts):
            outputs = [(part.offset + i, texts[ARRAY - 1]) for i, texts in enumerate(part.outputs) if texts is not None]
            doc = f"Rows {part.offset} to {part.offset + len(part) - 1} of {name}."
            self.functions.append(_Function("array_part", part_name, arg_names, doc, self.prologue(args, [part], ARRAY), outputs))

    def scalar(self, name: str, doc: str, sections: list[str], case: str | None) -> None:
        """Plain-float function (``math``) of one configuration returning one list per section
        (a long section as the concatenated lists of part functions ``{name}_part<k>``)."""
        blocks = [self.block(s, "cdefgh"[k]) for k, s in enumerate(sections)]
        args = self.slots(self.d.sections[sections[0]], case)
        arg_names = [a for a, _ in args]
        split = [block.parts(config.PART_STATEMENTS) for block in blocks]
        if all(len(parts) == 1 for parts in split):
            results = [_scalar_list(block) for block in blocks]
            self.functions.append(_Function("scalar", name, arg_names, doc, self.prologue(args, blocks, SCALAR), results=results))
            return
        results, k = [], 0
        parts_functions = []
        for parts in split:
            calls = []
            for part in parts:
                part_name = f"{name}_part{k}"
                doc = f"Items {part.offset} to {part.offset + len(part) - 1} of a list of {name}."
                prologue = self.prologue(args, [part], SCALAR)
                parts_functions.append(_Function("scalar", part_name, arg_names, doc, prologue, results=[_scalar_list(part)]))
                calls.append(f"{part_name}({', '.join(arg_names)})")
                k += 1
            results.append(" + ".join(calls))
        self.functions.append(_Function("scalar", name, arg_names, doc, results=results))
        self.functions += parts_functions

    def allocation(self, slots: tuple[str, ...]) -> str:
        """The output array of a function of ``slots``: rows first, then the arguments' batch shape."""
        if "q" in slots:
            return "_zeros({m}, q, u)" if "u" in slots else "_zeros({m}, q, ())"
        return "np.zeros(({m},) + np.shape(t))" if slots == ("t",) else f"np.zeros(({{m}},) + np.shape({slots[0]}[0]))"

    def shared(self, name: str, first: int, section: str) -> str:
        """The functions made from ``first`` on (one function's, or its parts'), for ``name``: kept, or
        dropped where another's are the same text but for their names (the same drivers in several
        cases: the excavator's seven digging-like cases), which is called instead
        (:class:`~kinegen.codegen.sharing.SharedTexts`, as the C backend's). Returns the name to call."""
        made = self.functions[first:]
        text = tuple((f.kind, tuple(f.args), tuple(f.prologue), tuple(f.outputs), f.allocate, len(f.parts),
                      tuple(r.replace(name, "<name>") for r in f.results), f.result) for f in made)  # (parts are name_part<k>)
        kept = self.texts.share(text, made, section)
        if kept is not made:
            del self.functions[first:]
        self.made[name] = kept[0].name
        return kept[0].name

    def section_array(self, section: str, case: str | None) -> str:
        """The NumPy function of one section (``_<section>``, made once); returns the name to call
        (:meth:`shared`)."""
        name = f"_{section}"
        if name not in self.made:
            s = self.d.sections[section]
            first = len(self.functions)
            self.array(name, s.doc, section, case, self.allocation(s.slots))
            self.shared(name, first, section)
        return self.made[name]

    def enclosure(self, function: str, doc: str, enclosure: Enclosure) -> None:
        """The NumPy function ``function(span)`` of an interval program: ``span`` = (t0, t1), two
        floats or arrays of one shape (many time intervals at once); the rows of the lower bounds,
        then of the upper bounds (the interval helpers ``_iv_*`` are printed once per module)."""
        program = enclosure.program
        lines = ["r0 = tuple(np.asarray(t, dtype=float) for t in span)"]
        for k, operation in enumerate(program.operations[1:], start=1):
            op, args = operation.op, ", ".join(f"r{a}" for a in operation.args)
            if op == "const":
                lines.append(f"r{k} = _iv_const({operation.value[0]!r}, {operation.value[1]!r}, r0)")
            elif op == "powi":
                lines.append(f"r{k} = _iv_powi({args}, {operation.value!r})")
            elif op == "powr":
                lines.append(f"r{k} = _iv_powr({args}, ({operation.value[0]!r}, {operation.value[1]!r}))")
            else:
                lines.append(f"r{k} = _iv_{op}({args})")
        n = len(program.outputs)
        lines.append(f"out = np.empty(({2 * n},) + np.shape(r0[0]))")
        for i, register in enumerate(program.outputs):
            lower, upper = ("-np.inf", "np.inf") if register is None else (f"r{register}[0]", f"r{register}[1]")
            lines += [f"out[{i}] = {lower}", f"out[{n + i}] = {upper}"]
        self.functions.append(_Function("returns", function, ["span"], doc, lines, result="out"))

    def output(self, function: str, kernel: Kernel, output: Output, case: str | None) -> None:
        """The NumPy function ``function`` of the kernel's slots giving ``output``: its one
        section's function, or its parts joined (zeros as their row count)."""
        parts = output.parts
        if len(parts) == 1 and parts[0] in self.d.enclosures:
            self.enclosure(function, _output_doc(kernel, output), self.d.enclosures[parts[0]])
            return
        if len(parts) == 1 and not isinstance(parts[0], Zeros) and self.d.sections[parts[0]].slots == kernel.slots:
            self.array(function, _output_doc(kernel, output), parts[0], case, self.allocation(kernel.slots))
            return
        calls = [str(part.size) if isinstance(part, Zeros) else f"{self.section_array(part, case)}({', '.join(self.d.sections[part].slots)})"
                 for part in parts]  # fmt: skip
        self.functions.append(_Function("returns", function, list(kernel.slots), _output_doc(kernel, output), result=f"_join({', '.join(calls)})"))

    def scalar_kernel(self, function: str, kernel: Kernel, case: str) -> None:
        """Plain-float ``function`` of one configuration: each output as a list (a tuple of them
        for several), the sections at the same place of every output computed together."""
        outputs = kernel.outputs
        lines, pieces = [], [[] for _ in outputs]
        for position in range(max(len(o.parts) for o in outputs)):
            sections = [(i, o.parts[position]) for i, o in enumerate(outputs) if position < len(o.parts)]
            for i, part in sections:
                if isinstance(part, Zeros):
                    pieces[i].append(f"[0.0] * {part.size}")
            named = [(i, part) for i, part in sections if not isinstance(part, Zeros)]
            if not named:
                continue
            name = "_" + "_".join(part for _, part in named) + "_s"
            if name not in self.made:
                doc = "; ".join(self.d.sections[part].doc for _, part in named) + " (one configuration, lists of floats)"
                first = len(self.functions)
                self.scalar(name, doc, [part for _, part in named], case)
                self.shared(name, first, " and ".join(part for _, part in named))
            values = [f"s{position}_{i}" for i, _ in named]
            slots = ", ".join(self.d.sections[named[0][1]].slots)
            lines.append(f"{', '.join(values)} = {self.made[name]}({slots})")
            for (i, _), value in zip(named, values):
                pieces[i].append(value)
        result = ", ".join(" + ".join(p) for p in pieces)
        doc = f"{kernel.doc} At one configuration (lists of floats)."
        self.functions.append(_Function("returns", function, list(kernel.slots), doc, lines, result=result))

    def render(self, templates) -> str:
        d = self.d
        for kernel in d.kernels.values():  # shared by the cases: a function per output, named as it
            for output in kernel.outputs:
                self.output(output.name, kernel, output, None)
        cases = []
        for name, case in d.cases.items():
            outputs, scalar = {}, {}
            for kernel in case.kernels.values():
                for output in kernel.outputs:
                    outputs[output.name] = f"{output.name}_{name}"
                    self.output(outputs[output.name], kernel, output, name)
                if kernel.name in config.SCALAR_KERNELS:
                    scalar[kernel.name] = f"{kernel.name}_s_{name}"
                    self.scalar_kernel(scalar[kernel.name], kernel, name)
            cases.append(SimpleNamespace(case=case, outputs=outputs, scalar=scalar))
        macros = templates.get_template("functions.py.jinja").module
        code = [getattr(macros, f.kind)(f) for f in self.functions]
        kernels = [
            SimpleNamespace(name=k.name, slots=k.slots, outputs=tuple(o.name for o in k.outputs))
            for k in [*next(iter(d.cases.values())).kernels.values(), *d.kernels.values()]
        ]
        return templates.get_template("module.py.jinja").render(
            d=d,
            sympy_version=sp.__version__,
            symengine_version=engine.VERSION,
            numpy_names=used_numpy_names("\n".join(code)),
            kernels=kernels,
            functions=code,
            cases=cases,
            frame_fields=FRAME_FIELDS,
            interval_helpers=interval_helpers(),
        )


def _output_doc(kernel: Kernel, output: Output) -> str:
    if len(kernel.outputs) == 1:
        return kernel.doc
    return f"Output {output.name!r} ({output.size} values) of the kernel {kernel.name}: {kernel.doc}"


def _scalar_list(block: Block) -> str:
    return "[" + ", ".join("0.0" if texts is None else texts[SCALAR - 1] for texts in block.outputs) + "]"


def interval_helpers() -> str:
    """The text of the interval helpers every module's enclosure kernels call: the part of
    ``intervals.py`` (beside this file) below its ``# ---- helpers ----`` line."""
    text = Path(__file__).with_name("intervals.py").read_text(encoding="utf-8")
    return text.split("# ---- helpers ----\n", 1)[1].split("# ---- end of helpers ----", 1)[0].strip()


def render(description: ModuleDescription, stem: str) -> dict[str, str]:
    """The module's file name and text: ``{stem}.py`` (naming the model's C by ``description.c_files``:
    render the C first)."""
    return {f"{stem}{config.SUFFIX}": _Module(description).render(environment(config.TEMPLATES))}
