"""The declared interface between generated code and the runtimes: written here once, printed
into every generated module (Python and C) by the backends, and read back from a module (or a
compiled library's own tables) by the runtime -- never copied by hand.

* :data:`SLOTS`: the arguments a kernel may take, by name.
* :data:`FRAME_FIELDS`: what the ``frames`` kernel gives per body, in order.
* :data:`SENSITIVITY_KERNELS`: the kernels of a model with design parameters that carry its
  exact sensitivities (each a sparse matrix given by its values at a constant pattern);
  :data:`SENSITIVITY_ONLY`: those and the other kernels only sensitivities need.
* :func:`row_owner`: whose a constraint row is, from its name (the modules' constraint names).

Which kernels a module has, their argument slots and their outputs' names and sizes are in the
module itself (``KERNELS`` and each case's ``"kernels"`` in Python; the ``kinegen_kernel`` tables
in C): the kernel description (:mod:`kinegen.codegen.kernels`) declares them, and adding one is
declaring it there with its symbolic content.

Units SI, angles in radians, quaternions (w, x, y, z). No SymPy here: the runtime imports it.
"""

from __future__ import annotations

#: What each argument slot holds.
SLOTS = {
    "t": "time [s]",
    "q": "stored coordinates",
    "v": "velocity coordinates",
    "a": "accelerations (time derivatives of the velocity coordinates)",
    "u": "driver inputs (angles, lengths, coordinates)",
    "ud": "their first time derivatives",
    "udd": "their second time derivatives",
    "p": "design parameters (only in a model with a design: section; units as in the model)",
    "w": "a change of the configuration, in velocity coordinates (sensitivity kernels)",
    "y": "a change of the velocity coordinates (sensitivity kernels)",
    "z": "a change of the accelerations (sensitivity kernels)",
    "f": "the actuation elements' forces [N or N m], in the order of the statics' elements (the supply kernel)",
}

#: The ``frames`` kernel's values per body, in order: (name, count). All global; the rotation
#: matrix row by row (body to global); angular velocity and acceleration as vectors [rad/s, rad/s^2].
FRAME_FIELDS = (
    ("origin", 3),
    ("rotation", 9),
    ("velocity", 3),
    ("angular_velocity", 3),
    ("acceleration", 3),
    ("angular_acceleration", 3),
)
#: Values per body in the ``frames`` kernel.
FRAME_VALUES = sum(count for _, count in FRAME_FIELDS)


def frame_slices(fields: tuple[tuple[str, int], ...] = FRAME_FIELDS) -> dict[str, slice]:
    """Where each of a body's frame values lies among its ``FRAME_VALUES`` (name -> slice);
    ``fields``: a module's own declaration (its ``FRAME_FIELDS``)."""
    out, start = {}, 0
    for name, count in fields:
        out[name] = slice(start, start + count)
        start += count
    return out


#: The sensitivity kernels, per case, and what their output holds (n_v velocity coordinates, n_p
#: design parameters). Each is a sparse matrix given by its values at a constant pattern (a case's
#: ``<kernel>_rows``, ``<kernel>_cols``).
SENSITIVITY_KERNELS = {
    "phi_p": "Phi_p = dPhi/dp (n_p columns)",
    "dvel": "[M_v | E_v], M_v = D_q(Phi_q v - nu) (n_v columns), E_v = d(Phi_q v - nu)/dp (n_p columns)",
    "dacc": "[M_a | N_a | E_a], M_a = D_q(Phi_q a - gamma), N_a = d(Phi_q a - gamma)/dv (n_v columns each), "
    "E_a = d(Phi_q a - gamma)/dp (n_p columns)",
}

#: The kernels only sensitivities need: the per-case :data:`SENSITIVITY_KERNELS`, and the model's
#: ``frames_d`` (the frames moved along a state's sensitivities) and ``points_p`` (the points'
#: derivatives by the design parameters). A large model's C holds them apart, compiled when first
#: asked for (kinegen.runtime.native).
SENSITIVITY_ONLY = (*SENSITIVITY_KERNELS, "frames_d", "points_p")


def normalization_row(body: str, k: int) -> str:
    """The name of ``body``'s k-th normalization row (a parametrization with more stored than velocity
    coordinates): ``upper.norm``, ``upper.norm1``, ... A joint's rows are ``<joint>.<component>``."""
    return f"{body}.norm{'' if k == 0 else k}"


def row_owner(name: str) -> tuple[str, bool]:
    """The joint a joint row belongs to (``boom_foot.x`` -> ``boom_foot``), or the body of a
    normalization row (:func:`normalization_row`), and whether it is one."""
    owner, _, rest = name.partition(".")
    return owner, rest.startswith("norm")
