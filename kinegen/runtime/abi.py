"""The C runtime's structs and status codes as a compiled library describes them.

kinegen_solver.c exports ``kinegen_fields`` (every field of its public structs with offset,
size and type), ``kinegen_structs`` (each struct's size) and ``kinegen_status_names`` (the
status codes' names, by code); a generated model's C exports its kernels as ``kinegen_kernel``
tables. :class:`Abi` lays ctypes structures out from those tables -- the one layout written
here is that of a table entry itself -- so the Python runtime holds no copy of a struct, a
status code or a kernel's signature that could drift from the C it loads.
"""

from __future__ import annotations

import ctypes
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinegen.interface import frame_slices


class _Field(ctypes.Structure):
    """One entry of ``kinegen_fields`` (kinegen_solver.h: ``kinegen_field``)."""

    _fields_ = [("structure", ctypes.c_char_p), ("name", ctypes.c_char_p), ("type", ctypes.c_char_p), ("offset", ctypes.c_int), ("size", ctypes.c_int)]


class _Struct(ctypes.Structure):
    """One entry of ``kinegen_structs``."""

    _fields_ = [("name", ctypes.c_char_p), ("size", ctypes.c_int)]


class _Function(ctypes.Structure):
    """One entry of ``kinegen_functions``."""

    _fields_ = [("name", ctypes.c_char_p), ("result", ctypes.c_char_p), ("parameters", ctypes.c_char_p)]


class _FrameField(ctypes.Structure):
    """One entry of ``kinegen_frame_fields``."""

    _fields_ = [("name", ctypes.c_char_p), ("offset", ctypes.c_int), ("count", ctypes.c_int)]


_SCALARS = {"double": ctypes.c_double, "int": ctypes.c_int}
_POINTERS = {
    "double*": ctypes.POINTER(ctypes.c_double), "int*": ctypes.POINTER(ctypes.c_int), "char*": ctypes.c_char_p,
    "pointer": ctypes.c_void_p, "function": ctypes.c_void_p,
}  # fmt: skip
#: a kernel's entry point: void call(const double *const *arguments, double *const *outputs)
KERNEL_CALL = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)


class AbiError(RuntimeError):
    """A library whose self-description does not describe what the runtime needs."""


#: the ctypes types of the C types kinegen_solver.h's functions take and return, pointers aside
_C_TYPES = {"void": None, "double": ctypes.c_double, "int": ctypes.c_int}


def c_type(declaration: str) -> Any:
    """The ctypes type of a C type as declared (a parameter's name, if any, ignored): a pointer
    ``c_void_p`` (``const char *``: ``c_char_p``), else ``double``, ``int`` or ``void`` (None)."""
    words = [w for w in declaration.replace("*", " * ").split() if w != "const"]
    if "*" in words:
        return ctypes.c_char_p if words[:2] == ["char", "*"] and words.count("*") == 1 else ctypes.c_void_p
    if not words or words[0] not in _C_TYPES:
        raise AbiError(f"a C type the runtime does not bind: {declaration!r}")
    return _C_TYPES[words[0]]


def bind_functions(library: ctypes.CDLL) -> dict[str, tuple[Any, list[Any]]]:
    """Set every function's ctypes signature (restype, argtypes) from the library's own table,
    ``kinegen_functions`` (name, result type, parameter list as kinegen_solver.h declares them):
    no signature is written on the Python side. Returns name -> (restype, argtypes)."""
    bound = {}
    for entry in _entries(library.kinegen_functions, _Function):
        name, parameters = entry.name.decode(), entry.parameters.decode().strip()
        if not (parameters.startswith("(") and parameters.endswith(")")):
            raise AbiError(f"{name}: a parameter list {parameters!r}")
        inner = parameters[1:-1].strip()
        argtypes = [] if inner in ("", "void") else [c_type(p) for p in inner.split(",")]
        function = getattr(library, name)
        function.restype, function.argtypes = c_type(entry.result.decode()), argtypes
        bound[name] = (function.restype, argtypes)
    return bound


class Abi:
    """The structs (``struct(name)``) and status codes (``status[name]``) of one loaded library."""

    def __init__(self, library: ctypes.CDLL) -> None:
        self.library = library
        self._fields: dict[str, list[tuple[str, str, int, int]]] = {}
        for e in _entries(library.kinegen_fields, _Field):
            self._fields.setdefault(e.structure.decode(), []).append((e.name.decode(), e.type.decode(), e.offset, e.size))
        self._sizes = {e.name.decode(): e.size for e in _entries(library.kinegen_structs, _Struct)}
        #: status name -> code (``kinegen_status``)
        self.status = {name.decode(): code for code, name in enumerate(_entries(library.kinegen_status_names, ctypes.c_char_p))}
        self._status_names = {code: name for name, code in self.status.items()}
        #: the frames kernel's layout as the C runtime reads it: (name, offset, count)
        self.frame_fields = tuple((e.name.decode(), e.offset, e.count) for e in _entries(library.kinegen_frame_fields, _FrameField))
        self._structs: dict[str, type[ctypes.Structure]] = {}

    def status_name(self, code: int) -> str:
        """A status code's name in the library's table (``status <code>`` for one it does not list)."""
        return self._status_names.get(code, f"status {code}")

    def check_frames(self, declared: tuple[tuple[str, int], ...]) -> None:
        """:class:`AbiError` unless the C runtime reads a body's frame values where a module
        declares them (``FRAME_FIELDS``: name and count, in order)."""
        offsets = tuple((name, at.start, at.stop - at.start) for name, at in frame_slices(declared).items())
        if offsets != self.frame_fields:
            raise AbiError(f"the C runtime's frame layout {self.frame_fields} is not the module's {offsets}")

    def struct(self, name: str) -> type[ctypes.Structure]:
        """The ctypes structure of the C struct ``name``, at the offsets the library states
        (explicit padding between fields; a gap wider than any alignment means a field the
        description leaves out, and is an :class:`AbiError`)."""
        if name in self._structs:
            return self._structs[name]
        if name not in self._sizes or name not in self._fields:
            raise AbiError(f"the library does not describe the struct {name}")
        fields: list[tuple[str, Any]] = []
        position = 0
        for field, kind, offset, size in sorted(self._fields[name], key=lambda f: f[2]):
            gap = offset - position
            if gap < 0 or gap >= 8:
                raise AbiError(f"the library's description of {name} leaves bytes {position} to {offset} undescribed")
            if gap:
                fields.append((f"_pad{position}", ctypes.c_ubyte * gap))
            fields.append((field, self._type(kind, size)))
            position = offset + size
        if not 0 <= self._sizes[name] - position < 8:
            raise AbiError(f"the library's description of {name} ends at byte {position} of {self._sizes[name]}")
        if self._sizes[name] > position:
            fields.append(("_pad_end", ctypes.c_ubyte * (self._sizes[name] - position)))
        made = type(name, (ctypes.Structure,), {"_pack_": 1, "_fields_": fields})
        if ctypes.sizeof(made) != self._sizes[name]:  # pragma: no cover -- explicit padding makes them equal
            raise AbiError(f"{name}: laid out in {ctypes.sizeof(made)} bytes, the library says {self._sizes[name]}")
        self._structs[name] = made
        return made

    def _type(self, kind: str, size: int) -> Any:
        if kind in _SCALARS:
            scalar = _SCALARS[kind]
            count, rest = divmod(size, ctypes.sizeof(scalar))
            if rest or not count:
                raise AbiError(f"a field of type {kind} of {size} bytes")
            return scalar if count == 1 else scalar * count
        if kind in _POINTERS:
            return _POINTERS[kind]
        return self.struct(kind)

    def assign(self, instance: ctypes.Structure, values: Mapping[str, Any]) -> None:
        """Set fields of an instance of a struct made by :meth:`struct`, by name (a field the
        library's struct does not have is an :class:`AbiError`, not silently ignored)."""
        name = type(instance).__name__
        known = {f for f, _, _, _ in self._fields[name]}
        for field, value in values.items():
            if field not in known:
                raise AbiError(f"the library's {name} has no field {field}")
            setattr(instance, field, value)

    def kernels(self, count: int, address: int) -> dict[str, BoundKernel]:
        """The ``count`` kernels of a ``kinegen_kernel`` table at ``address``, by name."""
        if not count:
            return {}
        entries = (self.struct("kinegen_kernel") * count).from_address(address)
        out = {}
        for entry in entries:
            outputs = ctypes.cast(entry.output_names, ctypes.POINTER(ctypes.c_char_p))
            names = tuple(outputs[k].decode() for k in range(entry.n_outputs))
            sizes = tuple(entry.output_sizes[k] for k in range(entry.n_outputs))
            name = entry.name.decode()
            out[name] = BoundKernel(name, tuple(entry.slots.decode().split(",")), names, sizes, KERNEL_CALL(entry.call))
        return out


def _entries(symbol: Any, kind: Any) -> list:
    """The entries of a table the library exports (``kind``: a ctypes structure, or a pointer
    type), up to the one whose first member is NULL."""
    table = ctypes.cast(symbol, ctypes.POINTER(kind))
    out, k = [], 0
    while (table[k] if kind is ctypes.c_char_p else getattr(table[k], kind._fields_[0][0])) is not None:
        out.append(table[k])
        k += 1
    return out


@dataclass(frozen=True)
class BoundKernel:
    """A compiled kernel as its table declares it: argument slots, outputs (names and sizes) and
    its entry point. :meth:`bind` fixes the argument and output arrays once, for repeated calls."""

    name: str
    slots: tuple[str, ...]
    outputs: tuple[str, ...]
    sizes: tuple[int, ...]
    entry: Any

    def bind(self, arguments: dict[str, np.ndarray], outputs: dict[str, np.ndarray]) -> Any:
        """A call without arguments that runs the kernel on these arrays (C-contiguous doubles,
        kept alive by the caller; a ``t`` argument: an array of one value)."""
        for name, size in zip(self.outputs, self.sizes):
            if outputs[name].size < size:
                raise ValueError(f"kernel {self.name}: output {name} needs {size} values, got {outputs[name].size}")
        x = (ctypes.c_void_p * max(1, len(self.slots)))(*(arguments[s].ctypes.data for s in self.slots))
        y = (ctypes.c_void_p * max(1, len(self.outputs)))(*(outputs[o].ctypes.data for o in self.outputs))
        entry = self.entry

        def call() -> None:
            entry(x, y)

        call.keep = (x, y)  # the pointer arrays live as long as the call
        return call
