"""The declared interface between generated code and the runtime (issue 26): the compiled library
describes its structs, status codes, frame layout and kernels, and the runtime binds by that
description; a kernel declared in the description reaches the Python module, the C and the
runtime's binding with no other edit; the service layer loads or rebuilds a module by one rule."""

from __future__ import annotations

import ctypes
import dataclasses
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import GENERATED, MODELS, generated_system, model

from kinegen import rotations
from kinegen.api import Session
from kinegen.codegen import generate
from kinegen.codegen.backends import get as backend
from kinegen.codegen.kernels import Kernel, Output, describe
from kinegen.runtime import from_module, kinematics, load_module, solve
from kinegen.runtime.abi import Abi, AbiError
from kinegen.runtime.native import SOLVER_SOURCES, build_library, native_case, with_solver

CC = shutil.which("cc") or shutil.which("gcc")


def _solver_abi() -> Abi:
    """The self-description of the C solver, from a library built with the committed boom's C."""
    stem = GENERATED / "boom_quaternion"
    library = build_library(with_solver({f"{stem.name}{s}": (stem.with_suffix(s)).read_text() for s in (".c", ".h")}))
    return Abi(ctypes.CDLL(str(library)))


def test_the_runtime_lays_out_every_struct_from_the_library_and_knows_no_status_code_of_its_own():
    """The table in kinegen_solver.c names every field the header declares (read from the header's
    text here, independently), and the ctypes layout built from it puts each where C does."""
    abi = _solver_abi()
    header = (SOLVER_SOURCES / "kinegen_solver.h").read_text()
    declared = _header_fields(header)
    assert {"kinegen_options", "kinegen_model", "kinegen_design", "kinegen_solver", "kinegen_layout", "kinegen_kernel", "kinegen_roles"} <= set(declared)
    for name, fields in declared.items():
        if name in ("kinegen_field", "kinegen_struct", "kinegen_frame_field", "kinegen_function"):  # the description's own entries
            continue
        struct = abi.struct(name)
        assert [f for f, *_ in abi._fields[name]] == fields, name
        for field, _, offset, size in abi._fields[name]:
            assert getattr(struct, field).offset == offset and getattr(struct, field).size == size, (name, field)
    # the status names by code, as the header's enum numbers them
    for status, code in abi.status.items():
        assert f"KINEGEN_{status.upper()} = {code}" in header
    assert abi.status["ok"] == 0 and len(set(abi.status.values())) == len(abi.status) == 7


def _header_fields(header: str) -> dict[str, list[str]]:
    """Struct name -> its field names in order, from the header's ``typedef struct name { ... } name;``."""
    text = re.sub(r"/\*.*?\*/", "", header, flags=re.DOTALL)
    out = {}
    for name, body in re.findall(r"typedef struct (\w+) \{(.*?)\} \1;", text, flags=re.DOTALL):
        fields = []
        for declaration in body.split(";"):
            declaration = declaration.strip()
            if not declaration:
                continue
            pointer = re.match(r".*?\(\*(\w+)\)\s*\(", declaration, flags=re.DOTALL)
            if pointer:
                fields.append(pointer.group(1))
                continue
            _, names = re.match(r"((?:const\s+)?\w+(?:\s+const)?)\s+(.*)", declaration, flags=re.DOTALL).groups()
            fields += [re.sub(r"[\s*]|\bconst\b|\[.*\]", "", n) for n in names.split(",")]
        out[name] = fields
    return out


@pytest.mark.skipif(CC is None, reason="needs a C compiler")
def test_a_library_whose_description_leaves_out_a_field_is_refused(tmp_path):
    """A struct whose table misses a field (a drifted description) is an AbiError, not a wrong layout."""
    source = tmp_path / "drifted.c"
    source.write_text(
        "#include <stddef.h>\n"
        "typedef struct { double a; double b; int c; } kinegen_options;\n"
        "typedef struct { const char *structure, *name, *type; int offset, size; } field;\n"
        "typedef struct { const char *name; int size; } size;\n"
        "const field kinegen_fields[] = {{\"kinegen_options\", \"a\", \"double\", 0, 8},"
        " {\"kinegen_options\", \"c\", \"int\", (int)offsetof(kinegen_options, c), 4}, {0, 0, 0, 0, 0}};\n"
        "const size kinegen_structs[] = {{\"kinegen_options\", (int)sizeof(kinegen_options)}, {0, 0}};\n"
        "const char *const kinegen_status_names[] = {\"ok\", 0};\n"
        "typedef struct { const char *name; int offset, count; } frame;\n"
        "const frame kinegen_frame_fields[] = {{0, 0, 0}};\n"
    )
    library = tmp_path / "drifted.so"
    subprocess.run([CC, "-shared", "-fPIC", "-o", str(library), str(source)], check=True)
    abi = Abi(ctypes.CDLL(str(library)))
    with pytest.raises(AbiError, match=r"kinegen_options leaves bytes 8 to 16 undescribed"):
        abi.struct("kinegen_options")
    with pytest.raises(AbiError, match="frame layout"):
        abi.check_frames((("origin", 3),))


def test_a_frame_layout_other_than_the_runtimes_is_refused():
    abi = _solver_abi()
    module = load_module(GENERATED / "boom_quaternion.py")
    abi.check_frames(tuple(tuple(f) for f in module.FRAME_FIELDS))
    swapped = list(module.FRAME_FIELDS)
    swapped[2], swapped[3] = swapped[3], swapped[2]
    with pytest.raises(AbiError, match="frame layout"):
        abi.check_frames(tuple(tuple(f) for f in swapped))


def test_a_kernel_declared_in_the_description_reaches_python_c_and_the_binding(tmp_path):
    """Declaring a kernel (here: the joint rows' residuals alone, from a section the description
    already has) is all it takes: the Python module gets a function for its output, the C an entry
    in the case's kernel table, and the runtime binds it by that table -- the values agree."""
    boom, param = model("boom"), rotations.get("quaternion")
    description = describe(boom, param)
    joints = description.sections["joints_phi"]
    for case in description.cases.values():
        case.kernels["joint_residuals"] = Kernel("joint_residuals", ("q",), (Output("residuals", ("joints_phi",), joints.size),),
                                                 "The joint rows' residuals (a kernel declared by a test).")  # fmt: skip
    stem = "boom_quaternion"
    files = {**backend("c")(description, stem, standalone=False), **backend("python")(description, stem)}
    from kinegen.codegen import write_files

    write_files(tmp_path, files)  # kinegen's own files (the trust store), as a build writes them
    import hashlib

    c_files = {n: hashlib.sha256((tmp_path / n).read_bytes()).hexdigest() for n in (f"{stem}.c", f"{stem}.h")}
    module = load_module(tmp_path / f"{stem}.py")
    module.C_FILES = c_files  # (generate() records them; here the backends were called directly)
    native = native_case(module, "swing")
    python = module.CASES["swing"]["outputs"]["residuals"]
    q = np.array(module.INITIAL_Q) + 0.01 * np.arange(len(module.INITIAL_Q))
    (values,) = native.run("joint_residuals", q=q)
    assert np.abs(values - python(q)).max() <= 1e-15 * max(1.0, np.abs(values).max())
    assert np.abs(values).max() > 1e-3  # away from the solution: a real comparison


def test_the_actuator_lengths_kernel_equals_the_lengths_from_the_point_positions():
    """``lengths`` (a kernel added by declaring it: codegen/kernels.py only) in Python and C, along
    the digging case, against the lengths computed from the solved poses' point positions."""
    system = generated_system("excavator_quaternion", "digging", compiled=True)
    results = solve(system)
    module = load_module(GENERATED / "excavator_quaternion.py")
    p = list(system.design.values())
    python = np.asarray(module.lengths(results.q.T, p))  # (actuators, K)
    reference = np.stack([kinematics.actuator_length(results, name) for name in module.ACTUATORS])
    assert np.abs(python - reference).max() <= 1e-12
    native = np.stack([system.native.run("lengths", q=q)[0] for q in results.q[::17]], axis=1)
    assert np.abs(native - reference[:, ::17]).max() <= 1e-12


def test_the_session_loads_a_fresh_module_and_rebuilds_a_stale_one_once(tmp_path):
    folder = tmp_path / "generated"
    folder.mkdir()
    model_file = tmp_path / "four_bar.yaml"
    model_file.write_text((MODELS / "four_bar.yaml").read_text())
    said: list[str] = []
    session = Session(folder, announce=said.append)
    first = session.solve(model_file, "crank_turn")
    assert len(said) == 1 and "missing or stale" in said[0]
    assert session.module(model_file) is session.module(model_file) and len(said) == 1
    fresh = Session(folder, announce=said.append)
    again = fresh.solve(model_file, "crank_turn")
    assert len(said) == 1  # fresh on disk: loaded, not rebuilt
    assert np.array_equal(first.q, again.q)
    model_file.write_text(model_file.read_text() + "\n# edited\n")
    Session(folder, announce=said.append).module(model_file)
    assert len(said) == 2  # the model file changed: rebuilt
    with pytest.raises(KeyError, match="no case"):
        fresh.system(model_file, "no_such_case")


def test_the_service_layer_and_the_runtime_give_the_same_solution():
    """Session.solve is from_module + solve on the committed module, nothing else."""
    direct = solve(from_module(load_module(GENERATED / "four_bar_quaternion.py", MODELS / "four_bar.yaml"), "crank_turn"))
    through = Session(GENERATED).solve(MODELS / "four_bar.yaml", "crank_turn")
    assert np.array_equal(direct.q, through.q) and dataclasses.is_dataclass(through.system)


def test_generate_records_the_c_files_the_module_belongs_to():
    made = generate(model("boom"), rotations.get("quaternion"))
    import hashlib

    module_text = made["python"]["boom_quaternion.py"]
    for name, text in made["c-model"].items():
        assert hashlib.sha256(text.encode()).hexdigest() in module_text, name
    assert Path(GENERATED / "boom_quaternion.c").read_text() == made["c-model"]["boom_quaternion.c"]


@pytest.mark.parametrize("param", ["quaternion", "euler-parameters", "euler:zxz", "dual-quaternion", "dual-euler-parameters"])
def test_the_update_of_a_step_is_defined_once_and_both_runtimes_follow_it(param):
    """The symbolic retraction (the definition) evaluated by SymPy, the NumPy retract of the Python
    runtime and the C retract printed from the definition (called in the compiled library) agree,
    for ordinary steps, steps about the quaternion's series threshold (angles ~0.03) and steps
    under the small-angle branches (1e-10)."""
    import sympy as sp

    parametrization = rotations.get(param)
    rng = np.random.default_rng(7)
    k = 12
    q = rng.normal(size=(parametrization.nq, k))
    if param != "euler:zxz":  # a unit quaternion / dual quaternion
        q = parametrization.project(q) if parametrization.nq == 7 else q
    if param.startswith("dual"):
        q[:4] /= np.linalg.norm(q[:4], axis=0)
        q[4:] -= q[:4] * np.einsum("ik,ik->k", q[:4], q[4:])  # real part orthogonal to the dual part
    step = rng.normal(scale=0.3, size=(parametrization.nv, k))
    step[:, : k // 2] *= 1e-10
    step[:, k // 2 : 3 * k // 4] *= 0.06  # angles ~0.03: on either side of qa.SERIES_BELOW
    numpy_moved = parametrization.retract(q, step)
    qs, ss = sp.symbols(f"q0:{parametrization.nq}", real=True), sp.symbols(f"s0:{parametrization.nv}", real=True)
    exprs = parametrization.retraction(sp.Matrix(qs), sp.Matrix(ss))
    for j in range(k):
        values = {**dict(zip(qs, q[:, j])), **dict(zip(ss, step[:, j]))}
        exact = np.array([float(e.xreplace(values).evalf(30)) for e in exprs])
        assert np.abs(numpy_moved[:, j] - exact).max() <= 1e-14, (param, j)
    stem = {"quaternion": "boom_quaternion", "euler-parameters": "boom_euler_parameters", "euler:zxz": "boom_euler_zxz",
            "dual-quaternion": "boom_dual_quaternion", "dual-euler-parameters": "boom_dual_euler_parameters"}[param]  # fmt: skip
    native = generated_system(stem, compiled=True).native
    retract = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)(native.model.retract)
    for j in range(k):  # the boom has one body: its retract is retract_body
        moved = np.ascontiguousarray(q[:, j])
        retract(moved.ctypes.data, np.ascontiguousarray(step[:, j]).ctypes.data)
        assert np.abs(moved - numpy_moved[:, j]).max() <= 1e-14, (param, j)


def _import_graph() -> dict[str, set[str]]:
    """Every import of one kinegen module by another, module-level or inside a function (type-only
    imports under TYPE_CHECKING aside): module -> the modules it imports."""
    import ast

    package = Path(__file__).resolve().parents[1] / "kinegen"
    modules = {}
    for file in package.rglob("*.py"):
        parts = file.relative_to(package.parent).with_suffix("").parts
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = file
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, file in modules.items():
        tree = ast.parse(file.read_text())
        typing_only = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
                       for n in ast.walk(node)}  # fmt: skip
        for node in ast.walk(tree):
            if id(node) in typing_only:
                continue
            if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("kinegen"):
                targets = [node.module, *(f"{node.module}.{a.name}" for a in node.names)]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                continue
            graph[name] |= {t for t in targets if t in modules and t != name}
    return graph


def test_no_import_cycle_among_kinegens_modules():
    """No module reaches itself through its imports."""
    graph = _import_graph()
    # a cycle is a module reachable from one of its own imports
    for start in graph:
        seen, frontier = set(), list(graph[start])
        while frontier:
            module = frontier.pop()
            assert module != start, f"import cycle through {start}"
            if module not in seen:
                seen.add(module)
                frontier += graph[module]


def test_the_layers_import_only_downwards():
    """The runtime below the force analyses, both below the analyses, all of them below the
    command line and the main job: no import points up (the working range's continuation and the
    figure helpers live below forces and analysis, which both use them)."""
    above = {
        "kinegen.runtime": ("kinegen.forces", "kinegen.analysis", "kinegen.explore"),
        "kinegen.forces": ("kinegen.analysis", "kinegen.explore"),
        "kinegen.figures": ("kinegen.forces", "kinegen.analysis", "kinegen.runtime"),
    }
    top = ("kinegen.cli", "kinegen.demo")
    for module, imports in _import_graph().items():
        for target in imports:
            assert not target.startswith(top) or module.startswith(top), f"{module} imports {target}"
            for layer, forbidden in above.items():
                if module == layer or module.startswith(layer + "."):
                    assert not target.startswith(forbidden), f"{module} imports {target}, a layer above it"


def test_kinds_are_listed_once_and_every_listed_kind_has_its_equations():
    """The loader, the constraint builders, the studies and the CLI's choices read one list each;
    a kind listed without equations (or equations of an unlisted kind) stops the import."""
    from kinegen.analysis.studies import DESIGN_MEASURES, MEASURES
    from kinegen.constraints import drivers, joints
    from kinegen.model import loader
    from kinegen.model.kinds import DRIVER_KINDS, JOINT_KINDS, check_registered
    from kinegen.model.schema import QUANTITY_KINDS

    assert set(joints.BUILDERS) == set(JOINT_KINDS) and set(drivers.BUILDERS) == set(DRIVER_KINDS)
    assert loader.JOINT_TYPES == tuple(JOINT_KINDS) and loader.DRIVER_TYPES == tuple(DRIVER_KINDS)
    assert set(MEASURES) | set(DESIGN_MEASURES) | {"working_range"} == set(QUANTITY_KINDS)
    assert not set(MEASURES) & set(DESIGN_MEASURES)
    with pytest.raises(ImportError, match=r"kinds without equations \['helical'\]"):
        check_registered("joints", {**JOINT_KINDS, "helical": None}, joints.BUILDERS)
    for name, kind in JOINT_KINDS.items():  # each kind's equation count, as its builder gives it, for the model shipped with it
        for m in ("boom", "four_bar", "rssr", "slider_crank", "excavator"):
            for joint in model(m).joints:
                if joint.type == name:
                    from kinegen.constraints.joints import joint_equations
                    from kinegen.symbolic.assembly import GROUND_FRAME, coordinates

                    for param in ("quaternion", "dual-quaternion"):
                        frames = {b.name: b.frame for b in coordinates(model(m), rotations.get(param)).bodies}
                        rows = joint_equations(joint, frames.get(joint.body1, GROUND_FRAME), frames.get(joint.body2, GROUND_FRAME), ())
                        assert len(rows) == kind.equations, (m, joint.name, param)
    assert rotations.get("euler:zxz").name in rotations.SHOWN and set(rotations.SHOWN) <= set(rotations.NAMES)


def test_a_case_named_jac_gets_distinct_temporaries_and_the_same_values(tmp_path):
    """Temporaries are named by the section's place in a function, not by a test on its name:
    a case called ``jac`` (whose driver sections' names end in 'jac') builds, and its plain-float,
    NumPy and compiled Phi/Phi_q agree."""
    text = (MODELS / "four_bar.yaml").read_text().replace("  crank_turn:", "  jac:")
    model_file = tmp_path / "four_bar.yaml"
    model_file.write_text(text)
    system = Session(tmp_path / "generated").system(model_file, "jac")
    source = (tmp_path / "generated" / "four_bar_quaternion.py").read_text()
    for function in source.split("\n\n\ndef ")[1:]:  # no temporary assigned twice in one function
        names = re.findall(r"^    (\w+) = ", function, flags=re.MULTILINE)
        temporaries = [n for n in names if re.fullmatch(r"[cdefgh]\d+", n)]
        assert len(temporaries) == len(set(temporaries)), function.splitlines()[0]
    q = system.initial_q + 0.01
    u = system.driver_inputs(0.3)[0]
    phi_s, jac_s = system.phi_jac_s(q.tolist(), u.tolist())
    assert np.abs(np.array(phi_s) - system.phi(q, u)).max() <= 1e-15 and np.abs(np.array(jac_s) - system.jac(q, u)).max() <= 1e-15
    phi_c, jac_c = system.native.evaluate(q, u)
    assert np.abs(phi_c - system.phi(q, u)).max() <= 1e-14 and np.abs(jac_c - system.jac(q, u)).max() <= 1e-14


def test_the_runtime_binds_every_shared_kernel_from_the_declaration_alone():
    """NumericSystem.kernels holds every kernel a module declares for all its cases, bound from
    KERNELS alone (slots, outputs; p bound): the declared set, and each output equal to the
    module's own function at a batch of configurations -- the supply kernel among them, which
    kinegen.forces.supply calls."""
    module = load_module(GENERATED / "excavator_quaternion.py")
    system = from_module(module, "digging", compiled=False)
    shared = {name for name, (_, outputs) in module.KERNELS.items() if all(hasattr(module, o) for o in outputs)}
    assert set(system.kernels) == shared and {"frames", "inertia", "supply", "loads", "actuation"} <= shared
    results = solve(system)
    q, v = results.q.T[:, ::40], results.v.T[:, ::40]
    p = [system.design[name] for name in module.DESIGN]
    force = np.random.default_rng(5).normal(scale=1e5, size=(len(system.statics.elements), q.shape[1]))
    outputs = system.kernels["supply"](q, v, force)
    assert len(outputs) == len(module.KERNELS["supply"][1])
    for name, values in zip(module.KERNELS["supply"][1], outputs):
        assert np.array_equal(np.broadcast_arrays(*values), np.broadcast_arrays(*getattr(module, name)(q, v, force, p))), name


def _python_columns(values, size: int, count: int) -> np.ndarray:
    """A Python kernel output at a batch as (size, count): rows that are constants broadcast."""
    if isinstance(values, np.ndarray) and values.ndim == 2 and values.shape[1] == count:
        return values.reshape(size, count)
    return np.array([np.broadcast_to(np.asarray(x, dtype=float), (count,)) for x in values]).reshape(size, count)


def test_every_compiled_kernel_runs_over_a_batch_in_one_call_with_the_python_functions_values():
    """kinegen_kernel_each (NativeCase.each) runs any declared kernel -- the case's, the layout's and
    the complete library's sensitivity kernels -- over a batch of configurations in one C call: each
    output equal to the Python module's function at the same batch (to rounding), one configuration
    giving the batch's column, and an argument of a wrong length refused before C reads it."""
    module = load_module(GENERATED / "excavator_quaternion.py")
    system = generated_system("excavator_quaternion", "digging", compiled=True)
    native = system.native.sensitivity_case()
    assert native is not None and {"dvel", "dacc", "phi_p", "frames_d", "actuation", "supply", "inputs"} <= set(native.kernels)
    results = solve(system)
    rng = np.random.default_rng(11)
    take = slice(None, None, 23)
    count = len(results.times[take])
    n_v, n_inputs = system.n_velocity, system.n_inputs
    arguments = {
        "q": results.q[take].T + 1e-3 * rng.normal(size=(system.n_stored, count)), "v": results.v[take].T, "a": results.a[take].T,
        "u": results.inputs[take].T, "ud": rng.normal(size=(n_inputs, count)), "udd": rng.normal(size=(n_inputs, count)),
        "t": results.times[take], "span": np.array([results.times[take], results.times[take] + 0.01]),
        "w": rng.normal(size=(n_v, count)), "y": rng.normal(size=(n_v, count)), "z": rng.normal(size=(n_v, count)),
        "f": rng.normal(scale=1e5, size=(len(system.statics.elements), count)),
    }  # fmt: skip
    p = [system.design[name] for name in module.DESIGN]
    outputs = module.CASES["digging"]["outputs"]
    for name, kernel in native.kernels.items():
        compiled = native.each(name, **{s: arguments[s] for s in kernel.slots if s != "p"})
        slots = [arguments[s] if s != "p" else p for s in kernel.slots]
        batch = kernel.slots != ("p",)  # (the design's own kernels: one value each)
        for output, size, values in zip(kernel.outputs, kernel.sizes, compiled):
            python = outputs[output] if output in outputs else getattr(module, output)
            expected = _python_columns(python(*slots), size, count) if batch else np.asarray(python(p), dtype=float).reshape(size)
            assert values.shape == ((size, count) if batch else (size,)), (name, output)
            assert np.allclose(values, expected, rtol=1e-12, atol=1e-12 * max(1.0, np.abs(expected).max())), (name, output)
        if not batch:
            continue
        one = native.each(name, **{s: arguments[s][..., 5] for s in kernel.slots if s != "p"})
        assert all(np.array_equal(x, values[:, 5]) for x, values in zip(one, compiled)), name
    for wrong in (arguments["q"][:-1], 1.0):
        with pytest.raises(ValueError, match="argument q of shape"):
            native.each("actuation", q=wrong)
    # the compiled system's force-solve kernel is this one
    matrix = system.statics.matrix(arguments["q"])
    assert np.allclose(matrix, _python_columns(module.actuation_matrix(arguments["q"], p), len(matrix), count), rtol=1e-12, atol=1e-9)
