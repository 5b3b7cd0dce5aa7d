"""Optional compiled path: the generated plain-float functions translated to C, built with
the machine's C compiler and called through ``ctypes``.

The C source is derived from the generated module itself (its ``*_s`` functions, parsed
with :mod:`ast`: assignments, ``+ - * / **``, ``math.*`` calls), so it computes exactly
the expressions of the Python code, in the same order. The shared library is cached by the
SHA-256 of its source (``$KINEGEN_CACHE`` or ``~/.cache/kinegen``). Nothing here is needed
to use kinegen: :func:`attach` raises :class:`CompileError` when no compiler is found, and
callers fall back to the Python functions.
"""

from __future__ import annotations

import ast
import ctypes
import hashlib
import inspect
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path
from types import ModuleType

import numpy as np

from kinegen.errors import KinegenError
from kinegen.runtime.system import NumericSystem

_C_FUNCTIONS = {
    "sin": "sin", "cos": "cos", "tan": "tan", "asin": "asin", "acos": "acos", "atan": "atan", "atan2": "atan2",
    "sinh": "sinh", "cosh": "cosh", "tanh": "tanh", "exp": "exp", "log": "log", "sqrt": "sqrt",
}  # fmt: skip


class CompileError(KinegenError):
    """No C compiler, or the generated C did not compile."""

    exit_code = 5


def _expression(node: ast.expr, names: dict[str, str]) -> str:
    """C text of a Python arithmetic expression of the generated code (every number a double;
    each name replaced by where ``names`` keeps it)."""
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
        return repr(float(node.value))
    if isinstance(node, ast.Name):
        return names.get(node.id, node.id)
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "math" and node.attr == "pi":
        return "M_PI"
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        return f"({'-' if isinstance(node.op, ast.USub) else '+'}{_expression(node.operand, names)})"
    if isinstance(node, ast.BinOp):
        left, right = _expression(node.left, names), _expression(node.right, names)
        if isinstance(node.op, ast.Pow):
            exponent = node.right.value if isinstance(node.right, ast.Constant) else None
            if isinstance(exponent, (int, float)) and float(exponent).is_integer() and 1 <= abs(exponent) <= 4:
                product = "*".join([f"({left})"] * int(abs(exponent)))
                return f"({product})" if exponent > 0 else f"(1.0/({product}))"
            return f"pow({left}, {right})"
        operator = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}.get(type(node.op))
        if operator is None:
            raise CompileError(f"cannot translate operator {type(node.op).__name__}")
        return f"({left} {operator} {right})"
    if isinstance(node, ast.Call) and not node.keywords:
        function = node.func
        args = ", ".join(_expression(a, names) for a in node.args)
        if isinstance(function, ast.Attribute) and isinstance(function.value, ast.Name) and function.value.id == "math":
            if function.attr in _C_FUNCTIONS:
                return f"{_C_FUNCTIONS[function.attr]}({args})"
        if isinstance(function, ast.Name) and function.id == "abs":
            return f"fabs({args})"
    raise CompileError(f"cannot translate {ast.dump(node)[:80]}")


@dataclass(frozen=True)
class _Function:
    name: str
    arguments: list[str]
    outputs: list[int]  # lengths of the returned lists
    names: dict[str, str]  # unpacked argument name -> its element, e.g. q[3]
    statements: list[tuple[str, ast.expr]]  # (intermediate's name or output element, expression), in order


def _translate(function: ast.FunctionDef) -> _Function:
    """One generated ``*_s`` function: unpacking, assignments, ``return [..], [..]``."""
    arguments = [a.arg for a in function.args.args]
    names: dict[str, str] = {}
    statements: list[tuple[str, ast.expr]] = []
    outputs: list[int] = []
    for statement in function.body:
        if isinstance(statement, ast.Expr) and isinstance(statement.value, ast.Constant):
            continue  # docstring
        if isinstance(statement, ast.Assign) and len(statement.targets) == 1:
            target, value = statement.targets[0], statement.value
            if isinstance(target, ast.Tuple) and isinstance(value, ast.Name):
                for i, element in enumerate(target.elts):
                    if isinstance(element, ast.Name) and element.id != "_":
                        names[element.id] = f"{value.id}[{i}]"
                continue
            if isinstance(target, ast.Name):
                statements.append((target.id, value))
                continue
        if isinstance(statement, ast.Return):
            lists = statement.value.elts if isinstance(statement.value, ast.Tuple) else [statement.value]
            for k, items in enumerate(lists):
                if not isinstance(items, ast.List):
                    raise CompileError(f"{function.name}: return of {type(items).__name__}")
                outputs.append(len(items.elts))
                statements += [(f"out{k}[{i}]", e) for i, e in enumerate(items.elts)]
            continue
        raise CompileError(f"{function.name}: cannot translate {type(statement).__name__}")
    return _Function(function.name, arguments, outputs, names, statements)


#: statements per C function: a generated function is cut into parts of this size, so that
#: the compiler's register allocation (superlinear in a function's live values) stays linear
#: in the model's size; an intermediate used by a later part is passed in a work array ``w``
PART = 250


def _c_function(f: _Function, name: str) -> str:
    """C of a translated function: parts of :data:`PART` statements, and ``name`` calling them."""
    parts = [f.statements[start : start + PART] for start in range(0, len(f.statements), PART)] or [[]]
    defined = {target: p for p, part in enumerate(parts) for target, _ in part if not target.startswith("out")}
    slots: dict[str, str] = {}
    for p, part in enumerate(parts):
        for _, value in part:
            for node in ast.walk(value):
                if isinstance(node, ast.Name) and defined.get(node.id, p) != p and node.id not in slots:
                    slots[node.id] = f"w[{len(slots)}]"
    names = {**f.names, **slots}
    parameters = [f"const double *restrict {a}" for a in f.arguments] + [
        f"double *restrict out{k}" for k in range(len(f.outputs))
    ]
    arguments = [*f.arguments, *(f"out{k}" for k in range(len(f.outputs)))]
    text, calls = [], []
    for p, part in enumerate(parts):
        lines = []
        for target, value in part:
            expression = _expression(value, names)
            if target.startswith("out") or target in slots:
                lines.append(f"{names.get(target, target)} = {expression};")
            else:
                lines.append(f"const double {target} = {expression};")
        body = "\n    ".join(lines)
        text.append(
            f"static __attribute__((noinline)) void {name}_part{p}({', '.join(parameters)}, double *restrict w) {{\n    {body}\n}}\n"
        )
        calls.append(f"    {name}_part{p}({', '.join(arguments)}, w);\n")
    return (
        "".join(text)
        + f"static void {name}({', '.join(parameters)}) {{\n    double w[{max(1, len(slots))}];\n"
        + "".join(calls)
        + "}\n"
    )


def c_source(module: ModuleType) -> tuple[str, dict[str, dict[str, int]]]:
    """C source of every case of ``module`` and, per case, the sizes (rows, entries, joint rows/entries)."""
    tree = ast.parse(inspect.getsource(module))
    functions = {node.name: node for node in tree.body if isinstance(node, ast.FunctionDef)}
    joints_phi_jac = _translate(functions["_joints_phi_jac_s"])
    joints_gamma = _translate(functions["_joints_gamma_s"])
    parts = ["#include <math.h>\n", _c_function(joints_phi_jac, "joints_phi_jac"), _c_function(joints_gamma, "joints_gamma")]
    sizes: dict[str, dict[str, int]] = {}
    mj, nj = joints_phi_jac.outputs
    for case in module.CASES:
        drivers = _translate(functions[f"_drivers_phi_jac_s_{case}"])
        nu = _translate(functions[f"_drivers_nu_s_{case}"])
        gamma = _translate(functions[f"_drivers_gamma_s_{case}"])
        md, nd = drivers.outputs
        parts += [
            _c_function(drivers, f"drivers_phi_jac_{case}"),
            _c_function(nu, f"drivers_nu_{case}"),
            _c_function(gamma, f"drivers_gamma_{case}"),
            f"void phi_jac_{case}(const double *q, const double *u, double *phi, double *jac) {{\n"
            f"    joints_phi_jac(q, phi, jac);\n    drivers_phi_jac_{case}(q, u, phi + {mj}, jac + {nj});\n}}\n",
            f"void nu_{case}(const double *q, const double *u, const double *ud, double *out) {{\n"
            f"    for (int i = 0; i < {mj}; ++i) out[i] = 0.0;\n    drivers_nu_{case}(q, u, ud, out + {mj});\n}}\n",
            f"void gamma_{case}(const double *q, const double *v, const double *u, const double *ud, const double *udd, double *out) {{\n"
            f"    joints_gamma(q, v, out);\n    drivers_gamma_{case}(q, v, u, ud, udd, out + {mj});\n}}\n",
        ]
        sizes[case] = {"rows": mj + md, "entries": nj + nd}
    return "\n".join(parts), sizes


def c_compiler() -> str:
    """The machine's C compiler: ``$CC``, else ``cc``, else ``gcc``; CompileError if none."""
    chosen = os.environ.get("CC")
    if chosen:
        compiler = shutil.which(chosen)
        if compiler is None:
            raise CompileError(f"CC={chosen!r} is not an executable C compiler")
        return compiler
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise CompileError("no C compiler found (set CC, or install gcc)")
    return compiler


def build_library(source: str) -> Path:
    """The shared library of ``source``, compiled once per source (cached by its hash)."""
    compiler = c_compiler()
    cache = Path(os.environ.get("KINEGEN_CACHE", Path.home() / ".cache" / "kinegen"))
    cache.mkdir(parents=True, exist_ok=True)
    digest = hashlib.sha256(source.encode()).hexdigest()[:20]
    library = cache / f"kinegen_{digest}.so"
    if library.exists():
        return library
    with tempfile.TemporaryDirectory() as folder:
        c_file = Path(folder) / "module.c"
        c_file.write_text(source)
        built = Path(folder) / library.name
        try:
            done = subprocess.run(
                [compiler, "-O2", "-fno-tree-slp-vectorize", "-shared", "-fPIC", "-o", str(built), str(c_file), "-lm"],
                capture_output=True,
                text=True,
            )
        except OSError as exc:
            raise CompileError(f"the C compiler {compiler} cannot be run: {exc.strerror or exc}") from None
        if done.returncode != 0:
            raise CompileError(
                f"the C compiler failed: {done.stderr.strip().splitlines()[-1] if done.stderr.strip() else done.returncode}"
            )
        os.replace(built, library)  # atomic: a concurrent build finds a whole library or none
    return library


class _Native:
    """Calls into the compiled case: the same results as the ``*_s`` functions, as arrays.

    Arguments are copied into buffers allocated once (their addresses computed once: asking
    an array for its address costs more than the C call at chain-3 size); results are
    written into buffers and returned as fresh copies, so a caller may keep them. (One
    object per system: not for concurrent calls from several threads.)
    """

    def __init__(
        self, library: ctypes.CDLL, case: str, rows: int, entries: int, n_stored: int, n_velocity: int, n_inputs: int
    ) -> None:
        self.library, self.case = library, case  #: also for the C trajectory loop (compiled_trajectory)
        self.rows, self.entries = rows, entries
        self._q, self._v = np.zeros(n_stored), np.zeros(n_velocity)
        self._u, self._ud, self._udd = np.zeros(n_inputs), np.zeros(n_inputs), np.zeros(n_inputs)
        self._phi, self._jac = np.zeros(rows), np.zeros(entries)
        address = {name: getattr(self, name).ctypes.data for name in ("_q", "_v", "_u", "_ud", "_udd", "_phi", "_jac")}
        self._phi_jac = getattr(library, f"phi_jac_{case}")
        self._nu = getattr(library, f"nu_{case}")
        self._gamma = getattr(library, f"gamma_{case}")
        for function in (self._phi_jac, self._nu, self._gamma):
            function.restype = None
        self._phi_jac.argtypes = self._nu.argtypes = [ctypes.c_void_p] * 4
        self._gamma.argtypes = [ctypes.c_void_p] * 6
        self._phi_jac_args = (address["_q"], address["_u"], address["_phi"], address["_jac"])
        self._nu_args = (address["_q"], address["_u"], address["_ud"], address["_phi"])
        self._gamma_args = (address["_q"], address["_v"], address["_u"], address["_ud"], address["_udd"], address["_phi"])

    def evaluate(self, q: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Phi and the Phi_q values at one configuration."""
        self._q[:] = q
        self._u[:] = u
        self._phi_jac(*self._phi_jac_args)
        return self._phi.copy(), self._jac.copy()

    def nu(self, q: np.ndarray, u: np.ndarray, ud: np.ndarray) -> np.ndarray:
        self._q[:] = q
        self._u[:] = u
        self._ud[:] = ud
        self._nu(*self._nu_args)
        return self._phi.copy()

    def gamma(self, q: np.ndarray, v: np.ndarray, u: np.ndarray, ud: np.ndarray, udd: np.ndarray) -> np.ndarray:
        self._q[:] = q
        self._v[:] = v
        self._u[:] = u
        self._ud[:] = ud
        self._udd[:] = udd
        self._gamma(*self._gamma_args)
        return self._phi.copy()


#: the solver's step loop in C (kinegen.runtime.compiled_trajectory), built into every library
TRAJECTORY_C = Path(__file__).with_name("trajectory.c")


def attach(system: NumericSystem, module: ModuleType) -> NumericSystem:
    """``system`` evaluating its one-configuration functions through the compiled module
    (and solving its trajectories with the C step loop, ``trajectory.c``)."""
    source, sizes = c_source(module)
    library = ctypes.CDLL(str(build_library(source + "\n" + TRAJECTORY_C.read_text())))
    size = sizes[system.case]
    native = _Native(library, system.case, size["rows"], size["entries"], system.n_stored, system.n_velocity, system.n_inputs)
    return replace(system, native=native)
