"""Shared helpers: paths, model loading, and the chain-of-revolute-links model factory."""

from __future__ import annotations

import functools
import os
from pathlib import Path

import numpy as np
import pytest

from kinegen import rotations
from kinegen.bench import chain as bench_chain
from kinegen.codegen.inmemory import lambdify_model
from kinegen.model import load, loads
from kinegen.runtime import from_module, load_module

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
GENERATED = ROOT / "generated"
#: the tests' own trust store (kinegen.integrity), shared by the test processes of a run and kept
#: between runs: a committed module is verified by regenerating it once, not in every process
os.environ["KINEGEN_TRUST"] = str(ROOT / ".pytest_cache" / "kinegen-trust")
#: the tests' kinegen cache (compiled libraries, kept builds, module code), never the user's
#: ~/.cache/kinegen: one for every test process of a run, so that the workers of `make test` share
#: each compile (kinegen.runtime.native locks an object while a process compiles it), kept between
#: runs as the trust store is. The tests that damage cached files keep a cache of their own.
os.environ["KINEGEN_CACHE"] = str(ROOT / ".pytest_cache" / "kinegen-cache")


def cache_with_solver(folder: Path) -> Path:
    """``folder`` made a kinegen cache that holds the current cache's C solver object
    (:func:`kinegen.runtime.native.copy_solver_object`), for a test that needs a cache of its own for
    something else (damaged files, what a build keeps): it does not compile the solver again (~2.5
    CPU-s). Without a C compiler, an empty folder."""
    from kinegen.errors import KinegenError
    from kinegen.runtime.native import copy_solver_object

    (folder / "objects").mkdir(parents=True, exist_ok=True)
    try:
        copy_solver_object(folder)
    except KinegenError:  # (no compiler: nothing to keep)
        pass
    return folder


#: The slider crank (models/slider_crank.yaml) at top dead centre, its stored quaternion coordinates: crank
#: and rod along x, the slider at x = r + l = 0.8 m, where Phi_q loses rank (a mechanism singularity).
SLIDER_CRANK_DEAD_CENTRE = (0, 0, 0, 1, 0, 0, 0, 0.2, 0, 0, 1, 0, 0, 0, 0.8, 0, 0, 1, 0, 0, 0.0)

#: A four-bar whose links cannot close (coupler 0.5 between points 2.3 m apart): no assembled pose.
OPEN_LOOP = """\
model: open_loop
ground:
  points: {A: [0, 0, 0], D: [3, 0, 0]}
  vectors: {z: [0, 0, 1]}
bodies:
  crank: {position: [0, 0, 0], points: {A: [0, 0, 0], B: [0.3, 0, 0]}, vectors: {z: [0, 0, 1]}}
  rocker: {position: [3, 0, 0], points: {D: [0, 0, 0], C: [0, 0.4, 0]}, vectors: {z: [0, 0, 1]}}
joints:
  A: {type: revolute, bodies: [ground, crank], points: [A, A], axes: [z, z]}
  D: {type: revolute, bodies: [ground, rocker], points: [D, D], axes: [z, z]}
  coupler: {type: distance, bodies: [crank, rocker], points: [B, C], length: 0.5}
cases:
  turn:
    drivers:
      crank: {type: joint_angle, joint: A, function: t}
"""


@functools.cache
def generated_system(stem: str, case: str | None = None, compiled: bool = False):
    """The numeric system of a committed generated module (e.g. ``boom_quaternion``): its Python
    functions, or (``compiled``) its C compiled with kinegen's C solver."""
    return from_module(load_module(GENERATED / f"{stem}.py"), case, compiled)


@functools.cache
def model(name: str):
    return load(MODELS / f"{name}.yaml")


def nominal_inertia(name: str, body) -> tuple[float, np.ndarray, np.ndarray]:
    """A body's mass [kg], centre of mass (3,) and inertia tensor (3, 3) of the model ``name`` at its
    design parameters' nominal values (the excavator's upper structure depends on its counterweight)."""
    from kinegen.model.schema import design_value

    design = {d.name: float(d.nominal) for d in model(name).design}
    inertia = body.inertia
    return (design_value(inertia.mass, design), np.array([design_value(x, design) for x in inertia.center]),
            np.array([[design_value(x, design) for x in row] for row in inertia.tensor.tolist()]))  # fmt: skip


#: tests that read :func:`excavator_working_range` run in one test process (make test distributes
#: with --dist loadgroup), so the excavator's working range and boundary (~6 s) are computed once
WORKING_RANGE_GROUP = pytest.mark.xdist_group(name="excavator_working_range")


@functools.cache
def excavator_working_range():
    """The excavator's working_range spec, its case's system (compiled, as `kinegen envelope` runs
    it: the boundary 5 s, its input effects in C), the working range and its
    exact boundary. Mark a test that uses it with :data:`WORKING_RANGE_GROUP`."""
    from kinegen.analysis.boundary import working_range_boundary
    from kinegen.analysis.envelope import working_range

    spec = model("excavator").working_range
    system = generated_system("excavator_quaternion", spec.case, compiled=True)
    return spec, system, working_range(system, spec), working_range_boundary(system, spec)


def chain_yaml(n: int) -> str:
    """The chain-N benchmark mechanism, shortened to t in [0, 2] with 41 steps."""
    return bench_chain.chain_yaml(n, t1=2.0, steps=41)


@functools.cache
def chain_system(n: int, parametrization: str):
    """In-memory (lambdify) system of the N-link chain."""
    return from_module(lambdify_model(loads(chain_yaml(n), f"chain{n}.yaml"), rotations.get(parametrization)))


@pytest.fixture
def boom_text() -> str:
    return (MODELS / "boom.yaml").read_text()


def on_a_terminal(command: list[str], env: dict | None = None, timeout: float = 300) -> tuple[int, str]:
    """Run ``command`` on a real pseudo-terminal (120 columns: stdin, stdout and stderr all on it)
    and return its exit code and everything it drew there."""
    import fcntl
    import os
    import pty
    import struct
    import subprocess
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
    process = subprocess.Popen(command, stdin=slave, stdout=slave, stderr=slave, close_fds=True, cwd=ROOT, env=env)
    os.close(slave)
    seen = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:  # the terminal closed: the command ended
            break
        if not chunk:
            break
        seen += chunk
    os.close(master)
    return process.wait(timeout=timeout), seen.decode(errors="replace")
