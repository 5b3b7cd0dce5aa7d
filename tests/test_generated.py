"""Generated modules: fresh, reproducible byte for byte, written atomically, batch = single."""

from __future__ import annotations

import ast
import hashlib
import os
import re
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kinegen import rotations
from kinegen.codegen import build, built_with_sensitivities, write_atomic, writer
from kinegen.codegen.inmemory import lambdify_model
from kinegen.errors import GeneratedModuleError, ModelError
from kinegen.runtime import from_module, load_module, solve
from tests.conftest import GENERATED, MODELS, ROOT, generated_system, model

COMMITTED = sorted(GENERATED.glob("*.py"))


def header_field(text: str, name: str) -> str:
    return re.search(rf"^{name}:\s+(\S+)$", text, re.MULTILINE).group(1)


def test_there_are_committed_modules():
    assert len(COMMITTED) >= 9


@pytest.mark.parametrize("path", COMMITTED, ids=lambda p: p.stem)
def test_committed_module_is_fresh(path):
    """Regenerating from models/ must give the committed files byte for byte: the Python module
    (what this kinegen writes for the model, regenerated once per content and code and then known
    to the trust store: the same check that lets the runtime load a module it did not write) and
    the model's C (``.c``, ``.h``) beside it, which the module names by their digests."""
    text = path.read_text()
    source = MODELS / header_field(text, "source")
    param = rotations.get(header_field(text, "parametrization"))
    assert writer.regenerates(path.read_bytes(), source, param.name, built_with_sensitivities(path), with_c=True), (
        f"{path.name} is stale: run `make generate`")  # fmt: skip
    named = load_module(path, source).C_FILES
    assert set(named) == {path.with_suffix(".c").name, path.with_suffix(".h").name}
    for name, digest in named.items():
        assert hashlib.sha256((GENERATED / name).read_bytes()).hexdigest() == digest, f"{name} is stale: run `make generate`"


def test_generation_does_not_depend_on_hash_seed():
    """The excavator (every kind of kernel: sensitivities, forces, supply, piecewise inputs), Python
    module and C, built under three ``PYTHONHASHSEED`` values at once (and a fourth, random one in
    the committed-module check's test process): each gives the committed
    files' bytes (SymPy derives and prints, SymEngine differentiates and eliminates; neither may
    let Python's string hashing order a term). Each build forks: its sensitivity kernels are derived and
    printed in a forked process, beside the description and the printing of the rest (this test's own
    process, with threads, does not fork: the committed-module checks build there). The third build's
    forked process prints only the C, so this one derives the sensitivity entries again for the Python."""
    code = (
        "import hashlib, sys; from kinegen.codegen import backends, writer; from kinegen.model import load; "
        "from kinegen import rotations; printers = backends.printers; "
        "backends.printers = (lambda target: printers('c')) if sys.argv[2] == 'c-only' else printers; "
        "made = writer.generate(load(sys.argv[1]), rotations.get('quaternion')); "
        "print(*sorted(f'{n} {hashlib.sha256(t.encode()).hexdigest()}' for f in made.values() for n, t in f.items()), sep='\\n')"
    )
    seeds = ("0", "4242", "7")
    runs = [
        subprocess.Popen([sys.executable, "-c", code, str(MODELS / "excavator.yaml"), "c-only" if seed == "7" else "all"],
                         env=dict(os.environ, PYTHONHASHSEED=seed), cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for seed in seeds
    ]  # fmt: skip
    committed = "\n".join(
        f"{name} {hashlib.sha256((GENERATED / name).read_bytes()).hexdigest()}"
        for name in sorted(f"excavator_quaternion{suffix}" for suffix in (".c", ".h", ".py"))
    )
    for seed, run in zip(seeds, runs):
        out, err = run.communicate(timeout=600)
        assert run.returncode == 0, err
        assert out.strip() == committed, f"PYTHONHASHSEED={seed} builds other bytes than generated/ holds"


def test_header_names_model_parametrization_hash_and_version():
    text = (GENERATED / "boom_quaternion.py").read_text()
    assert header_field(text, "model") == "boom"
    assert header_field(text, "parametrization") == "quaternion"
    assert header_field(text, "source sha256") == model("boom").source_sha256
    assert re.search(r"^kinegen version:\s+\d+\.\d+\.\d+$", text, re.MULTILINE)
    assert re.search(r"^    c\d+ = ", text, re.MULTILINE), "common subexpressions are hoisted"


def test_failed_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    target = tmp_path / "module.py"
    target.write_text("old")

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError):
        write_atomic(target, "new")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["module.py"]


def test_failed_build_leaves_generated_folder_untouched(tmp_path):
    out = tmp_path / "generated"
    out.mkdir()
    (out / "keep.py").write_text("x = 1\n")
    bad = tmp_path / "bad.yaml"
    bad.write_text((MODELS / "boom.yaml").read_text().replace("joint: pivot", "joint: nowhere"))
    with pytest.raises(ModelError):
        build(bad, "quaternion", out)
    assert [p.name for p in out.iterdir()] == ["keep.py"]


def test_half_the_statements_printed_in_a_forked_process_give_the_bytes_one_process_gives(monkeypatch, tmp_path):
    """writer.generate where it may fork eliminates and prints every other group in a child process,
    and renders the Python module in one while it renders the C (the C files' digests put in after):
    the same bytes as one process gives, and ``ready`` still sees the C before the Python."""
    from kinegen.codegen.backends import python as python_backend

    rendered_by = tmp_path / "pids"
    render = python_backend.render

    def recorded(description, stem):
        with rendered_by.open("a") as out:
            out.write(f"{os.getpid()}\n")
        return render(description, stem)

    monkeypatch.setattr(python_backend, "render", recorded)
    made, seen, renderers = {}, {}, {}
    for fork in (False, True):
        monkeypatch.setattr(writer, "may_fork", lambda fork=fork: fork)
        seen[fork] = []
        made[fork] = writer.generate(model("four_bar"), rotations.get("quaternion"), ready=lambda target, files, fork=fork: seen[fork].append(target))
        renderers[fork] = rendered_by.read_text().split()
        rendered_by.unlink()
    assert made[True] == made[False]
    assert seen[True] == seen[False] == ["c-model", "python"]
    assert renderers[False] == [str(os.getpid())] and len(renderers[True]) == 1 and renderers[True] != renderers[False]
    text = made[True]["python"]["four_bar_quaternion.py"]
    named = ast.literal_eval(re.search(r"^C_FILES = (.*)$", text, re.MULTILINE).group(1))
    assert named == {name: hashlib.sha256(text.encode()).hexdigest() for name, text in made[True]["c-model"].items()}


def test_the_garbage_collector_is_paused_while_a_model_is_generated_and_changes_no_byte(monkeypatch):
    """writer.generate runs with Python's cyclic garbage collector paused (kinegen.collector):
    paused while the targets are ready, enabled again after -- left disabled when it was -- and the
    same bytes as a generation with the collector running throughout."""
    import gc

    states = []
    assert gc.isenabled()
    paused = writer.generate(model("four_bar"), rotations.get("quaternion"), ready=lambda target, files: states.append(gc.isenabled()))
    assert states == [False, False] and gc.isenabled()
    gc.disable()
    try:
        writer.generate(model("slider_crank"), rotations.get("quaternion"))
        assert not gc.isenabled()
    finally:
        gc.enable()
    monkeypatch.setattr(gc, "disable", lambda: None)  # the pause a no-op: the collector runs throughout
    states.clear()
    running = writer.generate(model("four_bar"), rotations.get("quaternion"), ready=lambda target, files: states.append(gc.isenabled()))
    assert states == [True, True] and running == paused


def test_the_python_modules_place_for_the_c_digests_is_filled_once_or_refused():
    """Where the Python module is rendered before the model's C (in a forked process), its C_FILES holds a
    token for the digests: filled with their literal as the template prints it, and a text holding the
    token not exactly once is refused (a digest put in the wrong place would name other C)."""
    pending = writer._PendingDigests
    digests = {"m.h": "a" * 64, "m.c": "b" * 64}
    assert pending.filled(f"X = 1\nC_FILES = {pending()!r}\n", digests) == f"X = 1\nC_FILES = {digests!r}\n"
    for text in ("C_FILES = {}\n", f"C_FILES = {pending()!r}  # {pending()!r}\n"):
        with pytest.raises(RuntimeError, match="not one"):
            pending.filled(text, digests)


def test_compiled_templates_are_kept_in_the_cache_and_give_the_same_bytes(tmp_path, monkeypatch):
    """The backends' Jinja templates, compiled once into kinegen's cache (templates/), are loaded
    from there next time -- nothing compiled -- and render the same bytes; a cache that cannot be
    written (a file where its folder belongs) costs a compilation, not the build. (In one process:
    where it may fork, the Python module renders in a forked process, whose compilations this one
    would not see.)"""
    import jinja2

    from kinegen.codegen import templates

    monkeypatch.setattr(writer, "may_fork", lambda: False)

    def fresh_generate() -> dict:
        templates.environment.cache_clear()  # a new process's environment
        return writer.generate(model("four_bar"), rotations.get("quaternion"))

    try:
        monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path / "cache"))
        cold = fresh_generate()
        kept = sorted((tmp_path / "cache" / "templates").iterdir())
        assert len(kept) == 5 and all(path.stat().st_size > 0 for path in kept)  # functions, module (Python); functions, model .c, .h (C)
        compiled = []
        original = jinja2.Environment.compile
        monkeypatch.setattr(jinja2.Environment, "compile", lambda self, *a, **k: compiled.append(a[1]) or original(self, *a, **k))
        assert fresh_generate() == cold and compiled == []
        (tmp_path / "file").write_text("")
        monkeypatch.setenv("KINEGEN_CACHE", str(tmp_path / "file"))
        assert fresh_generate() == cold and len(compiled) == 5
    finally:
        templates.environment.cache_clear()  # the other tests' environment: kinegen's cache


def test_the_printers_own_methods_give_doprints_text_for_every_statement():
    """shapes.code prints with the printer's methods, not through doprint: each of the three printers
    gives doprint's text for every statement of the four-bar (the excavator's, sensitivity kernels
    too, are compared byte for byte with generated/ by the freshness tests above); an expression
    doprint would change (``re(...)``) is printed by doprint itself, and one doprint refuses is refused."""
    from sympy.printing.codeprinter import PrintMethodNotImplementedError

    from kinegen.codegen.backends.c.printer import CPrinter
    from kinegen.codegen.backends.python.printer import ModulePrinter, ScalarPrinter
    from kinegen.codegen.kernels import describe
    from kinegen.codegen.shapes import code

    description = describe(model("four_bar"), rotations.get("euler-parameters"))
    expressions = []
    for section in description.sections.values():
        for group in section.groups:
            statements = description.shapes.statements(group)
            expressions += [v for _, v in statements.temporaries] + [e for e in statements.outputs if e != 0]
    assert len(expressions) > 100
    x, y = sp.symbols("x y", real=True)
    odd = [sp.re(sp.Symbol("z")) * x, sp.Piecewise((x, y < 0), (x * y, True)), sp.sign(x) * sp.pi]
    for printer in (CPrinter(), ModulePrinter(), ScalarPrinter()):
        for expr in expressions + odd:
            try:
                expected = printer.doprint(expr)
            except PrintMethodNotImplementedError:  # the strict C printer has no re(): nor has code
                with pytest.raises(PrintMethodNotImplementedError):
                    code(printer, expr)
                continue
            assert code(printer, expr) == expected, (type(printer).__name__, expr)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_the_printers_sums_and_products_are_sympys_own_text(data):
    """kinegen's printers print sums and products with their precedences kept, and find each type's
    method once (PrecedenceOnce): on random expressions (negative, rational and float coefficients,
    negative and fractional powers, functions, nested sums; SymPy-evaluated and SymEngine's
    canonical form through engine.to_sympy; two unevaluated powers of a product), the text is that of
    SymPy's own _print, _print_Add, _print_Mul and parenthesize in each printer, and the kept
    precedence is SymPy's precedence (zoo's products too)."""
    import symengine as se
    from sympy.printing.c import C89CodePrinter
    from sympy.printing.codeprinter import CodePrinter
    from sympy.printing.precedence import precedence
    from sympy.printing.printer import Printer
    from sympy.printing.str import StrPrinter

    from kinegen.codegen.backends.c.printer import CPrinter
    from kinegen.codegen.backends.python.printer import ModulePrinter, ScalarPrinter
    from kinegen.codegen.expressions import _precedence
    from kinegen.codegen.shapes import code
    from kinegen.symbolic import engine

    symbols = sp.symbols("x y z", real=True)
    x, y, z = symbols
    unevaluated = [sp.Mul(z, sp.Pow(x * y, -1, evaluate=False), evaluate=False),  # SymPy parenthesizes 1/(x*y) twice
                   sp.Mul(-2, sp.Pow(x * y, -1, evaluate=False), sp.Pow(z + 1, -2), evaluate=False)]  # fmt: skip
    leaves = st.one_of(
        st.sampled_from(symbols), st.integers(-4, 4).map(sp.Integer), st.sampled_from([sp.Rational(-3, 7), sp.Rational(5, 2), sp.Float(-1.25), sp.Float(0.5)])
    )  # fmt: skip

    def grow(children):
        pair = st.tuples(children, children)
        return st.one_of(
            pair.map(lambda p: p[0] + p[1]), pair.map(lambda p: p[0] * p[1]), pair.map(lambda p: p[0] - p[1]),
            st.tuples(children, st.sampled_from([-1, -2, 2, 3, sp.Rational(1, 2), sp.Rational(-1, 2), sp.Rational(-3, 2)])).map(lambda p: p[0] ** p[1]),
            children.map(sp.sin), children.map(lambda e: sp.sqrt(e**2 + 1)), children.map(lambda e: -e),
        )  # fmt: skip

    expr = sp.sympify(data.draw(st.recursive(leaves, grow, max_leaves=12)))
    canonical = engine.to_sympy(se.sympify(expr), {s.name: s for s in symbols}, {})
    for e in (expr, canonical, sp.zoo * x * y, -sp.zoo * x):
        for node in sp.preorder_traversal(e):
            assert _precedence(node) == precedence(node), node
    for kind, product in ((CPrinter, C89CodePrinter._print_Mul), (ModulePrinter, CodePrinter._print_Mul), (ScalarPrinter, CodePrinter._print_Mul)):
        sympys = type("Sympys", (kind,), {"_print": Printer._print, "_print_Add": StrPrinter._print_Add, "_print_Mul": product,
                                          "parenthesize": StrPrinter.parenthesize})  # fmt: skip
        for e in (expr, canonical, *unevaluated):
            if e.has(sp.zoo, sp.nan, sp.oo, -sp.oo):
                continue
            kept, plain = kind(), sympys()
            kept.forget()
            assert code(kept, e) == code(plain, e), (kind.__name__, e)


def test_a_failure_printing_in_the_forked_process_is_raised_here_and_nothing_is_written(tmp_path, monkeypatch):
    import os

    from kinegen.codegen import shapes

    parent = os.getpid()
    printed = shapes.Shapes.printed_texts

    def broken(self, work):
        if os.getpid() != parent:  # the forked child's share only
            raise ModelError("four_bar.yaml", "joints", "the printing failed on purpose")
        return printed(self, work)

    monkeypatch.setattr(shapes.Shapes, "printed_texts", broken)  # in the child too: it is forked from here
    monkeypatch.setattr(writer, "may_fork", lambda: True)
    with pytest.raises(ModelError, match="failed on purpose") as raised:
        build(MODELS / "four_bar.yaml", "quaternion", tmp_path, keep=False)  # (derived: not from kinegen's cache)
    assert raised.value.file == "four_bar.yaml" and raised.value.entry == "joints"
    assert list(tmp_path.iterdir()) == []
    monkeypatch.setattr(shapes.Shapes, "printed_texts", lambda self, work: os._exit(3))  # a child that dies
    with pytest.raises(RuntimeError, match="exit code 3"):
        build(MODELS / "four_bar.yaml", "quaternion", tmp_path, keep=False)
    assert list(tmp_path.iterdir()) == []


def test_a_forked_child_whose_result_nobody_asks_for_is_stopped(tmp_path, monkeypatch):
    """The Python module renders in a forked process while this one renders the C: when the C fails,
    the error is raised here, nothing is written, and that process (its answer never read) is ended,
    not left blocked on its pipe until this process exits; so is any child dropped unanswered."""
    import gc
    import multiprocessing
    import time

    from kinegen.codegen.forked import Child

    def broken(description, stem, target):
        raise ModelError("four_bar.yaml", "joints", "the C failed on purpose")

    monkeypatch.setattr(writer, "may_fork", lambda: True)
    monkeypatch.setattr(writer, "_render_c", broken)
    with pytest.raises(ModelError, match="C failed on purpose"):
        build(MODELS / "four_bar.yaml", "quaternion", tmp_path, keep=False)
    gc.collect()
    assert list(tmp_path.iterdir()) == [] and not [p for p in multiprocessing.active_children() if p.name == "kinegen-child"]
    child = Child(time.sleep, 60)
    process = child._process
    assert process.is_alive()
    del child
    gc.collect()
    assert not process.is_alive() and process.exitcode is not None and process.exitcode < 0  # terminated


def test_stale_module_is_refused_with_rebuild_hint(tmp_path):
    path = build(MODELS / "boom.yaml", "quaternion", tmp_path)
    edited = tmp_path / "boom.yaml"
    edited.write_text((MODELS / "boom.yaml").read_text().replace("L: 1.78", "L: 1.80"))
    with pytest.raises(GeneratedModuleError, match=r"stale.*kinegen build"):
        load_module(path, edited)
    load_module(path, MODELS / "boom.yaml")  # the matching source is accepted


def _same_to_rounding(a, b) -> bool:
    """Equal up to a few ulps (vectorized and scalar sin/cos may round differently)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return bool(np.all(np.abs(a - b) <= 8 * np.finfo(float).eps * np.maximum(1.0, np.maximum(np.abs(a), np.abs(b)))))


@pytest.mark.parametrize("name", ["rssr_quaternion", "excavator_euler_parameters"])
def test_batch_single_and_scalar_code_agree(name):
    """The NumPy batch, NumPy single-configuration and plain-float (*_s) functions agree."""
    system = generated_system(name)
    results = solve(system)
    q, v, t = results.q[::20].T, results.v[::20].T, results.times[::20]
    u, ud, udd = system.driver_inputs(t)
    phi, jac, nu, gamma = system.phi(q, u), system.jac(q, u), system.nu(q, u, ud), system.gamma(q, v, u, ud, udd)
    assert phi.shape == (len(system.constraint_names), len(t))
    for k in range(len(t)):
        uk, udk, uddk = system.driver_inputs(t[k])
        qk, vk = q[:, k], v[:, k]
        single = (system.phi(qk, uk), system.jac(qk, uk), system.nu(qk, uk, udk), system.gamma(qk, vk, uk, udk, uddk))
        for batch, one in zip((phi, jac, nu, gamma), single):
            assert _same_to_rounding(batch[:, k], one)
        scalar_phi, scalar_jac = system.phi_jac_s(qk.tolist(), uk.tolist())
        assert _same_to_rounding(scalar_phi, single[0]) and _same_to_rounding(scalar_jac, single[1])
        assert _same_to_rounding(system.velocity_rhs(qk, uk, udk), single[2])
        assert _same_to_rounding(system.acceleration_rhs(qk, vk, uk, udk, uddk), single[3])


@pytest.mark.parametrize(("stem", "parametrization"), [("slider_crank", "quaternion"), ("four_bar", "dual_euler_parameters")])
def test_in_memory_kernels_are_the_declared_ones_and_equal_the_generated_modules(stem, parametrization):
    """The in-memory path evaluates the kernel declaration: every case has exactly the outputs of the
    per-case kernels the generated module declares (KERNELS), each equal to the module's own function
    of that name to 1e-13 of its scale at random states and times (batched, as the runtime calls them);
    a solve through it equals the module's."""
    module = load_module(GENERATED / f"{stem}_{parametrization}.py")
    in_memory = lambdify_model(model(stem), rotations.get(parametrization))
    assert in_memory.STORED_NAMES == module.STORED_NAMES and in_memory.INITIAL_Q == pytest.approx(module.INITIAL_Q, abs=1e-15)
    per_case = {output for _, outputs in module.KERNELS.values() for output in outputs if not hasattr(module, output)}
    rng = np.random.default_rng(7)
    for case in module.CASES:
        mine, theirs = in_memory.CASES[case]["outputs"], module.CASES[case]["outputs"]
        assert set(mine) == per_case and set(theirs) >= per_case
        n_q, n_v, n_u = len(module.STORED_NAMES), len(module.VELOCITY_NAMES), len(module.CASES[case]["drivers"])
        q, v = rng.normal(size=(n_q, 5)), rng.normal(size=(n_v, 5))
        u, ud, udd = (rng.normal(size=(n_u, 5)) for _ in range(3))
        t0, t1 = module.CASES[case]["t0"], module.CASES[case]["t1"]
        times = np.linspace(t0, t1, 5)
        arguments = {"phi": (q, u), "jac": (q, u), "nu": (q, u, ud), "gamma": (q, v, u, ud, udd), "inputs": (times,),
                     "input_ranges": ((times[1], times[2]),)}  # fmt: skip
        assert set(arguments) == per_case
        for name, args in arguments.items():
            expected, got = np.asarray(theirs[name](*args)), np.asarray(mine[name](*args))
            assert got.shape == expected.shape, name
            assert np.abs(got - expected).max() <= 1e-13 * max(1.0, np.abs(expected).max()), (case, name)
    a, b = solve(from_module(module, compiled=False)), solve(from_module(in_memory))
    assert np.abs(a.q - b.q).max() < 1e-12
    assert np.abs(a.a - b.a).max() <= 1e-12 * max(1.0, np.abs(a.a).max())


def test_interrupted_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    """Ctrl-C while the module is being written (before the atomic replace): nothing changes."""
    target = tmp_path / "module.py"
    target.write_text("old")

    def interrupted(fd):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "fsync", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_atomic(target, "new")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["module.py"]


def test_atomic_writes_keep_the_mode_a_new_file_gets(tmp_path):
    """Not the temporary file's 0600: another user (or a CI step) must read generated modules."""
    import os

    from kinegen.files import write_atomic

    for umask in (0o022, 0o077, 0o002):
        old = os.umask(umask)
        try:
            target = tmp_path / f"module_{umask:o}.py"
            write_atomic(target, "x = 1\n")
            plain = tmp_path / f"plain_{umask:o}.py"
            plain.write_text("x = 1\n")
        finally:
            os.umask(old)
        assert target.stat().st_mode & 0o777 == plain.stat().st_mode & 0o777 == 0o666 & ~umask
