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
from types import SimpleNamespace

import sympy as sp

from kinegen.codegen.backends.python import config
from kinegen.codegen.backends.python.printer import ModulePrinter, ScalarPrinter, used_numpy_names
from kinegen.codegen.kernels import SENSITIVITY_KERNELS, ModuleDescription, Section
from kinegen.codegen.shapes import Block, Printing
from kinegen.codegen.templates import environment

ARRAY, SCALAR = 1, 2  # text positions in a Block's temporaries / outputs (after the name)


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
    first: str = ""
    second: str = ""
    result: str = ""


class _Module:
    """The functions of one module, rendered in order."""

    def __init__(self, description: ModuleDescription) -> None:
        self.d = description
        self.printing: Printing = description.shapes.printing((ModulePrinter(), ScalarPrinter()))
        self.functions: list[_Function] = []
        self.blocks: dict[str, Block] = {}

    def block(self, name: str) -> Block:
        if name not in self.blocks:
            section = self.d.sections[name]
            self.blocks[name] = self.printing.block(section.groups, "d" if name.endswith("jac") or "_jac_" in name else "c")
        return self.blocks[name]

    def slots(self, section: Section | tuple[str, ...], case: str | None) -> list[tuple[str, tuple[sp.Symbol, ...]]]:
        names = section.slots if isinstance(section, Section) else section
        case_slots = self.d.cases[case].slots if case else {}
        return [(n, case_slots.get(n, self.d.slots.get(n, ()))) for n in names]

    def prologue(self, args: list[tuple[str, tuple[sp.Symbol, ...]]], blocks: list[Block], style: int) -> list[str]:
        """Unpacking of the arguments and the definitions the blocks use, then their temporaries."""
        used = set().union(*(b.symbols for b in blocks))
        defined, needs = self.printing.definitions(self.d.definitions, used)
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
        blocks = [self.block(s) for s in sections]
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

    def render(self, templates) -> str:
        d = self.d
        joints = d.joint_rows
        self.array("_joints_phi", d.sections["joints_phi"].doc, "joints_phi", None, "_zeros({m}, q, ())")
        self.array("_joints_jac", d.sections["joints_jac"].doc, "joints_jac", None, "_zeros({m}, q, ())")
        self.array("_joints_gamma", d.sections["joints_gamma"].doc, "joints_gamma", None, "_zeros({m}, q, ())")
        self.scalar("_joints_phi_jac_s", "Phi and Phi_q values of the joint rows at one configuration (lists of floats).",
                    ["joints_phi", "joints_jac"], None)  # fmt: skip
        self.scalar("_joints_gamma_s", "gamma of the joint rows at one configuration (list of floats).", ["joints_gamma"], None)
        self.array("frames", d.kernels["frames"].doc, "frames", None, "_zeros({m}, q, ())")
        if "points" in d.kernels:
            self.array("points", d.kernels["points"].doc, "points", None, "np.zeros(({m},) + np.shape(p[0]))")
            self.array("actuator_ranges", d.sections["actuator_ranges"].doc, "actuator_ranges", None, "np.zeros(({m},) + np.shape(p[0]))")
        if d.sensitivities:
            self.array("points_p", d.sections["points_p"].doc, "points_p", None, "np.zeros(({m},) + np.shape(p[0]))")
            self.array("frames_d", d.sections["frames_d"].doc, "frames_d", None, "_zeros({m}, q, ())")
            for kind in SENSITIVITY_KERNELS:
                self.array(f"_joints_{kind}", d.sections[f"joints_{kind}"].doc, f"joints_{kind}", None, "_zeros({m}, q, ())")
        p = [", p", ["p"]] if d.design else ["", []]  # the design parameters' argument, last
        for name, case in d.cases.items():
            self.array(f"inputs_{name}", d.sections[f"inputs_{name}"].doc, f"inputs_{name}", name, "np.zeros(({m},) + np.shape(t))")
            for kind in ("phi", "jac", "nu", "gamma"):
                section = f"drivers_{kind}_{name}"
                self.array(f"_{section}", d.sections[section].doc, section, name, "_zeros({m}, q, u)")
            for kind in SENSITIVITY_KERNELS if d.sensitivities else ():
                section, kernel = d.sections[f"drivers_{kind}_{name}"], case.kernels[kind]
                self.array(f"_{section.name}", section.doc, section.name, name, "_zeros({m}, q, u)")
                joint_args = ", ".join(d.sections[f"joints_{kind}"].slots)
                self.functions.append(_Function("join", f"{kind}_{name}", list(kernel.slots), kernel.doc,
                                                first=f"_joints_{kind}({joint_args})", second=f"_{section.name}({', '.join(section.slots)})"))  # fmt: skip
            self.scalar(f"_drivers_phi_jac_s_{name}", f"Phi and Phi_q values of the driver rows of case {name!r} at one configuration.",
                        [f"drivers_phi_{name}", f"drivers_jac_{name}"], name)  # fmt: skip
            self.scalar(f"_drivers_nu_s_{name}", f"nu of the driver rows of case {name!r} at one configuration.", [f"drivers_nu_{name}"], name)
            self.scalar(f"_drivers_gamma_s_{name}", f"gamma of the driver rows of case {name!r} at one configuration.",
                        [f"drivers_gamma_{name}"], name)  # fmt: skip
            kernels = case.kernels
            m, entries = kernels["phi_jac"].outputs[0].size, kernels["phi_jac"].outputs[1].size
            q_u, q_u_ud, q_v_inputs = ["q", "u", *p[1]], ["q", "u", "ud", *p[1]], ["q", "v", "u", "ud", "udd", *p[1]]
            P = p[0]
            self.functions += [
                _Function("join", f"phi_{name}", q_u, f"Phi(q, u) of case {name!r}: {m} residuals.",
                          first=f"_joints_phi(q{P})", second=f"_drivers_phi_{name}(q, u{P})"),
                _Function("join", f"jac_{name}", q_u, f"Values of the sparse Phi_q of case {name!r} at jac_rows, jac_cols ({entries} entries).",
                          first=f"_joints_jac(q{P})", second=f"_drivers_jac_{name}(q, u{P})"),
                _Function("returns", f"nu_{name}", q_u_ud, kernels["nu"].doc, [f"drivers = _drivers_nu_{name}(q, u, ud{P})"],
                          result=f"_join(np.zeros(({joints},) + drivers.shape[1:]), drivers)"),
                _Function("join", f"gamma_{name}", q_v_inputs, kernels["gamma"].doc,
                          first=f"_joints_gamma(q, v{P})", second=f"_drivers_gamma_{name}(q, v, u, ud, udd{P})"),
                _Function("returns", f"phi_jac_s_{name}", q_u,
                          f"Phi and the Phi_q values of case {name!r} at one configuration (q, u: lists of floats).",
                          [f"phi, jac = _joints_phi_jac_s(q{P})", f"driver_phi, driver_jac = _drivers_phi_jac_s_{name}(q, u{P})"],
                          result="phi + driver_phi, jac + driver_jac"),
                _Function("returns", f"nu_s_{name}", q_u_ud, f"nu of case {name!r} at one configuration (list of floats).",
                          result=f"[0.0] * {joints} + _drivers_nu_s_{name}(q, u, ud{P})"),
                _Function("returns", f"gamma_s_{name}", q_v_inputs, f"gamma of case {name!r} at one configuration (list of floats).",
                          result=f"_joints_gamma_s(q, v{P}) + _drivers_gamma_s_{name}(q, v, u, ud, udd{P})"),
            ]  # fmt: skip
        macros = templates.get_template("functions.py.jinja").module
        code = [getattr(macros, f.kind)(f) for f in self.functions]
        kernels = [
            SimpleNamespace(name=k.name, slots=k.slots, outputs=tuple(o.name for o in k.outputs))
            for k in [*next(iter(d.cases.values())).kernels.values(), *d.kernels.values()]
        ]
        return templates.get_template("module.py.jinja").render(
            d=d,
            sympy_version=sp.__version__,
            numpy_names=used_numpy_names("\n".join(code)),
            kernels=kernels,
            functions=code,
            cases=list(d.cases.values()),
        )


def _scalar_list(block: Block) -> str:
    return "[" + ", ".join("0.0" if texts is None else texts[SCALAR - 1] for texts in block.outputs) + "]"


def render(description: ModuleDescription, stem: str) -> dict[str, str]:
    """The module's file name and text: ``{stem}.py``."""
    return {f"{stem}{config.SUFFIX}": _Module(description).render(environment(config.TEMPLATES))}
