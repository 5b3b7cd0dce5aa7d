/* kinegen_solver.h -- the runtime of kinegen's C target.
 *
 * Position (Newton-Raphson), velocity and acceleration of a mechanism over time, for the
 * kernels a generated <model>_<param>.c provides. C99 and libm only; no heap allocation and
 * no global state: every solver instance lives in memory its caller passes (one workspace
 * struct, sized at build time by the generated header), so instances are independent and the
 * functions re-entrant.
 *
 * Conventions: SI units, angles in radians, quaternions (w, x, y, z). q holds the stored
 * coordinates, v and a the velocity coordinates and their time derivatives (for the
 * quaternion parametrization: global angular velocity and acceleration). Phi_q is square and
 * given by its values at a fixed pattern; it is factorized block by block in the
 * block-triangular order found at build time (partial pivoting within each block).
 *
 * Typical use (see example_main.c):
 *     excavator_quaternion_workspace w;
 *     kinegen_solver s;
 *     kinegen_init(&s, &excavator_quaternion_digging, NULL, w.doubles, w.ints);
 *     status = kinegen_start(&s, t0, model->initial_q, u, ud, udd);
 *     while (...) status = kinegen_step(&s, t, u, ud, udd);   -- s.q, s.v, s.a: the solution
 */
#ifndef KINEGEN_SOLVER_H
#define KINEGEN_SOLVER_H

#include <stddef.h> /* NULL: the functions below take it for "none" or "the default" */

#ifdef __cplusplus
extern "C" {
#endif

/* What a call returns. On anything but KINEGEN_OK the solver keeps its last solved state. */
enum kinegen_status {
    KINEGEN_OK = 0,
    KINEGEN_NOT_CONVERGED = 1, /* Newton did not reach the tolerance (iteration limit, divergence, NaN) */
    KINEGEN_SINGULAR = 2,      /* Phi_q is (nearly) singular: min |U_ii| <= singular_tolerance * max |U_ii| */
    KINEGEN_BRANCH = 3,        /* the step could not be certified to continue the last solution, even
                                  halved options.max_refinements times: a diagonal block of Phi_q changed
                                  the sign of its determinant (its assembly mode: a toggle or dead point lies
                                  in between), or the continuation bound failed (inputs too fast for the
                                  grid, or a singular pose near); see branch_block and bound */
    KINEGEN_NOT_STARTED = 4,   /* kinegen_step before a successful kinegen_start */
    KINEGEN_INPUTS = 5,        /* the case's time functions are not finite at a time inside the step
                                  (branch_time): a function leaves its domain between two time points */
    KINEGEN_MODEL = 6          /* kinegen_init: the model's kernel tables lack a kernel the solver calls, or
                                  declare it with other argument slots or output sizes (role names it); the
                                  solver then refuses every call with this status */
};

/* How a step is certified (kinegen_step). With x0 the last solution and x1 Newton's solution at the
 * new time, J1 = Phi_q(x1) factorized, d = x1 - x0 in velocity coordinates (the predictor's motion
 * plus Newton's steps) and norms the max-norm:
 *   omega = safety * |J1^-1 (Phi_q(x0) - J1) d| / |d|^2   (affine-covariant Lipschitz constant, measured)
 *   alpha = |J1^-1 Phi(x1)| + max over the step of |J1^-1 Phi_u (u(s) - u(t1))| (first order in u), bounded
 *           with options.case_inputs for the case's own time functions over their enclosures on the step
 *           (its input_ranges kernel: interval arithmetic), however they move between its ends; otherwise
 *           for the cubic Hermite path of the inputs' values and rates at both ends
 * The step is accepted when every diagonal block keeps the sign of its determinant, |d_i| < KINEGEN_MAX_MOTION
 * in every velocity coordinate i but the bodies' translations,
 * alpha omega <= 1/2 and omega |d| < 1: by the Newton-Kantorovich theorem every Phi(., u(s)) then has
 * exactly one zero in the ball of radius 1/omega about x1, these zeros form one continuous path, and x0
 * and x1 both lie on it. Otherwise the step is halved (inputs at the midpoint: options.case_inputs). */
/* The largest motion of a certified step in any velocity coordinate but a body's translations: a quarter
 * turn. Beyond half a turn a rotation coordinate repeats within the certificate's ball (and Phi_q with it),
 * where omega measured over the step says nothing; a translation repeats nothing, and a chain's far links
 * move metres in a step (kinegen_solver.turning). */
#define KINEGEN_MAX_MOTION 1.5707963267948966
/* ... and the least over which omega is measured: Phi_q's change over a smaller motion is rounding (a step
 * that moves less is as certain as x0 itself; below 1e-154, |d|^2 underflows) */
#define KINEGEN_MIN_MOTION 1e-12
/* The most halvings of one step (a larger options.max_refinements counts as this): 2^-52 of a step is
 * below a double's resolution of its time. */
#define KINEGEN_MAX_REFINEMENTS 52
typedef struct kinegen_options {
    double tolerance;          /* max |Phi_i| at convergence (1e-10) */
    double singular_tolerance; /* see KINEGEN_SINGULAR (1e-10) */
    double divergence_limit;   /* max |Phi| beyond which Newton stops at once (1e8) */
    double chord_rate;         /* chord iterations continue while max |Phi| falls by this factor (0.1) */
    double safety;             /* factor on the measured omega of the certificate (2) */
    int max_iterations;        /* Newton iterations per step (25) */
    int predictor;             /* 1: start each step from q moved by v h + a h^2 / 2, on a whole step after another
                                  + (a - a_prev) / h_prev h^3 / 6 (a_prev: a at the last step's start, h_prev its
                                  length; a halved piece's is of second order) (1) */
    int chord;                 /* 1: reuse the last factorization while Newton converges fast (0) */
    int polish;                /* 1: one more correction with the factors at the solution (1) */
    int keep_branch;           /* 1: certify every step (above), halving it when needed (1) */
    int condition;             /* 1: estimate the 1-norm condition number of Phi_q at every step (0) */
    int max_refinements;       /* halvings of a step before KINEGEN_BRANCH (12; at most KINEGEN_MAX_REFINEMENTS) */
    int case_inputs;           /* inputs at a midpoint: 1, the case's own time functions (its inputs kernel);
                                  0, the cubic Hermite interpolant of the values and rates given at the
                                  step's ends (0) */
} kinegen_options;

/* A kernel as data: what the C solver and a binding in another language (kinegen's Python runtime)
 * call it by. Every kernel a generated model declares is listed in its layout (shared by the cases:
 * the frames, the force solve's, and with design parameters the points and their derivatives) or in
 * its case (kinegen_model.kernels: phi_jac, nu, gamma, inputs, ...), with its argument slots and
 * outputs, and one entry point of a fixed signature: no kernel is reached through a typed pointer of
 * its own. The solver finds the ones it calls by name (their role: kinegen_roles) when it is set up. */
typedef struct kinegen_kernel {
    const char *name;
    const char *slots;                   /* argument slots, comma-separated (q, v, a, u, ud, udd, t, p, w, y, z) */
    int n_outputs;
    const char *const *output_names;
    const int *output_sizes;             /* doubles per output */
    void (*call)(const double *const *arguments, double *const *outputs); /* t: arguments[k][0] */
} kinegen_kernel;

/* Where a body's values lie in the frames kernel's output (KINEGEN_FRAME_VALUES per body, all global;
 * the rotation matrix row by row). The generated modules declare the same layout (FRAME_FIELDS);
 * kinegen's runtime compares the two (kinegen_frame_fields) before it uses a library. */
enum kinegen_frame {
    KINEGEN_FRAME_ORIGIN = 0,
    KINEGEN_FRAME_ROTATION = 3,
    KINEGEN_FRAME_VELOCITY = 12,
    KINEGEN_FRAME_ANGULAR_VELOCITY = 15,
    KINEGEN_FRAME_ACCELERATION = 18,
    KINEGEN_FRAME_ANGULAR_ACCELERATION = 21,
    KINEGEN_FRAME_VALUES = 24
};

/* A named point: on a body (body >= 0, local = body coordinates) or the ground (body = -1, global). */
typedef struct kinegen_point {
    int body;
    const char *name;
    double local[3];
} kinegen_point;

/* A reported length between two points (e.g. a hydraulic cylinder), with its allowed range. */
typedef struct kinegen_actuator {
    const char *name;
    int point1, point2; /* indices into the layout's points */
    int has_range;
    double min, max;
} kinegen_actuator;

/* A sparse matrix given by a kernel's values at a constant pattern (entry k at row rows[k],
 * column cols[k]). */
typedef struct kinegen_pattern {
    int n;
    const int *rows, *cols;
} kinegen_pattern;

/* The force solve of a model that declares loads or actuation elements (kinegen_layout.statics; NULL:
 * neither): at a solved configuration, Phi_q^T lambda = Q (kinegen_forces). By virtual work the
 * constraint forces -Phi_q^T lambda hold the loads' generalized force Q.
 *   With actuation elements (n_elements > 0: the motors, then the actuators with hydraulic data), the
 *   matrix is the joint rows of Phi_q (the first n_joint_rows rows; their values are the first of every
 *   case's Phi_q) and one row per element, d(its length or joint angle)/dv: the kernel `actuation` gives
 *   the matrix's values at `pattern`, factorized in the block lower triangular plan below (as a case's,
 *   kinegen_model). An element's force is f = -lambda of its row: an actuator's push [N] (positive
 *   pushes its points apart), a motor's torque [N m] about its joint's axis on the joint's second body.
 *   Without elements, each case's drivers carry the load: the matrix is the case's Phi_q, and a driver's
 *   force along its input is f = lambda dPhi/du (from nu at a unit input rate).
 * The kernel `loads` gives every load's Q at load_pattern (rows: the load's index in load_names); a model
 * with masses has the kernel `inertia` (q, v, a[, p]): the generalized force of gravity and of the bodies'
 * inertia (d'Alembert: m (g - a_C) at each centre of mass, -(J w' + w x J w) on each body) at inertia_cols,
 * which kinegen_forces adds for inverse dynamics. */
typedef struct kinegen_statics {
    int n_elements;
    const char *const *element_names;
    const char *const *element_kinds; /* "actuator" or "motor" */
    int n_joint_rows;
    kinegen_pattern pattern;          /* of the matrix (n_elements > 0): the kernel actuation's values */
    int n_loads;
    const char *const *load_names;
    kinegen_pattern load_pattern;     /* of the kernel loads' values */
    int n_inertia;                    /* the kernel inertia's values (0: the model has no masses) */
    const int *inertia_cols;
    int n_blocks;                     /* the matrix's plan (n_elements > 0), as kinegen_model's */
    const int *block_start, *block_store, *row_order, *col_order;
    int n_store, n_diag;
    const int *diag_value, *diag_slot;
    int n_off;
    const int *off_start, *off_col, *off_value;
    int work_doubles, work_ints;      /* what kinegen_forces needs as work, for any case */
    /* Pin reactions (kinegen_reactions): per joint, the body whose wrench its rows' multipliers give
     * (joint_body: its second body, or its first with joint_sign -1 when the second is the ground), the
     * body of the joint's point (joint_point_body; -1: the ground) and the point's coordinates in it
     * (joint_local, 3 per joint; at the nominal design, as the layout's points), and its rows among the
     * joint rows (joint_rows[joint_row_start[j] .. joint_row_start[j+1]-1]); per body its normalization
     * rows (body_norm_rows[body_norm_start[b] ..]), which with the body's 6 tangent rows make its square
     * map from wrenches to generalized forces. */
    int n_joints;
    const char *const *joint_names;
    const int *joint_body, *joint_sign, *joint_point_body;
    const double *joint_local;
    const int *joint_row_start, *joint_rows;
    const int *body_norm_start, *body_norm_rows;
    /* Per element (7 values): cap and rod side areas [m^2], relief (extend, retract) and holding
     * (extend, retract) settings [Pa] at the nominal design, and its actuator's index in the layout
     * (a motor: NaN and -1): the pressure on the side that carries the force, and its limit. */
    const double *element_hydraulics;
    int reaction_doubles, reaction_ints; /* what kinegen_reactions needs as work */
} kinegen_statics;

/* What a model is, whatever the case: names, bodies, points, actuators, and the frames kernel
 * (per body 24 values: origin, rotation matrix row by row, origin velocity, angular velocity,
 * origin acceleration, angular acceleration; all global); with loads or actuation elements, its
 * force solve (statics). */
typedef struct kinegen_layout {
    const char *model, *parametrization, *source, *source_sha256, *kinegen_version;
    int n_q, n_v, n_bodies;
    const char *const *body_names;
    const char *const *stored_names;
    const char *const *velocity_names;
    int n_points;
    const kinegen_point *points;
    int n_actuators;
    const kinegen_actuator *actuators;
    int n_kernels;                 /* every kernel shared by the cases (frames first) */
    const kinegen_kernel *kernels;
    const kinegen_statics *statics; /* NULL: the model declares no loads and no actuation elements */
} kinegen_layout;

/* The design parameters of a case of a model with a design: section (kinegen_model.design; the
 * case's kernels then take the parameters p last, slot p): their n_design nominal values
 * (kinegen_set_design; by default the nominal values).
 *
 * Then the patterns of the exact sensitivities' kernels (kinegen_sensitivities; roles phi_p, dvel and
 * dacc, absent from a model built without them), each a sparse matrix (n_v rows; n_v velocity
 * coordinates, n_p = n_design parameters):
 *   phi_p: Phi_p = dPhi/dp (n_p columns);
 *   dvel:  [M_v | E_v], M_v = D_q(Phi_q v - nu), E_v = d(Phi_q v - nu)/dp (n_v + n_p columns);
 *   dacc:  [M_a | N_a | E_a], M_a = D_q(Phi_q a - gamma), N_a = d(Phi_q a - gamma)/dv,
 *          E_a = d(Phi_q a - gamma)/dp (2 n_v + n_p columns);
 * D_q: derivatives along the velocity coordinates' tangent directions, as for Phi_q. */
typedef struct kinegen_design {
    int n_design;
    const double *nominal;
    kinegen_pattern phi_p_pattern, dvel_pattern, dacc_pattern;
    int sensitivity_doubles; /* what kinegen_sensitivities needs as work: 2 n_v n_p + the largest kernel output */
} kinegen_design;

/* One case of a model: its kernels (as data, in kernels) and the factorization plan of its Phi_q. The
 * solver calls the case's kernels by these roles (slots; with design parameters each takes p last):
 *   phi_jac (q, u) -> Phi (n_v), Phi_q's values (n_jac);  nu (q, u, ud) -> nu (n_v);
 *   gamma (q, v, u, ud, udd) -> gamma (n_v);  inputs (t) -> u, du/dt, d2u/dt2 (3 n_inputs: the case's
 *   own time functions);  input_ranges (span) -> their enclosures over the time interval span = (t0, t1):
 *   the lower bounds of u, du/dt, d2u/dt2, then the upper bounds (6 n_inputs; interval arithmetic,
 *   kinegen_interval.h);  with design parameters phi_p, dvel, dacc (kinegen_design);
 * and the layout's: frames (q, v, a) -> KINEGEN_FRAME_VALUES per body; with a force solve (kinegen_statics)
 *   actuation (q) -> the force matrix's values, loads (q, t) -> the loads' Q values, inertia (q, v, a) ->
 *   gravity's and inertia's Q values. */
typedef struct kinegen_model {
    const kinegen_layout *layout;
    const char *case_name;
    int n_q, n_v, n_inputs, n_jac; /* n_v constraints, n_jac values of Phi_q */
    double t0, t1;
    int steps;
    const double *initial_q;
    const char *const *constraint_names; /* the joints' rows, the normalizations', then the drivers': */
    const char *const *driver_names;     /*   driver k's is row n_v - n_inputs + k and depends on input k alone */
    const int *jac_rows, *jac_cols;
    void (*retract)(double *q, const double *step);              /* q moved by a velocity-coordinate step */
    /* Phi_q permuted to block lower triangular form: position i holds constraint row_order[i]
     * and coordinate col_order[i]; block k spans positions block_start[k] .. block_start[k+1]-1
     * and keeps its LU factors at block_store[k] (column-major). */
    int n_blocks;
    const int *block_start, *block_store;
    const int *row_order, *col_order;
    int n_store;
    int n_diag;                    /* Phi_q values inside diagonal blocks: */
    const int *diag_value, *diag_slot; /*   value diag_value[k] goes to store[diag_slot[k]] */
    int n_off;                     /* values below the block diagonal, by permuted row (CSR): */
    const int *off_start, *off_col, *off_value;
    /* x = Phi_q^-1 b from the factors (store, off, perms as kinegen_init carves them; y: n_v values of
     * work; x and b may alias): the plan's block solve written out for this case, straight-line (no
     * loop over the blocks or their entries); NULL: the solver's loop over the plan (same operations) */
    void (*solve)(const double *store, const double *off, const int *perms, const double *b, double *x, double *y);
    /* x = Phi_q^-T c likewise (w: n_v values of work; x and c may alias), NULL with solve */
    void (*solve_transposed)(const double *store, const double *off, const int *perms, const double *c, double *x, double *w);
    /* x = Phi_q^-1 b like solve, for a b that is zero in the permuted rows before those of the written solve's
     * function `first` (their part skipped), and per input k the function where its column of Phi_q^-1 Phi_u
     * starts (input_pieces[k]: its driver's row is in it); both NULL with solve, or in C generated before them */
    void (*solve_from)(const double *store, const double *off, const int *perms, const double *b, double *x, double *y, int first);
    const int *input_pieces;
    int work_doubles, work_ints;   /* what kinegen_init needs for this case */
    int n_kernels;                 /* every kernel of the case, as data (with design parameters: */
    const kinegen_kernel *kernels; /*   the ones taking p, slot p last) */
    const kinegen_design *design;  /* a model with design parameters: theirs and the kernels taking them; else NULL */
} kinegen_model;



/* The kernels a solver calls, found by role (kinegen_model) in the case's and the layout's tables by
 * kinegen_init, their slots and output sizes checked there; NULL: the model has none of that role. */
typedef struct kinegen_roles {
    const kinegen_kernel *phi_jac, *nu, *gamma, *inputs, *input_ranges; /* the case's */
    const kinegen_kernel *phi_p, *dvel, *dacc;                          /* its sensitivities' */
    const kinegen_kernel *frames, *actuation, *loads, *inertia;         /* the layout's */
} kinegen_roles;

/* One solver instance. After a call returning KINEGEN_OK: q, v, a at time t, and the step's
 * Newton iterations, final max |Phi| and condition estimate. All arrays point into the
 * caller's memory (kinegen_init). */
typedef struct kinegen_solver {
    const kinegen_model *model;
    kinegen_options options;
    double t;
    double *q, *v, *a;
    int started, iterations;
    double residual, condition;
    int sign;         /* sign of det(Phi_q) at the solution, up to the plan's fixed permutations */
    int have_factors; /* store holds factors (of the last solution, or of a Newton iterate) */
    int factor_sign;  /* sign of det(Phi_q) of the factors in store */
    /* workspace */
    double *trial, *phi, *jac, *store, *off, *rhs, *step, *y, *x;
    int *pivots; /* the blocks' LU interchanges (LAPACK's: row k swapped with row pivots[k] of its block, in turn),
                    and the condition estimate's sign vector after them */
    int *perms;  /* the same interchanges composed, the written-out solves' (kinegen_model.solve): position k of a
                    block starting at position f takes row f + perms[k] (n_v ints; filled where the case has them) */
    const double *design; /* the design parameters the kernels take, or NULL (a model without them) */
    /* the certificate (see kinegen_options) */
    double *u, *ud;         /* the inputs and their rates at t */
    double *jac_q;          /* Phi_q values at q, those the factors in store are of after a step (jac: the
                               Newton iterates', the array it exchanges with at every accepted step) */
    double *moved, *w1, *w2; /* the step's motion d (the predictor's, then Newton's steps added); work */
    int *block_sign;        /* sign of det of every diagonal block of Phi_q at q (the assembly modes) */
    int *factor_block_sign; /* ... of the factors in store */
    int refinements;        /* halvings the last kinegen_step took (0: the whole step was certified) */
    int branch_block;       /* after KINEGEN_BRANCH: the block whose determinant changed sign, or -1 (the bound failed) */
    double bound;           /* alpha omega of the last certified (or refused) step (infinite: it moved too far); a
                               certified one's may hold the inputs' coarse bound (input_effect, kinegen_solver.c) */
    double branch_time;     /* after KINEGEN_BRANCH: the start of the shortest step tried */
    double *cert;           /* the certificate's work: 10 n_v + 7 n_inputs doubles */
    int branch_input;       /* after KINEGEN_BRANCH: the input that contributed most to the refused bound, or -1 */
    int *moving;            /* the certificate's work: the inputs that move over the step (n_inputs ints) */
    int *turning, n_turning; /* the velocity coordinates KINEGEN_MAX_MOTION caps (at most n_v ints): all but the
                                bodies' translations, the ones the layout names <body>.x, .y, .z, or .vx, .vy,
                                .vz (a dual quaternion's twist) -- kinegen.rotations' names, read by kinegen_init */
    double *path;           /* kinegen_step's work: the step's start inputs and a halved piece's (5 n_inputs) */
    double *bound_store, *bound_off; /* the certificate's coarse bound: the comparison matrices of the factors in
                                        store and off (n_store, n_off doubles), made when first needed */
    int have_bound;                  /* bound_store and bound_off are those of the factors in store */
    double *a_start, *a_prev; /* a at the start of the step kinegen_step takes, and of the last one it took (n_v each) */
    double h_prev;            /* the length of that last step; has_prev: a_prev and h_prev hold one (the predictor's
                                 third-order term on a whole step: see kinegen_options.predictor) */
    int has_prev;
    kinegen_roles roles;    /* the kernels it calls */
    const char *role;       /* after KINEGEN_MODEL from kinegen_init: the role it could not bind (else NULL) */
} kinegen_solver;

/* The memory each call below carves from what its caller passes -- the one statement of these sizes:
 * the generated models state theirs with them (kinegen_model.work_doubles and .work_ints,
 * kinegen_statics' work and reaction sizes, kinegen_design.sensitivity_doubles, and the generated
 * header's *_WORK_* macros for static memory). All are integer constant expressions. */
#define KINEGEN_MAX(a, b) ((a) > (b) ? (a) : (b))
/* kinegen_init, one case: n_q stored and n_v velocity coordinates, n_jac values of Phi_q, n_store values of
 * its blocks' factors and n_off below them, n_blocks diagonal blocks, n_inputs drivers */
#define KINEGEN_WORK_DOUBLES(n_q, n_v, n_jac, n_store, n_off, n_inputs) \
    (2 * (n_q) + 22 * (n_v) + 2 * (n_jac) + 2 * (n_store) + 2 * (n_off) + 14 * (n_inputs))
#define KINEGEN_WORK_INTS(n_v, n_blocks, n_inputs) (4 * (n_v) + 2 * (n_blocks) + (n_inputs))
/* kinegen_sensitivities: n_p design parameters, n_values the largest sensitivity kernel's output */
#define KINEGEN_SENSITIVITY_DOUBLES(n_v, n_p, n_values) (2 * (n_v) * (n_p) + (n_values))
/* kinegen_forces, any case: n_inertia and n_load_values the inertia and loads kernels' outputs, n_inputs
 * the most drivers of a case; with elements the force matrix's n_matrix values, n_store of its factors,
 * n_off below them (0 without) */
#define KINEGEN_FORCE_WORK_DOUBLES(n_inertia, n_load_values, n_v, n_inputs, n_matrix, n_store, n_off) \
    ((n_inertia) + KINEGEN_MAX(1, n_load_values) + 2 * (n_v) +                                       \
     KINEGEN_MAX((n_v) + KINEGEN_MAX(1, n_inputs), (n_matrix) + (n_store) + (n_off)))
#define KINEGEN_FORCE_WORK_INTS(n_v) (n_v)
/* kinegen_reactions: n_bodies bodies of n_v / n_bodies velocity coordinates each, n_matrix as above, n_jac
 * the most values of a case's Phi_q, n_joint_rows the joints' rows */
#define KINEGEN_BODY_COORDINATES(n_v, n_bodies) ((n_v) / KINEGEN_MAX(1, n_bodies))
#define KINEGEN_REACTION_WORK_DOUBLES(n_bodies, n_v, n_matrix, n_jac)                                          \
    (KINEGEN_FRAME_VALUES * (n_bodies) + 8 * (n_v) + 2 * KINEGEN_BODY_COORDINATES(n_v, n_bodies) +             \
     KINEGEN_BODY_COORDINATES(n_v, n_bodies) * KINEGEN_BODY_COORDINATES(n_v, n_bodies) + KINEGEN_MAX(n_matrix, (n_v) + (n_jac)))
#define KINEGEN_REACTION_WORK_INTS(n_joint_rows) KINEGEN_MAX(1, n_joint_rows)

void kinegen_default_options(kinegen_options *options);

/* Set up a solver for one case in caller-provided memory: at least model->work_doubles
 * doubles and model->work_ints ints (KINEGEN_WORK_DOUBLES and KINEGEN_WORK_INTS of its sizes;
 * the generated header's *_WORK_DOUBLES / *_WORK_INTS cover every case of the model). options NULL: kinegen_default_options.
 * Finds the kernels it calls by role (kinegen_roles) and checks their slots and sizes: KINEGEN_OK, or
 * KINEGEN_MODEL naming the role in s->role (the solver then refuses every call). */
int kinegen_init(kinegen_solver *s, const kinegen_model *model, const kinegen_options *options, double *doubles, int *ints);

/* The kernel of that name in the case's table, else in its layout's; NULL: none. */
const kinegen_kernel *kinegen_find_kernel(const kinegen_model *model, const char *name);

/* The most argument slots and outputs kinegen_kernel_each runs a kernel with. */
#define KINEGEN_MAX_SLOTS 16
#define KINEGEN_MAX_OUTPUTS 16

/* Runs `kernel` at `count` configurations, one call each, without a solver: its argument slot j (in the order of
 * kernel->slots) of configuration i at arguments[j] + i * strides[j] (stride 0: the same values at every one),
 * its output o of configuration i at outputs[o] + i * kernel->output_sizes[o]. What kinegen's runtime evaluates a
 * kernel over many configurations by (a batch of poses, a trajectory's points) in one call. Returns KINEGEN_OK,
 * or KINEGEN_MODEL (nothing run) for a kernel of more than KINEGEN_MAX_SLOTS slots or KINEGEN_MAX_OUTPUTS outputs. */
int kinegen_kernel_each(const kinegen_kernel *kernel, int count, const double *const *arguments, const int *strides,
                        double *const *outputs);

/* The case's own time functions at t (its inputs kernel): u, du/dt, d2u/dt2 of every driver into out
 * (3 n_inputs). Returns KINEGEN_OK, or KINEGEN_MODEL for a case without them. */
int kinegen_case_inputs(const kinegen_model *model, double t, double *out);

/* The design parameters (model->design->n_design values, kept by the caller)
 * the solver's kernels take from now on; NULL: the nominal values. Without design parameters
 * nothing to set. */
void kinegen_set_design(kinegen_solver *s, const double *p);

/* Assemble the pose at time t from q0 (Newton without predictor), then velocity and acceleration. */
int kinegen_start(kinegen_solver *s, double t, const double *q0, const double *u, const double *ud, const double *udd);

/* Advance to time t with driver inputs u (and their rates ud, udd): predictor, Newton or chord
 * iterations, the step's certificate (see kinegen_options), polishing, velocity, acceleration. A step
 * that cannot be certified is halved, up to options.max_refinements times (refinements says how
 * often); the state then moves only to t. */
int kinegen_step(kinegen_solver *s, double t, const double *u, const double *ud, const double *udd);

/* How far rows of tabulated inputs (u, du/dt, d2u/dt2 of n inputs at two times h apart) disagree with
 * the cubic Hermite path a halved step follows between them (their values and rates at both ends):
 * h^2 |that path's d2u/dt2 - the rows' d2u/dt2| at either end, relative to the input's own change over
 * the step (|du| + h |du/dt| + h^2 |d2u/dt2|, the rows' means). About 0.2 for a sine with 4 rows a period,
 * 1.6 with 2 (its Nyquist rate); above KINEGEN_TABLE_MISMATCH the rows are sampled below their own
 * variation and the path between them is not theirs. Returns the largest ratio, *input the input. */
#define KINEGEN_TABLE_MISMATCH 0.5
double kinegen_table_mismatch(int n, double h, const double *u0, const double *ud0, const double *udd0, const double *u1,
                              const double *ud1, const double *udd1, int *input);

/* Take (t, q, v, a) solved elsewhere as the current state (u, ud: the inputs and their rates at t); a_prev: the
 * acceleration at the start of the step that ended there, h_prev its length (NULL: none, the next step's
 * predictor is of second order). */
int kinegen_resume(kinegen_solver *s, double t, const double *q, const double *v, const double *a, const double *u,
                   const double *ud, const double *a_prev, double h_prev);

/* Steps at times[0..count-1] (after a start or a resume) with inputs rows U, UD, UDD
 * (count x n_inputs, row-major); rows of Q (count x n_q), V, A (count x n_v) and the per-step
 * iterations, residuals and conditions are written. Returns the number of steps solved; when
 * less than count, *status says why the next one failed. */
int kinegen_trajectory(kinegen_solver *s, int count, const double *times, const double *U, const double *UD,
                       const double *UDD, double *Q, double *V, double *A, int *iterations, double *residuals,
                       double *conditions, int *status);

/* Newton (no predictor; with options.chord, chord iterations that start each configuration from
 * the factors of the one before) on many configurations: row k of U
 * (count x n_inputs, row-major) from row k of Q (count x n_q), solved in place; converged[k],
 * iterations[k], residuals[k] per configuration. Returns how many converged. Leaves the
 * solver's state as it was, but not its factors. */
int kinegen_solve_batch(kinegen_solver *s, int count, const double *U, double *Q, int *converged, int *iterations,
                        double *residuals);

/* Full Newton from q (in place) for inputs u: its iterations, final max |Phi| and the summed
 * max-norm of its steps. The solver's state stays as it was (not its factors). */
int kinegen_newton(kinegen_solver *s, double *q, const double *u, int *iterations, double *residual, double *travel);

/* The change of the configuration per unit change of each input, Phi staying 0, at many solved
 * configurations: dq/du = Phi_q^-1 nu(q, u, e_j) in column j (velocity coordinates), row k of Q
 * (count x n_q) with row k of U (count x n_inputs) into block k of DQDU (count blocks of n_v x
 * n_inputs, row-major). A configuration whose Phi_q is singular gets NaN. Returns how many were
 * regular. The solver's state stays as it was (not its factors). */
int kinegen_input_effects(kinegen_solver *s, int count, const double *Q, const double *U, double *DQDU);

/* Exact sensitivities by the design parameters along a solved trajectory (a model with design
 * parameters; the solver's design values): at each of count time points, rows of Q (count x n_q),
 * V, A (count x n_v) and of the inputs U, UD, UDD (count x n_inputs), row-major, it factors Phi_q
 * once and writes S = dq/dp = -Phi_q^-1 Phi_p, DV = dv/dp = -Phi_q^-1 (M_v S + E_v) and
 * DA = da/dp = -Phi_q^-1 (M_a S + N_a DV + E_a), each count x n_v x n_design (row-major; q's
 * change in velocity coordinates). work: the design model's sensitivity_doubles. A time point
 * whose Phi_q is singular gets NaN. Returns the number of time points done (count), or -1 for a
 * model without design parameters or built without sensitivity kernels. The solver's state stays as it was (not its factors). */
int kinegen_sensitivities(kinegen_solver *s, int count, const double *Q, const double *V, const double *A, const double *U,
                          const double *UD, const double *UDD, double *S, double *DV, double *DA, double *work);

/* The forces that hold the model's loads (kinegen_statics) at count solved configurations of the
 * solver's case: rows of Q (count x n_q) at times[k] with the case's inputs U (count x n_inputs), each
 * load weighted by weights[load] (n_loads values; NULL: each once); with inertia = 1 (a model with masses)
 * also the bodies' weight and inertia at the velocities and accelerations V, A (count x n_v; NULL with
 * inertia = 0): inverse dynamics. Writes the multipliers LAMBDA
 * (count x n_v: the joint rows', then the elements' or the case drivers') and the forces F (count x
 * n_elements, or the case's n_inputs without elements), row-major. A configuration whose matrix is
 * singular (min |U_ii| <= options.singular_tolerance * max |U_ii|) gets NaN. work, iwork: the statics'
 * work_doubles and work_ints. Returns the number of configurations solved (the others NaN), or -1 for
 * a model without loads, actuation elements and masses (or inertia asked of one without masses). The solver's state stays as it was; without elements
 * (the case's Phi_q factorized) not its factors, so that a following step factorizes again. */
int kinegen_forces(kinegen_solver *s, int count, const double *times, const double *Q, const double *V, const double *A,
                   const double *U, const double *weights, double inertia, double *LAMBDA, double *F, double *work, int *iwork);

/* The pin reactions at one solved configuration q (inputs u) from the multipliers lambda of
 * kinegen_forces: per joint 6 values in out, what its first body exerts on its second -- the force
 * [N] and its moment [N m] about the joint's point (kinegen_statics.joint_local), global axes. The
 * joint's rows carry the generalized force -Phi_q[rows]^T lambda[rows] on the body; its wrench w solves
 * [T_v; T_w; N]^T w = that force restricted to the body's coordinates (T_v, T_w: the body's tangent
 * maps, from the frames kernel at unit velocities; N: its normalization rows). work, iwork: the
 * statics' reaction_doubles and reaction_ints. Returns the number of joints, or -1 for a model without
 * a force solve (or whose bodies have more than 8 velocity coordinates each, which no parametrization
 * has); a joint whose square map is singular gets NaN. The solver's state stays as it was. */
int kinegen_reactions(kinegen_solver *s, const double *q, const double *u, const double *lambda, double *out, double *work, int *iwork);

const char *kinegen_status_text(int status);

/* The runtime's self-description, for bindings in other languages (kinegen's Python runtime lays
 * out its structs from it, never from a copy): every field of the structs above with its offset,
 * size and type ("double", "int", "double*", "int*", "char*", "pointer", "function", or a struct's
 * name), each struct's size, and the names of the status codes, by code. Each list ends with an
 * entry whose first member is NULL. */
typedef struct kinegen_field {
    const char *structure, *name, *type;
    int offset, size;
} kinegen_field;
typedef struct kinegen_struct {
    const char *name;
    int size;
} kinegen_struct;
extern const kinegen_field kinegen_fields[];
extern const kinegen_struct kinegen_structs[];
extern const char *const kinegen_status_names[];
typedef struct kinegen_frame_field {
    const char *name; /* origin, rotation, velocity, angular_velocity, acceleration, angular_acceleration */
    int offset, count;
} kinegen_frame_field;
extern const kinegen_frame_field kinegen_frame_fields[];
/* Every function declared here: its name, its result type and its parameter list as declared (a
 * binding's argument types; kinegen's runtime sets its ctypes signatures from it). */
typedef struct kinegen_function {
    const char *name, *result, *parameters;
} kinegen_function;
extern const kinegen_function kinegen_functions[];

/* Reporting helpers: unit quaternion (w >= 0) of a rotation matrix (row by row; Shepperd's
 * method), and position, velocity, acceleration of a body point from a body's 24 frame values. */
void kinegen_quaternion_from_matrix(const double *matrix, double *quaternion);
void kinegen_point_kinematics(const double *frame, const double *local, double *position, double *velocity,
                              double *acceleration);

#ifdef __cplusplus
}
#endif
#endif
