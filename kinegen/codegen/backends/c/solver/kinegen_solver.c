/* kinegen_solver.c -- the runtime of kinegen's C target (see kinegen_solver.h).
 *
 * The same step as kinegen.runtime.solver.Solver's usual step, in C: predictor from the last
 * step's velocity and acceleration, Newton or chord iterations until max |Phi| <= tolerance,
 * the factors of Phi_q at the solution (branch check on the sign of det Phi_q and on the
 * length of Newton's correction), one polishing correction, then velocity and acceleration
 * with those factors. What Python adds around it (line search, homotopy, least squares,
 * step halving near a toggle) it does not do: it returns a status and keeps its state.
 *
 * Phi_q: the values of its pattern, scattered into the dense diagonal blocks of its block
 * lower triangular form (found at build time); the entries below the blocks are kept beside
 * the blocks' factors, so that a chord step solves with the Jacobian it factorized.
 * Each block is LU-factorized with partial pivoting; a solve is a forward substitution over
 * the blocks. The 1-norm condition estimate is Hager's method (as LAPACK's xLACN2) with solves
 * by Phi_q and its transpose.
 */
#include "kinegen_solver.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

void kinegen_default_options(kinegen_options *o) {
    o->tolerance = 1e-10;
    o->singular_tolerance = 1e-10;
    o->divergence_limit = 1e8;
    o->chord_rate = 0.1;
    o->safety = 2.0;
    o->max_iterations = 25;
    o->predictor = 1;
    o->chord = 0;
    o->polish = 1;
    o->keep_branch = 1;
    o->condition = 0; /* asked for where its value is used (the example program's column) */
    o->max_refinements = 12;
    o->case_inputs = 0;
}

void kinegen_set_design(kinegen_solver *s, const double *p) {
    const kinegen_design *d = s->model->design;
    if (d != NULL) s->design = p != NULL ? p : d->nominal;
}

/* The case's kernels by role, with the design parameters last when the model has them (s->design; a kernel
 * without slot p does not read it). */
static void phi_jac(const kinegen_solver *s, const double *q, const double *u, double *phi, double *jac) {
    const double *x[3] = {q, u, s->design};
    double *y[2] = {phi, jac};
    s->roles.phi_jac->call(x, y);
}

static void nu(const kinegen_solver *s, const double *q, const double *u, const double *ud, double *out) {
    const double *x[4] = {q, u, ud, s->design};
    double *y[1] = {out};
    s->roles.nu->call(x, y);
}

static void gamma_rhs(const kinegen_solver *s, const double *q, const double *v, const double *u, const double *ud,
                      const double *udd, double *out) {
    const double *x[6] = {q, v, u, ud, udd, s->design};
    double *y[1] = {out};
    s->roles.gamma->call(x, y);
}

const kinegen_kernel *kinegen_find_kernel(const kinegen_model *m, const char *name) {
    for (int k = 0; k < m->n_kernels; ++k)
        if (strcmp(m->kernels[k].name, name) == 0) return &m->kernels[k];
    for (int k = 0; k < m->layout->n_kernels; ++k)
        if (strcmp(m->layout->kernels[k].name, name) == 0) return &m->layout->kernels[k];
    return NULL;
}

int kinegen_kernel_each(const kinegen_kernel *kernel, int count, const double *const *arguments, const int *strides,
                        double *const *outputs) {
    int n_slots = kernel->slots[0] != '\0';
    for (const char *c = kernel->slots; *c != '\0'; ++c) n_slots += *c == ',';
    if (n_slots > KINEGEN_MAX_SLOTS || kernel->n_outputs > KINEGEN_MAX_OUTPUTS) return KINEGEN_MODEL;
    const double *x[KINEGEN_MAX_SLOTS];
    double *y[KINEGEN_MAX_OUTPUTS];
    for (int i = 0; i < count; ++i) {
        for (int j = 0; j < n_slots; ++j) x[j] = arguments[j] + (size_t)i * (size_t)strides[j];
        for (int o = 0; o < kernel->n_outputs; ++o) y[o] = outputs[o] + (size_t)i * (size_t)kernel->output_sizes[o];
        kernel->call(x, y);
    }
    return KINEGEN_OK;
}

int kinegen_case_inputs(const kinegen_model *m, double t, double *out) {
    const kinegen_kernel *k = kinegen_find_kernel(m, "inputs");
    if (k == NULL) return KINEGEN_MODEL;
    const double *x[1] = {&t};
    double *y[1] = {out};
    k->call(x, y);
    return KINEGEN_OK;
}

/* The kernel of role `name` into *found, if its slots are `slots` (with ",p" after them when `design`) and
 * its outputs have the sizes given (n_outputs of them); a missing one is NULL. 0, or 1 (s->role = name) when
 * it is declared otherwise, or missing though `required`. */
static int bind(kinegen_solver *s, const kinegen_kernel **found, const char *name, const char *slots, int design, int required,
                int n_outputs, int size0, int size1) {
    const kinegen_kernel *k = kinegen_find_kernel(s->model, name);
    size_t n = strlen(slots);
    int sizes[2] = {size0, size1};
    *found = NULL;
    if (k == NULL) {
        if (required) s->role = name;
        return required;
    }
    int same = k->slots != NULL && strncmp(k->slots, slots, n) == 0 && strcmp(k->slots + n, design ? ",p" : "") == 0 &&
               k->n_outputs == n_outputs && k->call != NULL;
    for (int i = 0; i < n_outputs && same; ++i) same = k->output_sizes[i] == sizes[i];
    if (!same) {
        s->role = name;
        return 1;
    }
    *found = k;
    return 0;
}

/* Every role the solver calls (kinegen_roles) bound from the model's tables; 0, or 1 naming the first
 * that is missing or declared otherwise in s->role. */
static int bind_roles(kinegen_solver *s) {
    const kinegen_model *m = s->model;
    const kinegen_design *d = m->design;
    const kinegen_statics *st = m->layout->statics;
    kinegen_roles *r = &s->roles;
    int p = d != NULL, nv = m->n_v, ni = m->n_inputs;
    if (bind(s, &r->phi_jac, "phi_jac", "q,u", p, 1, 2, nv, m->n_jac) || bind(s, &r->nu, "nu", "q,u,ud", p, 1, 1, nv, 0) ||
        bind(s, &r->gamma, "gamma", "q,v,u,ud,udd", p, 1, 1, nv, 0) || bind(s, &r->inputs, "inputs", "t", 0, 0, 1, 3 * ni, 0) ||
        bind(s, &r->input_ranges, "input_ranges", "span", 0, 0, 1, 6 * ni, 0) ||
        bind(s, &r->frames, "frames", "q,v,a", 0, 0, 1, KINEGEN_FRAME_VALUES * m->layout->n_bodies, 0))
        return 1;
    if (d != NULL) { /* the sensitivities': all three, or none (built without them) */
        if (bind(s, &r->phi_p, "phi_p", "q,u", 1, 0, 1, d->phi_p_pattern.n, 0) ||
            bind(s, &r->dvel, "dvel", "q,v,u,ud", 1, r->phi_p != NULL, 1, d->dvel_pattern.n, 0) ||
            bind(s, &r->dacc, "dacc", "q,v,a,u,ud,udd", 1, r->phi_p != NULL, 1, d->dacc_pattern.n, 0))
            return 1;
        if (r->phi_p == NULL && r->dvel != NULL) {
            s->role = "phi_p";
            return 1;
        }
    }
    if (st != NULL)
        return bind(s, &r->actuation, "actuation", "q", p, st->n_elements > 0, 1, st->pattern.n, 0) ||
               bind(s, &r->loads, "loads", "q,t", p, st->n_loads > 0, 1, st->load_pattern.n, 0) ||
               bind(s, &r->inertia, "inertia", "q,v,a", p, st->n_inertia > 0, 1, st->n_inertia, 0) ||
               (st->n_joints > 0 && r->frames == NULL && (s->role = "frames") != NULL);
    return 0;
}

/* Whether a velocity coordinate, named <body>.<coordinate> by the layout, is a body's translation: x, y, z
 * (every parametrization that stores the origin) or vx, vy, vz (the twist of a dual quaternion) -- the
 * names kinegen.rotations gives them (kinegen.runtime.system.TRANSLATIONS, the Python certificate's). */
static int translation(const char *name) {
    static const char *const names[] = {"x", "y", "z", "vx", "vy", "vz"};
    const char *dot = strrchr(name, '.');
    const char *coordinate = dot != NULL ? dot + 1 : name;
    for (size_t k = 0; k < sizeof(names) / sizeof(names[0]); ++k)
        if (strcmp(coordinate, names[k]) == 0) return 1;
    return 0;
}

int kinegen_init(kinegen_solver *s, const kinegen_model *m, const kinegen_options *options, double *doubles, int *ints) {
    int nq = m->n_q, nv = m->n_v;
    memset(s, 0, sizeof(*s));
    s->model = m;
    kinegen_set_design(s, NULL);
    if (options != NULL) {
        s->options = *options;
    } else {
        kinegen_default_options(&s->options);
    }
    s->q = doubles;
    s->v = s->q + nq;
    s->a = s->v + nv;
    s->trial = s->a + nv;
    s->phi = s->trial + nq;
    s->jac = s->phi + nv;
    s->store = s->jac + m->n_jac;
    s->off = s->store + m->n_store;
    s->rhs = s->off + m->n_off;
    s->step = s->rhs + nv;
    s->y = s->step + nv;
    s->x = s->y + nv;
    s->moved = s->x + nv;
    s->w1 = s->moved + nv;
    s->w2 = s->w1 + nv;
    s->jac_q = s->w2 + nv;
    s->u = s->jac_q + m->n_jac;
    s->ud = s->u + m->n_inputs;
    s->cert = s->ud + m->n_inputs;
    s->path = s->cert + 10 * nv + 7 * m->n_inputs;
    s->bound_store = s->path + 5 * m->n_inputs;
    s->bound_off = s->bound_store + m->n_store;
    s->a_start = s->bound_off + m->n_off;
    s->a_prev = s->a_start + nv;
    s->pivots = ints;
    s->perms = ints + 2 * nv;
    s->block_sign = s->perms + nv;
    s->factor_block_sign = s->block_sign + m->n_blocks;
    s->moving = s->factor_block_sign + m->n_blocks;
    s->turning = s->moving + m->n_inputs;
    s->n_turning = 0;
    for (int i = 0; i < nv; ++i)
        if (!translation(m->layout->velocity_names[i])) s->turning[s->n_turning++] = i;
    for (int b = 0; b < m->n_blocks; ++b) s->block_sign[b] = s->factor_block_sign[b] = 1;
    s->branch_block = -1;
    s->branch_input = -1;
    s->branch_time = NAN;
    s->bound = NAN;
    s->t = m->t0;
    s->residual = NAN;
    s->condition = NAN;
    s->sign = 1;
    return bind_roles(s) ? KINEGEN_MODEL : KINEGEN_OK;
}

/* max |x_i|, NaN if any x_i is NaN (as NumPy's max). Without a branch per value: four running maxima, and
 * four running sums of the |x_i|, which only a NaN makes NaN (the |x_i| are >= 0, so no inf - inf) -- an
 * addition a value where a NaN test and flag took three instructions (the branch of `if (!(a <= m)) m = a`
 * cost ~9 % of a step, the flags ~40 % of this loop). */
static double max_abs(const double *x, int n) {
    double m0 = 0.0, m1 = 0.0, m2 = 0.0, m3 = 0.0, s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    int i = 0;
    for (; i + 4 <= n; i += 4) {
        double a0 = fabs(x[i]), a1 = fabs(x[i + 1]), a2 = fabs(x[i + 2]), a3 = fabs(x[i + 3]);
        s0 += a0;
        s1 += a1;
        s2 += a2;
        s3 += a3;
        m0 = a0 > m0 ? a0 : m0;
        m1 = a1 > m1 ? a1 : m1;
        m2 = a2 > m2 ? a2 : m2;
        m3 = a3 > m3 ? a3 : m3;
    }
    for (; i < n; ++i) {
        double a = fabs(x[i]);
        s0 += a;
        m0 = a > m0 ? a : m0;
    }
    m0 = m1 > m0 ? m1 : m0;
    m2 = m3 > m2 ? m3 : m2;
    return isnan((s0 + s1) + (s2 + s3)) ? NAN : (m2 > m0 ? m2 : m0);
}

/* CALL(N) with N a literal for the block sizes the mechanisms have (a joint's or body's 1-9 rows), else
 * with n itself: the block routines below are static inline, so that the compiler unrolls their loops
 * for each literal size (the block solves were ~40 % of a step with the loops over a variable n). */
#define BY_BLOCK_SIZE(n, CALL)                                                                                         \
    switch (n) {                                                                                                       \
    case 1: CALL(1); break;                                                                                            \
    case 2: CALL(2); break;                                                                                            \
    case 3: CALL(3); break;                                                                                            \
    case 4: CALL(4); break;                                                                                            \
    case 6: CALL(6); break;                                                                                            \
    case 7: CALL(7); break;                                                                                            \
    case 9: CALL(9); break;                                                                                            \
    default: CALL(n);                                                                                                  \
    }

/* Full unrolling of a loop at a constant block size (BY_BLOCK_SIZE's cases), for the compilers that read a
 * pragma for it; nothing for the others. In lu_block it takes the excavator's factorization (four 9 x 9
 * blocks) from 1.59 to 1.18 us, the same bits (docs/performance.md). */
#if defined(__clang__)
#define KINEGEN_UNROLL _Pragma("unroll 9")
#elif defined(__GNUC__) && __GNUC__ >= 8
#define KINEGEN_UNROLL _Pragma("GCC unroll 9")
#else
#define KINEGEN_UNROLL
#endif

/* LU with partial pivoting of one n x n block (column-major, in place); pivots in piv.
 * Updates the smallest and largest |pivot| (low_out, high_out) and the parity of interchanges and
 * negative pivots (odd_out); returns 1 at a zero or non-finite pivot. Called through BY_BLOCK_SIZE,
 * where n is a constant and every loop is unrolled. The running values are locals: stores into A
 * could otherwise change them, and each would be read again after every store. */
static inline int lu_block(double *restrict A, int *restrict piv, const int n, double *low_out, double *high_out,
                           int *odd_out) {
    double low = *low_out, high = *high_out;
    int odd = *odd_out, failed = 0;
    KINEGEN_UNROLL
    for (int k = 0; k < n; ++k) {
        int p = k;
        double best = fabs(A[k + k * n]);
        KINEGEN_UNROLL
        for (int i = k + 1; i < n; ++i) {
            double c = fabs(A[i + k * n]);
            p = c > best ? i : p; /* (no branch: which row wins is data) */
            best = c > best ? c : best;
        }
        piv[k] = p;
        if (p != k) {
            odd ^= 1;
            KINEGEN_UNROLL
            for (int j = 0; j < n; ++j) {
                double tmp = A[k + j * n];
                A[k + j * n] = A[p + j * n];
                A[p + j * n] = tmp;
            }
        }
        double pivot = A[k + k * n];
        if (!(best >= low)) low = best; /* NaN propagates */
        if (!(best <= high)) high = best;
        if (pivot == 0.0 || !isfinite(pivot)) {
            failed = 1;
            break;
        }
        if (pivot < 0.0) odd ^= 1;
        double inverse = 1.0 / pivot;
        KINEGEN_UNROLL
        for (int i = k + 1; i < n; ++i) A[i + k * n] *= inverse;
        KINEGEN_UNROLL
        for (int j = k + 1; j < n; ++j) {
            double f = A[k + j * n];
            if (f != 0.0) {
                KINEGEN_UNROLL
                for (int i = k + 1; i < n; ++i) A[i + j * n] -= A[i + k * n] * f;
            }
        }
    }
    *low_out = low;
    *high_out = high;
    *odd_out = odd;
    return failed;
}

/* A block-triangular factorization plan (a case's Phi_q, or the statics' matrix) as one view. */
typedef struct plan_view {
    int n, n_blocks;
    const int *block_start, *block_store, *row_order, *col_order;
    int n_store, n_diag;
    const int *diag_value, *diag_slot;
    int n_off;
    const int *off_start, *off_col, *off_value;
} plan_view;

static plan_view case_plan(const kinegen_model *m) {
    plan_view p = {m->n_v, m->n_blocks, m->block_start, m->block_store, m->row_order, m->col_order, m->n_store, m->n_diag,
                   m->diag_value, m->diag_slot, m->n_off, m->off_start, m->off_col, m->off_value};
    return p;
}

/* LU factors of every diagonal block of the plan's matrix (its values at the plan's pattern) into store, the
 * entries below the blocks into off; the smallest and largest |pivot| into low, high; each block's
 * determinant sign into block_sign (if not NULL). Returns 1 at a zero or non-finite pivot, else 0; *odd:
 * the parity of the whole determinant's sign. */
static int factor_blocks(const plan_view *m, const double *values, double *store, double *off, int *pivots, int *block_sign,
                         double *low, double *high, int *odd) {
    int failed = 0;
    *odd = 0;
    memset(store, 0, sizeof(double) * (size_t)m->n_store);
    for (int k = 0; k < m->n_diag; ++k) store[m->diag_slot[k]] = values[m->diag_value[k]];
    for (int e = 0; e < m->n_off; ++e) off[e] = values[m->off_value[e]]; /* kept with the factors (chord steps) */
    for (int b = 0; b < m->n_blocks && !failed; ++b) {
        int first = m->block_start[b], n = m->block_start[b + 1] - first, block_odd = 0;
        double *A = store + m->block_store[b];
        int *piv = pivots + first;
#define LU_BLOCK(N) failed = lu_block(A, piv, N, low, high, &block_odd)
        BY_BLOCK_SIZE(n, LU_BLOCK)
#undef LU_BLOCK
        if (block_sign != NULL) block_sign[b] = block_odd ? -1 : 1; /* the block's assembly mode */
        *odd ^= block_odd;
    }
    return failed;
}

/* perms from pivots: each block's interchanges composed into one permutation, position k of the block taking
 * its row perms[k] (what the written-out solves gather with: kinegen_solver.perms) */
static void compose_interchanges(const kinegen_model *m, const int *pivots, int *perms) {
    for (int b = 0; b < m->n_blocks; ++b) {
        int first = m->block_start[b], n = m->block_start[b + 1] - first;
        int *perm = perms + first;
        const int *piv = pivots + first;
        for (int k = 0; k < n; ++k) perm[k] = k;
        for (int k = 0; k < n - 1; ++k) { /* (most steps interchange nothing: no store, nothing waits on one) */
            int p = piv[k];
            if (p != k) {
                int t = perm[k];
                perm[k] = perm[p];
                perm[p] = t;
            }
        }
    }
}

/* LU factors of every diagonal block of Phi_q (values jac). Returns 1 when singular. */
static int factor(kinegen_solver *s, const double *jac) {
    plan_view plan = case_plan(s->model);
    double low = INFINITY, high = 0.0;
    int odd = 0;
    s->have_bound = 0;
    if (factor_blocks(&plan, jac, s->store, s->off, s->pivots, s->factor_block_sign, &low, &high, &odd)) {
        s->have_factors = 0;
        return 1;
    }
    if (s->model->solve != NULL) compose_interchanges(s->model, s->pivots, s->perms); /* (only they read perms) */
    s->factor_sign = odd ? -1 : 1;
    s->have_factors = 1;
    return !(low > s->options.singular_tolerance * fmax(high, 1e-300));
}

/* The row interchanges of one n x n block's LU (pivots piv) applied to r, in their order. */
static inline void interchange(const int *piv, double *r, const int n) {
    for (int k = 0; k < n; ++k) {
        if (piv[k] != k) {
            double tmp = r[k];
            r[k] = r[piv[k]];
            r[piv[k]] = tmp;
        }
    }
}

/* r = A^-1 r for one n x n block's LU factors A (column-major) and pivots piv (through BY_BLOCK_SIZE). */
static inline void solve_block(const double *A, const int *piv, double *r, const int n) {
    interchange(piv, r, n);
    for (int k = 0; k < n; ++k)
        for (int i = k + 1; i < n; ++i) r[i] -= A[i + k * n] * r[k];
    for (int k = n - 1; k >= 0; --k) {
        r[k] *= 1.0 / A[k + k * n]; /* the reciprocals off the chain of dependent operations: no division on it */
        for (int i = 0; i < k; ++i) r[i] -= A[i + k * n] * r[k];
    }
}

/* r = an upper bound on |A^-1| r for r >= 0, from one n x n block's LU factors A and pivots piv (through
 * BY_BLOCK_SIZE): M(U)^-1 M(L)^-1 P r, M the comparison matrix (|diagonal|, -|off-diagonal|). For a
 * triangular T, |T^-1| <= M(T)^-1 entry by entry (Higham, Accuracy and Stability of Numerical Algorithms,
 * 2nd ed., Theorem 8.12), and |A^-1| = |U^-1 L^-1 P| <= |U^-1| |L^-1| P. */
static inline void bound_block(const double *A, const int *piv, double *r, const int n) {
    interchange(piv, r, n);
    for (int k = 0; k < n; ++k)
        for (int i = k + 1; i < n; ++i) r[i] += fabs(A[i + k * n]) * r[k];
    for (int k = n - 1; k >= 0; --k) {
        r[k] *= 1.0 / fabs(A[k + k * n]); /* (as solve_block: the same bits as a solve over the comparison matrix) */
        for (int i = 0; i < k; ++i) r[i] += fabs(A[i + k * n]) * r[k];
    }
}

/* The block forward substitution over the current factors, x from b (x and b may alias): y = Phi_q^-1 b
 * (bound = 0: each block's rows less the entries below the blocks times the earlier blocks' solution, then
 * solve_block), or an upper bound on |Phi_q^-1| b for b >= 0 (bound = 1: the same in absolute values, the
 * entries below added, then bound_block). */
static void substitute(kinegen_solver *s, const double *b, double *x, int bound) {
    const kinegen_model *m = s->model;
    double *y = s->y; /* the solution in the permuted order */
    for (int blk = 0; blk < m->n_blocks; ++blk) {
        int first = m->block_start[blk], n = m->block_start[blk + 1] - first;
        const double *A = s->store + m->block_store[blk];
        const int *piv = s->pivots + first;
        double *r = y + first;
        for (int i = 0; i < n; ++i) {
            int row = first + i;
            double acc = b[m->row_order[row]];
            for (int e = m->off_start[row]; e < m->off_start[row + 1]; ++e)
                acc += (bound ? fabs(s->off[e]) : -s->off[e]) * y[m->off_col[e]];
            r[i] = acc;
        }
        if (bound) {
#define BOUND_BLOCK(N) bound_block(A, piv, r, N)
            BY_BLOCK_SIZE(n, BOUND_BLOCK)
#undef BOUND_BLOCK
        } else {
#define SOLVE_BLOCK(N) solve_block(A, piv, r, N)
            BY_BLOCK_SIZE(n, SOLVE_BLOCK)
#undef SOLVE_BLOCK
        }
    }
    for (int j = 0; j < m->n_v; ++j) x[m->col_order[j]] = y[j];
}

/* x = Phi_q^-1 b with the current factors (x and b may alias). */
static void solve(kinegen_solver *s, const double *b, double *x) {
    const kinegen_model *m = s->model;
    if (m->solve != NULL) { /* the case's own, straight-line: ~0.35 against ~1 us for the excavator's */
        m->solve(s->store, s->off, s->perms, b, x, s->y);
        return;
    }
    substitute(s, b, x, 0);
}

/* W's columns solved together by the certificate (the Hermite bound's three changes fit) */
#define CERTIFY_COLUMNS 4

/* solve_block for CERTIFY_COLUMNS columns at once, r holding position i's columns at r[i CERTIFY_COLUMNS + c]:
 * each column's arithmetic that of solve_block (through BY_BLOCK_SIZE). */
static inline void solve_block_columns(const double *A, const int *piv, double *r, const int n) {
    enum { count = CERTIFY_COLUMNS };
    for (int k = 0; k < n; ++k) {
        if (piv[k] != k) {
            double *rk = r + (size_t)k * count, *rp = r + (size_t)piv[k] * count;
            for (int c = 0; c < count; ++c) {
                double tmp = rk[c];
                rk[c] = rp[c];
                rp[c] = tmp;
            }
        }
    }
    for (int k = 0; k < n; ++k)
        for (int i = k + 1; i < n; ++i) {
            double f = A[i + k * n];
            for (int c = 0; c < count; ++c) r[(size_t)i * count + c] -= f * r[(size_t)k * count + c];
        }
    for (int k = n - 1; k >= 0; --k) {
        double inverse = 1.0 / A[k + k * n];
        for (int c = 0; c < count; ++c) r[(size_t)k * count + c] *= inverse;
        for (int i = 0; i < k; ++i) {
            double f = A[i + k * n];
            for (int c = 0; c < count; ++c) r[(size_t)i * count + c] -= f * r[(size_t)k * count + c];
        }
    }
}

/* The CERTIFY_COLUMNS columns of b (column c at b + c n_v; those from `used` on zero) each replaced by
 * Phi_q^-1 times it (the input effects of a step's certificate): through the case's written-out solve one
 * column at a time, else with the same factors in one pass of the loop over them; y: CERTIFY_COLUMNS n_v
 * scratch values (the solution in the permuted order, position by position). Blocks above the columns'
 * first non-zero value are skipped (their solution is zero). The arithmetic of each column is that of solve(). */
static int zero_block(const kinegen_model *m, int count, const double *b, int blk) {
    for (int row = m->block_start[blk]; row < m->block_start[blk + 1]; ++row)
        for (int c = 0; c < count; ++c)
            if (b[(size_t)c * m->n_v + m->row_order[row]] != 0.0) return 0;
    return 1;
}

static void solve_columns(kinegen_solver *s, double *b, int used, double *y) {
    enum { count = CERTIFY_COLUMNS }; /* a constant: each row's columns in one vector operation */
    const kinegen_model *m = s->model;
    if (m->solve != NULL) { /* the case's written-out solve, column by column (the columns from used on are zero):
                             * the excavator's four columns 1.4 us against 2.6 us in one pass of the loop */
        for (int c = 0; c < used; ++c) m->solve(s->store, s->off, s->perms, b + (size_t)c * m->n_v, b + (size_t)c * m->n_v, y);
        return;
    }
    int nv = m->n_v, start = 0; /* the first block where a column has a non-zero value */
    while (start < m->n_blocks && zero_block(m, count, b, start)) ++start;
    memset(y, 0, sizeof(double) * (size_t)count * (size_t)m->block_start[start]);
    for (int blk = start; blk < m->n_blocks; ++blk) {
        int first = m->block_start[blk], n = m->block_start[blk + 1] - first;
        const double *A = s->store + m->block_store[blk];
        const int *piv = s->pivots + first;
        double *r = y + (size_t)first * count; /* position first + i, column c at r[i count + c] */
        for (int i = 0; i < n; ++i) {
            int row = first + i, source = m->row_order[row];
            double *ri = r + (size_t)i * count;
            for (int c = 0; c < count; ++c) ri[c] = b[(size_t)c * nv + source];
            for (int e = m->off_start[row]; e < m->off_start[row + 1]; ++e) {
                double f = s->off[e];
                const double *yc = y + (size_t)m->off_col[e] * count;
                for (int c = 0; c < count; ++c) ri[c] -= f * yc[c];
            }
        }
#define SOLVE_BLOCK_COLUMNS(N) solve_block_columns(A, piv, r, N)
        BY_BLOCK_SIZE(n, SOLVE_BLOCK_COLUMNS)
#undef SOLVE_BLOCK_COLUMNS
    }
    for (int j = 0; j < nv; ++j)
        for (int c = 0; c < count; ++c) b[(size_t)c * nv + m->col_order[j]] = y[(size_t)j * count + c];
}

/* out = -|x| for n values, four at a time (as max_abs: a quarter of the loop's own instructions) */
static void negated_magnitudes(const double *x, double *out, int n) {
    int i = 0;
    for (; i + 4 <= n; i += 4) {
        double a0 = -fabs(x[i]), a1 = -fabs(x[i + 1]), a2 = -fabs(x[i + 2]), a3 = -fabs(x[i + 3]);
        out[i] = a0;
        out[i + 1] = a1;
        out[i + 2] = a2;
        out[i + 3] = a3;
    }
    for (; i < n; ++i) out[i] = -fabs(x[i]);
}

/* x = an upper bound on |Phi_q^-1| b for b >= 0 (entry by entry) from the current factors (x and b may
 * alias): substitute's pass in absolute values. Coarse -- it loses every cancellation: ~10^3-10^4 times
 * |Phi_q^-1| b on chain-50's and the excavator's steps. With the case's written-out solve, that solve over
 * the factors' comparison matrices (bound_store, bound_off: each block's LU with |diagonal| and -|other
 * entries|, -|entries below the blocks|), made once per factorization: substitute's pass to the bit
 * (a - (-|e|) y is a + |e| y exactly) at a solve's cost (chain-14: ~2 against ~11 thousand instructions).
 * first: b is zero in the rows before the written-out solve's function `first` (kinegen_model.solve_from),
 * whose functions are then skipped: their part of the bound is zero, so the bits are the same. */
static void solve_bound_from(kinegen_solver *s, const double *b, double *x, int first) {
    const kinegen_model *m = s->model;
    if (m->solve == NULL) {
        substitute(s, b, x, 1);
        return;
    }
    if (!s->have_bound) {
        negated_magnitudes(s->store, s->bound_store, m->n_store);
        negated_magnitudes(s->off, s->bound_off, m->n_off);
        for (int blk = 0; blk < m->n_blocks; ++blk) {
            int n = m->block_start[blk + 1] - m->block_start[blk];
            double *A = s->bound_store + m->block_store[blk];
            for (int k = 0; k < n; ++k) A[k + k * n] = -A[k + k * n];
        }
        s->have_bound = 1;
    }
    if (first > 0 && m->solve_from != NULL)
        m->solve_from(s->bound_store, s->bound_off, s->perms, b, x, s->y, first);
    else
        m->solve(s->bound_store, s->bound_off, s->perms, b, x, s->y);
}

static void solve_bound(kinegen_solver *s, const double *b, double *x) { solve_bound_from(s, b, x, 0); }

/* r = A^-T r for one block's LU factors A and pivots piv (through BY_BLOCK_SIZE). */
static inline void solve_block_transposed(const double *A, const int *piv, double *r, const int n) {
    for (int k = 0; k < n; ++k) { /* U^T */
        double acc = r[k];
        for (int i = 0; i < k; ++i) acc -= A[i + k * n] * r[i];
        r[k] = acc * (1.0 / A[k + k * n]);
    }
    for (int k = n - 1; k >= 0; --k) { /* L^T */
        double acc = r[k];
        for (int i = k + 1; i < n; ++i) acc -= A[i + k * n] * r[i];
        r[k] = acc;
    }
    for (int k = n - 1; k >= 0; --k) {
        if (piv[k] != k) {
            double tmp = r[k];
            r[k] = r[piv[k]];
            r[piv[k]] = tmp;
        }
    }
}

/* x = M^-T c with the factors of the plan's matrix M (store, off, pivots); w: n values of work (x and c may
 * alias): the force solve's (kinegen_forces). */
static void solve_transposed_blocks(const plan_view *m, const double *store, const double *off, const int *pivots, double *w,
                                    const double *c, double *x) {
    for (int j = 0; j < m->n; ++j) w[j] = c[m->col_order[j]];
    for (int blk = m->n_blocks - 1; blk >= 0; --blk) {
        int first = m->block_start[blk], n = m->block_start[blk + 1] - first;
        const double *A = store + m->block_store[blk];
        const int *piv = pivots + first;
        double *r = w + first;
#define SOLVE_BLOCK_TRANSPOSED(N) solve_block_transposed(A, piv, r, N)
        BY_BLOCK_SIZE(n, SOLVE_BLOCK_TRANSPOSED)
#undef SOLVE_BLOCK_TRANSPOSED
        /* the entries below the blocks couple this block's rows to earlier blocks' columns */
        for (int i = 0; i < n; ++i) {
            int row = first + i;
            for (int e = m->off_start[row]; e < m->off_start[row + 1]; ++e) w[m->off_col[e]] -= off[e] * r[i];
        }
    }
    for (int i = 0; i < m->n; ++i) x[m->row_order[i]] = w[i];
}

/* x = Phi_q^-T c (for the condition estimate; x and c may alias). The blocks' arithmetic is shared with
 * solve_transposed_blocks (solve_block_transposed); the loop over the blocks is written again on the
 * solver's own fields: the condition estimate calls it at every step, and through the shared function
 * (static or static inline, with or without restrict) the excavator's digging step took 29.6-31.6 us
 * instead of 22.5-24.2 us (2026-11-27: gcc 12 -O2 -march=native, 1000 steps, best of 30, 4 alternating
 * pairs, loaded machine), and again 25.7-26.8 us instead of 19.8-20.6 us after the block routines
 * (4 pairs, quiet) -- far above the 2 % sharing may cost. */
static void solve_transposed(kinegen_solver *s, const double *c, double *x) {
    const kinegen_model *m = s->model;
    double *w = s->y;
    if (m->solve_transposed != NULL) { /* the case's own, written out */
        m->solve_transposed(s->store, s->off, s->perms, c, x, w);
        return;
    }
    for (int j = 0; j < m->n_v; ++j) w[j] = c[m->col_order[j]];
    for (int blk = m->n_blocks - 1; blk >= 0; --blk) {
        int first = m->block_start[blk], n = m->block_start[blk + 1] - first;
        const double *A = s->store + m->block_store[blk];
        const int *piv = s->pivots + first;
        double *r = w + first;
#define SOLVE_BLOCK_TRANSPOSED(N) solve_block_transposed(A, piv, r, N)
        BY_BLOCK_SIZE(n, SOLVE_BLOCK_TRANSPOSED)
#undef SOLVE_BLOCK_TRANSPOSED
        /* the entries below the blocks couple this block's rows to earlier blocks' columns */
        for (int i = 0; i < n; ++i) {
            int row = first + i;
            for (int e = m->off_start[row]; e < m->off_start[row + 1]; ++e) w[m->off_col[e]] -= s->off[e] * r[i];
        }
    }
    for (int i = 0; i < m->n_v; ++i) x[m->row_order[i]] = w[i];
}

/* The first index of the largest |x[i]| (BLAS's IDAMAX, 0-based; 0 when x[0] is NaN, a NaN never chosen):
 * the largest found first, in four running maxima, then its first index. The search by index (j = i where
 * |x[i]| > |x[j]|) reads x[j] again in every comparison, a chain through memory: with it the excavator's
 * condition estimate took 2.25-2.29 us, with this 1.91-1.95 us (2026-12-04: its digging case, 20 states,
 * best of 7 x 2000 calls), the same index. */
static int first_largest(const double *x, int n) {
    double m0 = fabs(x[0]), m1 = m0, m2 = m0, m3 = m0;
    int i = 1;
    for (; i + 4 <= n; i += 4) {
        double a0 = fabs(x[i]), a1 = fabs(x[i + 1]), a2 = fabs(x[i + 2]), a3 = fabs(x[i + 3]);
        m0 = a0 > m0 ? a0 : m0;
        m1 = a1 > m1 ? a1 : m1;
        m2 = a2 > m2 ? a2 : m2;
        m3 = a3 > m3 ? a3 : m3;
    }
    for (; i < n; ++i) {
        double a = fabs(x[i]);
        m0 = a > m0 ? a : m0;
    }
    m0 = m1 > m0 ? m1 : m0;
    m2 = m3 > m2 ? m3 : m2;
    m0 = m2 > m0 ? m2 : m0;
    for (i = 0; i < n; ++i)
        if (fabs(x[i]) == m0) return i;
    return 0;
}

/* A value's sign as LAPACK's xLACN2 takes it: +1 where it is >= 0, a zero of either sign too. (copysign, the old
 * xLACON's SIGN(ONE, X) with IEEE zeros, made -0.0 -1; a solve of e_j is exactly zero in every block before
 * j's, with the sign of its pivots, so that changed the sign vectors: the excavator's level cut agreed with
 * the Python path's LAPACK gecon to 1e-12 in 72.6 % of its 1,000 steps, now 85.1 %; digging 97.7 %, its
 * largest ratio 2.25 -> 1.00.) */
static inline double lacn2_sign(double x) { return x >= 0.0 ? 1.0 : -1.0; }

/* 1-norm condition estimate of Phi_q from its factors: ||Phi_q||_1 times Higham's estimate of
 * ||Phi_q^-1||_1 (the iteration of LAPACK's xLACN2: at most 5 sign-vector steps, then the
 * alternating vector's estimate if larger; its signs: lacn2_sign). */
static double condition_estimate(kinegen_solver *s) {
    const kinegen_model *m = s->model;
    int n = m->n_v, *isgn = s->pivots + n; /* the sign vector, after the pivots */
    double *x = s->x, anorm, estimate, previous;
    memset(x, 0, sizeof(double) * (size_t)n);
    for (int k = 0; k < m->n_jac; ++k) x[m->jac_cols[k]] += fabs(s->jac[k]);
    anorm = max_abs(x, n);
    for (int i = 0; i < n; ++i) x[i] = 1.0 / n;
    solve(s, x, x);
    if (n == 1) return anorm * fabs(x[0]);
    estimate = 0.0;
    for (int i = 0; i < n; ++i) {
        estimate += fabs(x[i]);
        x[i] = lacn2_sign(x[i]);
        isgn[i] = (int)x[i];
    }
    solve_transposed(s, x, x);
    int j = first_largest(x, n);
    for (int iteration = 2;; ++iteration) {
        memset(x, 0, sizeof(double) * (size_t)n);
        x[j] = 1.0;
        solve(s, x, x);
        previous = estimate;
        estimate = 0.0;
        int changed = 0;
        for (int i = 0; i < n; ++i) {
            estimate += fabs(x[i]);
            if ((int)lacn2_sign(x[i]) != isgn[i]) changed = 1;
        }
        if (!changed || estimate <= previous) break; /* a repeated sign vector, or no progress */
        for (int i = 0; i < n; ++i) {
            x[i] = lacn2_sign(x[i]);
            isgn[i] = (int)x[i];
        }
        solve_transposed(s, x, x);
        int last = j;
        j = first_largest(x, n);
        if (x[last] == fabs(x[j]) || iteration >= 5) break;
    }
    double sign = 1.0;
    for (int i = 0; i < n; ++i) {
        x[i] = sign * (1.0 + (double)i / (n - 1));
        sign = -sign;
    }
    solve(s, x, x);
    double alternative = 0.0;
    for (int i = 0; i < n; ++i) alternative += fabs(x[i]);
    alternative = 2.0 * alternative / (3.0 * n);
    return anorm * (alternative > estimate ? alternative : estimate);
}

/* Newton from s->trial for inputs u; with have_factors and chord, chord iterations first.
 * On KINEGEN_OK: phi and jac at the solution, *count iterations, *travel summed max-norm steps;
 * every step is also added to s->moved. */
static int newton(kinegen_solver *s, const double *u, int chord, int *count, double *travel, double *norm) {
    const kinegen_model *m = s->model;
    const kinegen_options *o = &s->options;
    int n = m->n_v, have = chord && s->have_factors;
    phi_jac(s, s->trial, u, s->phi, s->jac);
    *norm = max_abs(s->phi, n);
    *count = 0;
    *travel = 0.0;
    while (!(*norm <= o->tolerance)) {
        if (*count >= o->max_iterations || !isfinite(*norm) || *norm > o->divergence_limit) return KINEGEN_NOT_CONVERGED;
        if (!have) {
            if (factor(s, s->jac)) return KINEGEN_SINGULAR;
            have = 1;
        }
        solve(s, s->phi, s->step);
        for (int j = 0; j < n; ++j) {
            s->step[j] = -s->step[j];
            s->moved[j] += s->step[j];
        }
        ++*count;
        *travel += max_abs(s->step, n);
        m->retract(s->trial, s->step);
        phi_jac(s, s->trial, u, s->phi, s->jac);
        double next = max_abs(s->phi, n);
        if (!chord || !(next <= o->chord_rate * *norm)) have = 0;
        *norm = next;
    }
    return KINEGEN_OK;
}

/* The k-th change of the inputs the Hermite bound takes (w, n_inputs values), for the step of h from
 * the state's inputs (s->u, s->ud) to (u, ud): D = u1 - u0, A = h ud0 - D, B = h ud1 - D. */
static void input_change(const kinegen_solver *s, int k, double h, const double *u, const double *ud, double *w) {
    for (int i = 0; i < s->model->n_inputs; ++i) {
        double change = u[i] - s->u[i];
        w[i] = k == 0 ? change : (k == 1 ? h * s->ud[i] : h * ud[i]) - change;
    }
}

/* A bound c_k on |u_k(t) - L_k(t)| over a step of h, L the chord from u_k(t0) to u_k(t1) = u1 (change = u1 -
 * u_k(t0)), from the enclosures of u, du/dt, d2u/dt2 over the step (ranges: the input_ranges kernel's
 * output): h^2/8 max |d2u/dt2| (linear interpolation's error), else min(max |u - u1|, h max |du/dt|) +
 * |change|; infinite where nothing bounds it. Where c_k is the first, with d2u/dt2 in [lo, hi] = mid +- rad,
 * also its split (input_effect): *curve = h^2/8 mid, *beyond = h^2/8 rad; else *curve = 0, *beyond = c_k. */
static double chord_deviation(const double *ranges, int ni, int k, double h, double u1, double change, double *curve,
                              double *beyond) {
    const double *lo = ranges, *hi = ranges + 3 * ni;
    double offset = fmax(fabs(lo[k] - u1), fabs(hi[k] - u1));
    double rate = fmax(fabs(lo[ni + k]), fabs(hi[ni + k]));
    double low = lo[2 * ni + k], high = hi[2 * ni + k];
    double fine = h * h / 8.0 * fmax(fabs(low), fabs(high));
    double bound = fmin(fine, fmin(offset, h * rate) + fabs(change));
    bound = isnan(bound) ? INFINITY : bound;
    double mid = 0.5 * (low + high), rad = fmax(high - mid, mid - low);
    int split = bound == fine && isfinite(mid) && isfinite(rad);
    *curve = split ? h * h / 8.0 * mid : 0.0;
    *beyond = split ? h * h / 8.0 * rad : bound;
    return bound;
}

/* |Phi_u| c over the moving inputs from `first` on (moving[first .. count - 1]), c their chord deviations: in
 * driver k's row (n_v - n_inputs + k), |-Phi_u 1| there (s->w2, nu's) times c_k; zero elsewhere. What the
 * coarse bound of their spread sum_k |W_k| c_k is taken of (solve_bound). */
static void spread_rhs(const kinegen_solver *s, const int *moving, int first, int count, const double *deviation,
                       double *out) {
    int nv = s->model->n_v, ni = s->model->n_inputs;
    memset(out, 0, sizeof(double) * (size_t)nv);
    for (int c = first; c < count; ++c) {
        int row = nv - ni + moving[c];
        out[row] = fabs(s->w2[row]) * deviation[moving[c]];
    }
}

/* sum += change column and spread += spread_k |column| over n values; returns max |column| (NaN passed over).
 * Four at a time, each value's arithmetic as one at a time. */
static double add_column(const double *restrict column, double change, double spread_k, double *restrict sum,
                         double *restrict spread, int n) {
    double m0 = 0.0, m1 = 0.0, m2 = 0.0, m3 = 0.0;
    int j = 0;
    for (; j + 4 <= n; j += 4) {
        double a0 = fabs(column[j]), a1 = fabs(column[j + 1]), a2 = fabs(column[j + 2]), a3 = fabs(column[j + 3]);
        m0 = a0 > m0 ? a0 : m0;
        m1 = a1 > m1 ? a1 : m1;
        m2 = a2 > m2 ? a2 : m2;
        m3 = a3 > m3 ? a3 : m3;
        sum[j] += column[j] * change;
        sum[j + 1] += column[j + 1] * change;
        sum[j + 2] += column[j + 2] * change;
        sum[j + 3] += column[j + 3] * change;
        spread[j] += a0 * spread_k;
        spread[j + 1] += a1 * spread_k;
        spread[j + 2] += a2 * spread_k;
        spread[j + 3] += a3 * spread_k;
    }
    for (; j < n; ++j) {
        double a = fabs(column[j]);
        m0 = a > m0 ? a : m0;
        sum[j] += column[j] * change;
        spread[j] += a * spread_k;
    }
    m0 = m1 > m0 ? m1 : m0;
    m2 = m3 > m2 ? m3 : m2;
    return m2 > m0 ? m2 : m0;
}

/* max over k of |x[index[k]]|, at least 0 (a NaN is passed over), in four running maxima (as max_of_sum) */
static double largest_at(const double *x, const int *index, int n) {
    double t0 = 0.0, t1 = 0.0, t2 = 0.0, t3 = 0.0;
    int k = 0;
    for (; k + 4 <= n; k += 4) {
        double a0 = fabs(x[index[k]]), a1 = fabs(x[index[k + 1]]), a2 = fabs(x[index[k + 2]]), a3 = fabs(x[index[k + 3]]);
        t0 = a0 > t0 ? a0 : t0;
        t1 = a1 > t1 ? a1 : t1;
        t2 = a2 > t2 ? a2 : t2;
        t3 = a3 > t3 ? a3 : t3;
    }
    for (; k < n; ++k) {
        double a = fabs(x[index[k]]);
        t0 = a > t0 ? a : t0;
    }
    t0 = t1 > t0 ? t1 : t0;
    t2 = t3 > t2 ? t3 : t2;
    return t2 > t0 ? t2 : t0;
}

/* max over j of a_j + b_j, at least 0 (a NaN is passed over, as by fmax): in four running maxima, as
 * max_abs (one, a chain of dependent comparisons, took 1.9 % of chain-100's certified step) -- the same
 * value, a maximum's being the same in any order */
static double max_of_sum(const double *a, const double *b, int n) {
    double t0 = 0.0, t1 = 0.0, t2 = 0.0, t3 = 0.0;
    int j = 0;
    for (; j + 4 <= n; j += 4) {
        double v0 = a[j] + b[j], v1 = a[j + 1] + b[j + 1], v2 = a[j + 2] + b[j + 2], v3 = a[j + 3] + b[j + 3];
        t0 = v0 > t0 ? v0 : t0;
        t1 = v1 > t1 ? v1 : t1;
        t2 = v2 > t2 ? v2 : t2;
        t3 = v3 > t3 ? v3 : t3;
    }
    for (; j < n; ++j) {
        double v = a[j] + b[j];
        t0 = v > t0 ? v : t0;
    }
    t0 = t1 > t0 ? t1 : t0;
    t2 = t3 > t2 ? t3 : t2;
    return t2 > t0 ? t2 : t0;
}

/* A bound on max over the step (from the state at s->t to t = s->t + h, inputs u, ud) of |W (u(s) - u1)|,
 * W = J1^-1 Phi_u (the factors in store), as input_effect in kinegen/runtime/solver.py:
 *   the case's own time functions (options.case_inputs): u(s) - u1 = -(1 - r) D + e(s), |e_k| <= the chord
 *     deviation c_k over the step's enclosures, so at most |W D| + |sum_k |W_k| c_k|; s->branch_input: the
 *     input that contributes most. Where c_k is the curvature's h^2/8 max |d2u/dt2| (chord_deviation), e_k(s)
 *     = -(sigma/2) d2u_k/dt2 at some point of the step (the interpolation error's Peano form, sigma = (s - t0)
 *     (t1 - s) <= h^2/4: one factor for every input), so with d2u_k/dt2 in mid_k +- rad_k, e(s) = -(4 sigma /
 *     h^2) (curve + delta), |delta_k| <= beyond_k (h^2/8 mid_k, h^2/8 rad_k): the exact bound is |W D| + max
 *     over rows of (|W curve| + sum_k |W_k| beyond_k), never above |W D| + |sum_k |W_k| c_k| (|mid| + rad =
 *     max |d2u/dt2|), and far below it where the inputs' curvature changes little within the step: chain-100's
 *     exact columns 29,432 -> 5,468 in 999 steps. First coarsely, from two solves whatever the number of inputs: |W D| from
 *     one solve of Phi_u D, and sum_k |W_k| c_k <= |Phi_q^-1| |Phi_u| c bounded by solve_bound. That value
 *     is returned when it is below `allowed` (what the step's bound allows the effect) by a margin of 1e-12
 *     of it: it is never below the exact one, so a step it certifies the exact bound certifies too. |W D|
 *     alone is returned when it is above `allowed` by that margin and this is not the last try (`last_try`:
 *     where the refusal names the input): the exact bound is at least |W D|, so it would refuse the step
 *     too. Then, with curves, |W D| + max(|W curve| + the coarse bound of sum_k |W_k| beyond_k) (two more
 *     solves), returned by the same rule. Otherwise the exact bound, column by column, CERTIFY_COLUMNS at a
 *     time in the inputs' order -- after each group also |W D| + the exact spread so far + the coarse bound of the rest's, returned when it is
 *     below `allowed` by that margin (chain-50, where the first inputs' columns run the whole chain and
 *     their coarse bound is the loosest: of 224 such certificates, 91 settled after 4 columns, 58 after 8,
 *     65 after 12, 10 after 16, of 50). The same steps are accepted and refused either way. Phi_u's columns
 *     come from one nu call: driver k's equation is row n_v - n_inputs + k (the drivers' rows come last, in
 *     the inputs' order; kinegen_model) and depends on u_k alone, so nu(q, u, 1) holds column k's one value
 *     in that row, the same value nu(q, u, e_k) gives there (one call a step, not one per moving input:
 *     chain-50 217 -> 179 us a step);
 *   tabulated inputs: along the cubic Hermite path of the values and rates at both ends, u(s) - u1 =
 *     -(1 - r) D + r (1 - r)^2 A - r^2 (1 - r) B, so at most |W D| + 4/27 (|W A| + |W B|).
 * Work: s->cert (10 n_v + 7 n_inputs doubles), s->moving, s->x (n_inputs), s->w1 and s->w2 (n_v each). */
static double input_effect(kinegen_solver *s, double t, double h, const double *u, const double *ud, double allowed,
                           int last_try) {
    const kinegen_model *m = s->model;
    int nv = m->n_v, ni = m->n_inputs;
    double *w = s->x; /* n_inputs <= n_v values */
    double *columns = s->cert, *scratch = s->cert + CERTIFY_COLUMNS * nv; /* CERTIFY_COLUMNS columns of W at a time */
    s->branch_input = -1;
    if (s->options.case_inputs && s->roles.input_ranges != NULL) {
        double *sum = s->cert + 2 * CERTIFY_COLUMNS * nv, *spread = sum + nv, *ranges = spread + nv, *deviation = ranges + 6 * ni;
        double *beyond = ranges, *curve = ranges + ni; /* each input's own enclosures are read before its split is written */
        int *moving = s->moving, count = 0;
        double span[2], worst = -1.0;
        span[0] = s->t;
        span[1] = t;
        const double *x[1] = {span};
        double *y[1] = {ranges};
        s->roles.input_ranges->call(x, y);
        memset(sum, 0, sizeof(double) * 2 * (size_t)nv);
        for (int k = 0; k < ni; ++k) {
            double split[2];
            deviation[k] = chord_deviation(ranges, ni, k, h, u[k], u[k] - s->u[k], split, split + 1);
            curve[k] = split[0];
            beyond[k] = split[1];
            if (u[k] != s->u[k] || deviation[k] != 0.0) moving[count++] = k; /* the others stay put */
        }
        for (int i = 0; i < ni; ++i) w[i] = 1.0;
        nu(s, s->trial, u, w, s->w2); /* -Phi_u 1: -dPhi/du_k in driver k's row, n_v - n_inputs + k */
        double changed = -1.0; /* |W D| from the coarse bounds' solve, once they ran */
        if (count > 1) { /* the coarse bound (with one input it is no cheaper than the exact) */
            double *effect = columns, *deviations = columns + nv;
            int finite = 1;
            memset(effect, 0, sizeof(double) * (size_t)nv);
            for (int c = 0; c < count; ++c) {
                int k = moving[c], row = nv - ni + k;
                effect[row] = s->w2[row] * (u[k] - s->u[k]);
                finite &= isfinite(deviation[k]);
            }
            spread_rhs(s, moving, 0, count, deviation, deviations);
            if (finite) {
                solve(s, effect, effect);
                solve_bound(s, deviations, deviations);
                changed = max_abs(effect, nv);
                double coarse = changed + max_abs(deviations, nv);
                if (coarse <= allowed * (1.0 - 1e-12)) return coarse; /* (NaN is neither) */
                if (!last_try && changed >= allowed + 1e-12 * fabs(allowed)) return changed;
            }
        }
        double *mean = columns; /* |W curve| starts the spread; then coarsely, the rest of it as above */
        int curved = 0;
        memset(mean, 0, sizeof(double) * (size_t)nv);
        for (int c = 0; c < count; ++c) {
            int k = moving[c], row = nv - ni + k;
            mean[row] = s->w2[row] * curve[k];
            curved |= curve[k] != 0.0;
        }
        if (curved) {
            solve(s, mean, mean);
            for (int j = 0; j < nv; ++j) spread[j] = fabs(mean[j]);
            if (changed >= 0.0) {
                double *rest = s->w1;
                spread_rhs(s, moving, 0, count, beyond, rest);
                solve_bound(s, rest, rest);
                double top = max_of_sum(spread, rest, nv);
                if (changed + top <= allowed * (1.0 - 1e-12)) return changed + top;
            }
        }
        int by_piece = m->solve_from != NULL && m->input_pieces != NULL; /* each column from its driver's part of the solve */
        double *unit = scratch + nv; /* by_piece: -Phi_u e_k, zero but in driver k's row (solve_from's y: scratch) */
        if (by_piece) memset(unit, 0, sizeof(double) * (size_t)nv);
        for (int first = 0; first < count; first += CERTIFY_COLUMNS) {
            int group = count - first < CERTIFY_COLUMNS ? count - first : CERTIFY_COLUMNS;
            if (by_piece) /* solve_from writes each whole column: nothing to clear */
                for (int c = 0; c < group; ++c) {
                    int k = moving[first + c], row = nv - ni + k;
                    unit[row] = s->w2[row];
                    m->solve_from(s->store, s->off, s->perms, unit, columns + (size_t)c * nv, scratch, m->input_pieces[k]);
                    unit[row] = 0.0;
                }
            else {
                memset(columns, 0, sizeof(double) * CERTIFY_COLUMNS * (size_t)nv);
                for (int c = 0; c < group; ++c) { /* -Phi_u e_k: its one value */
                    int row = nv - ni + moving[first + c];
                    columns[(size_t)c * nv + row] = s->w2[row];
                }
                solve_columns(s, columns, group, scratch);
            }
            for (int c = 0; c < group; ++c) {
                int k = moving[first + c];
                double change = u[k] - s->u[k], spread_k = isinf(beyond[k]) ? 0.0 : beyond[k];
                double size = add_column(columns + (size_t)c * nv, change, spread_k, sum, spread, nv);
                double share = size * (fabs(change) + deviation[k]);
                if (size > 0.0 && !(share <= worst)) { /* (an input that does nothing here adds nothing) */
                    worst = share;
                    s->branch_input = k;
                }
                if (size > 0.0 && isinf(deviation[k])) return INFINITY;
            }
            int done = first + group;
            if (changed >= 0.0 && done < count) { /* the exact spread so far, the coarse bound of the rest */
                double *rest = s->w1;
                int from = by_piece ? m->input_pieces[moving[done]] : 0; /* the rest's first row with a value */
                for (int c = done + 1; c < count && by_piece; ++c) from = m->input_pieces[moving[c]] < from ? m->input_pieces[moving[c]] : from;
                spread_rhs(s, moving, done, count, beyond, rest);
                solve_bound_from(s, rest, rest, from);
                double top = max_of_sum(spread, rest, nv);
                if (changed + top <= allowed * (1.0 - 1e-12)) return changed + top;
            }
        }
        return max_abs(sum, nv) + max_abs(spread, nv);
    }
    for (int k = 0; k < 3; ++k) { /* |W D|, |W A|, |W B| solved together */
        input_change(s, k, h, u, ud, w);
        nu(s, s->trial, u, w, columns + (size_t)k * nv);
    }
    memset(columns + 3 * (size_t)nv, 0, sizeof(double) * (size_t)nv * (CERTIFY_COLUMNS - 3));
    solve_columns(s, columns, 3, scratch);
    return max_abs(columns, nv) + 4.0 / 27.0 * (max_abs(columns + nv, nv) + max_abs(columns + 2 * nv, nv));
}

/* w = (J0 - J1) d for Phi_q's values j0, j1 at the case's pattern (jac_rows, jac_cols) and d (n_v values):
 * each row's terms added in the pattern's order, a run of one row's entries in a register. Row by row
 * through memory, every term waited on the store of the one before it (the pattern lists a row's
 * entries together): ~57 % of finish's time on the excavator's step. Where every row's entries are one
 * run (every generated pattern) the sums are those of adding term by term into w, to the bit. */
static void changes_times(const kinegen_model *m, const double *j0, const double *j1, const double *d, double *w) {
    memset(w, 0, sizeof(double) * (size_t)m->n_v);
    int k = 0;
    while (k < m->n_jac) {
        int row = m->jac_rows[k];
        double acc = 0.0;
        for (; k < m->n_jac && m->jac_rows[k] == row; ++k) acc += (j0[k] - j1[k]) * d[m->jac_cols[k]];
        w[row] += acc;
    }
}

/* The step's certificate (see kinegen_options in kinegen_solver.h) for the converged s->trial at
 * the new inputs u, ud at t, a step of h from the state (q, u, ud at s->t): the factors in store are
 * Phi_q's at s->trial and s->step is -Phi_q^-1 Phi there; last_try: a refusal is final (no halving follows),
 * so it names the input (branch_input). KINEGEN_OK or KINEGEN_BRANCH. */
static int certify(kinegen_solver *s, double t, double h, const double *u, const double *ud, int last_try) {
    const kinegen_model *m = s->model;
    int nv = m->n_v;
    s->branch_block = -1;
    s->branch_input = -1;
    for (int b = 0; b < m->n_blocks; ++b)
        if (s->factor_block_sign[b] != s->block_sign[b]) {
            s->branch_block = b;
            s->bound = NAN;
            return KINEGEN_BRANCH;
        }
    double distance = max_abs(s->moved, nv), omega = 0.0, turn = largest_at(s->moved, s->turning, s->n_turning);
    if (!(turn < KINEGEN_MAX_MOTION) || !isfinite(distance)) { /* beyond a quarter turn: see KINEGEN_MAX_MOTION */
        s->bound = INFINITY;
        return KINEGEN_BRANCH;
    }
    if (distance > KINEGEN_MIN_MOTION) { /* omega = safety |J1^-1 (J0 - J1) d| / |d|^2 */
        changes_times(m, s->jac_q, s->jac, s->moved, s->w1);
        solve(s, s->w1, s->w1);
        omega = s->options.safety * max_abs(s->w1, nv) / (distance * distance);
    }
    /* alpha: Newton's last correction, plus the inputs' effect over the step (what alpha omega <= 1/2 allows
     * that effect: its coarse bounds are decisive only away from it) */
    double correction = max_abs(s->step, nv);
    double alpha = correction + input_effect(s, t, h, u, ud, omega > 0.0 ? 0.5 / omega - correction : INFINITY, last_try);
    s->bound = alpha * omega;
    if (!(s->bound <= 0.5 && omega * distance < 1.0)) return KINEGEN_BRANCH;
    return KINEGEN_OK;
}

/* From a converged s->trial (phi, jac at it): factors, the certificate (certify_h > 0: the step's
 * length; last_try as certify's), polish, v, a; commit the state. */
static int finish(kinegen_solver *s, double t, const double *u, const double *ud, const double *udd, int count, double norm,
                  double certify_h, int last_try) {
    const kinegen_model *m = s->model;
    const kinegen_options *o = &s->options;
    int n = m->n_v;
    if (factor(s, s->jac)) return KINEGEN_SINGULAR;
    solve(s, s->phi, s->step); /* the polishing correction */
    for (int j = 0; j < n; ++j) s->step[j] = -s->step[j];
    if (certify_h > 0.0 && o->keep_branch) {
        int status = certify(s, t, certify_h, u, ud, last_try);
        if (status != KINEGEN_OK) {
            s->have_factors = 0;
            return status;
        }
    }
    double condition = o->condition ? condition_estimate(s) : NAN;
    if (o->polish || o->chord) m->retract(s->trial, s->step);
    memcpy(s->q, s->trial, sizeof(double) * (size_t)m->n_q);
    double *at_q = s->jac; /* Phi_q at q: the state's by an exchange of the two arrays, not a copy (chain-100's 35 kB
                            * a step); s->jac is written again before it is read (phi_jac: newton, kinegen_resume) */
    s->jac = s->jac_q;
    s->jac_q = at_q;
    memcpy(s->block_sign, s->factor_block_sign, sizeof(int) * (size_t)m->n_blocks);
    memcpy(s->u, u, sizeof(double) * (size_t)m->n_inputs);
    memcpy(s->ud, ud, sizeof(double) * (size_t)m->n_inputs);
    nu(s, s->q, u, ud, s->rhs);
    solve(s, s->rhs, s->v);
    gamma_rhs(s, s->q, s->v, u, ud, udd, s->rhs);
    solve(s, s->rhs, s->a);
    s->t = t;
    s->sign = s->factor_sign;
    s->iterations = count;
    s->residual = norm;
    s->condition = condition;
    s->started = 1;
    return KINEGEN_OK;
}

int kinegen_start(kinegen_solver *s, double t, const double *q0, const double *u, const double *ud, const double *udd) {
    int count, status;
    double travel, norm;
    if (s->role != NULL) return KINEGEN_MODEL;
    memcpy(s->trial, q0, sizeof(double) * (size_t)s->model->n_q);
    s->has_prev = 0;
    status = newton(s, u, 0, &count, &travel, &norm);
    if (status != KINEGEN_OK) {
        s->have_factors = 0;
        return status;
    }
    s->refinements = 0;
    return finish(s, t, u, ud, udd, count, norm, 0.0, 1);
}

/* One try at the step to t: predictor, Newton, certificate (last_try: no halving follows a refusal; whole: the
 * step kinegen_step was asked for, not a halved piece of it, whose predictor may take the third-order term). */
static int attempt(kinegen_solver *s, double t, const double *u, const double *ud, const double *udd, int *iterations,
                   int last_try, int whole) {
    const kinegen_model *m = s->model;
    int n = m->n_v, count, status;
    double travel, norm, h = t - s->t;
    memcpy(s->trial, s->q, sizeof(double) * (size_t)m->n_q);
    memset(s->moved, 0, sizeof(double) * (size_t)n);
    if (s->options.predictor) {
        for (int j = 0; j < n; ++j) s->moved[j] = s->v[j] * h + 0.5 * s->a[j] * h * h;
        if (whole && s->has_prev) /* the jerk from the last step's accelerations (Python: Solver._step, the same sums) */
            for (int j = 0; j < n; ++j) s->moved[j] += (s->a[j] - s->a_prev[j]) / s->h_prev * h * h * h / 6.0;
        m->retract(s->trial, s->moved);
    }
    status = newton(s, u, s->options.chord, &count, &travel, &norm);
    if (status != KINEGEN_OK) {
        s->have_factors = 0;
        return status;
    }
    status = finish(s, t, u, ud, udd, count, norm, h, last_try);
    if (status == KINEGEN_OK) s->iterations = *iterations += count; /* the accepted pieces' iterations, as Python counts */
    return status;
}

/* The inputs at tm within the step from t0 (inputs u0, ud0) to t1 (u1, ud1): the case's own time
 * functions, or the cubic Hermite interpolant of the values and rates at both ends. out: u, du/dt,
 * d2u/dt2 (3 n_inputs). */
static void inputs_at(const kinegen_solver *s, double tm, double t0, const double *u0, const double *ud0, double t1,
                      const double *u1, const double *ud1, double *out) {
    const kinegen_model *m = s->model;
    int ni = m->n_inputs;
    if (s->options.case_inputs && s->roles.inputs != NULL) {
        const double *x[1] = {&tm};
        double *y[1] = {out};
        s->roles.inputs->call(x, y);
        return;
    }
    double d = t1 - t0, r = (tm - t0) / d;
    for (int i = 0; i < ni; ++i) {
        double a = u0[i], m0 = d * ud0[i], m1 = d * ud1[i], b = u1[i];
        out[i] = (2 * r * r * r - 3 * r * r + 1) * a + (r * r * r - 2 * r * r + r) * m0 + (3 * r * r - 2 * r * r * r) * b +
                 (r * r * r - r * r) * m1;
        out[ni + i] = ((6 * r * r - 6 * r) * (a - b) + (3 * r * r - 4 * r + 1) * m0 + (3 * r * r - 2 * r) * m1) / d;
        out[2 * ni + i] = ((12 * r - 6) * (a - b) + (6 * r - 4) * m0 + (6 * r - 2) * m1) / (d * d);
    }
}

/* The step to t: tried whole, then halved while it cannot be certified, up to options.max_refinements
 * times (at most KINEGEN_MAX_REFINEMENTS), the halves taken in time order -- piece `piece` of 2^level
 * equal pieces of the step, its inputs from the case's time functions or from the cubic Hermite path of
 * the step's ends (inputs_at). A loop over the pieces, not a recursion: the solver's stack use is
 * bounded, its memory the workspace's (s->path: the step's start inputs, then a piece's inputs). */
static int advance(kinegen_solver *s, double t, const double *u, const double *ud, const double *udd, int *iterations) {
    const int ni = s->model->n_inputs;
    const int limit = s->options.max_refinements < 0                         ? 0
                      : s->options.max_refinements > KINEGEN_MAX_REFINEMENTS ? KINEGEN_MAX_REFINEMENTS
                                                                             : s->options.max_refinements;
    const double t0 = s->t;
    double *u0 = s->path, *ud0 = u0 + ni, *inputs = ud0 + ni;
    unsigned long long piece = 0;
    int level = 0;
    memcpy(u0, s->u, sizeof(double) * (size_t)ni);
    memcpy(ud0, s->ud, sizeof(double) * (size_t)ni);
    for (;;) {
        const unsigned long long pieces = 1ULL << level;
        const int last = piece + 1 == pieces;
        double end = t;
        const double *pu = u, *pud = ud, *pudd = udd;
        if (!last) { /* (the last piece ends at t with the caller's inputs, exactly) */
            end = t0 + (t - t0) * ((double)(piece + 1) / (double)pieces);
            inputs_at(s, end, t0, u0, ud0, t, u, ud, inputs);
            for (int i = 0; i < 3 * ni; ++i) {
                if (!isfinite(inputs[i])) {
                    s->branch_time = end;
                    return KINEGEN_INPUTS;
                }
            }
            pu = inputs, pud = inputs + ni, pudd = inputs + 2 * ni;
        }
        int status = attempt(s, end, pu, pud, pudd, iterations, level >= limit, level == 0);
        if (status == KINEGEN_OK) {
            if (last) return KINEGEN_OK;
            for (++piece; level > 0 && piece % 2 == 0; --level) piece /= 2; /* a second half done: its whole is */
            continue;
        }
        if (!s->options.keep_branch || level >= limit) {
            s->branch_time = s->t;
            return status;
        }
        ++s->refinements;
        ++level;
        piece *= 2;
    }
}

int kinegen_step(kinegen_solver *s, double t, const double *u, const double *ud, const double *udd) {
    int iterations = 0, status;
    double t0 = s->t;
    if (s->role != NULL) return KINEGEN_MODEL;
    if (!s->started) return KINEGEN_NOT_STARTED;
    s->refinements = 0;
    s->branch_block = -1;
    memcpy(s->a_start, s->a, sizeof(double) * (size_t)s->model->n_v);
    status = advance(s, t, u, ud, udd, &iterations);
    if (status == KINEGEN_OK) { /* the next step's third-order term (attempt) */
        double *swap = s->a_prev;
        s->a_prev = s->a_start;
        s->a_start = swap;
        s->h_prev = t - t0;
        s->has_prev = 1;
    } else {
        s->has_prev = 0;
    }
    return status;
}

double kinegen_table_mismatch(int n, double h, const double *u0, const double *ud0, const double *udd0, const double *u1,
                              const double *ud1, const double *udd1, int *input) {
    double worst = 0.0;
    *input = -1;
    for (int k = 0; k < n; ++k) {
        double change = u1[k] - u0[k];
        double start = (6.0 * change - h * (4.0 * ud0[k] + 2.0 * ud1[k])) / (h * h); /* the cubic path's d2u/dt2 at both ends */
        double end = (-6.0 * change + h * (2.0 * ud0[k] + 4.0 * ud1[k])) / (h * h);
        double scale = fabs(change) + h * (fabs(ud0[k]) + fabs(ud1[k])) / 2.0 + h * h * (fabs(udd0[k]) + fabs(udd1[k])) / 4.0 +
                       1e-12 * (1.0 + fabs(u0[k]));
        double ratio = h * h * fmax(fabs(start - udd0[k]), fabs(end - udd1[k])) / scale;
        if (!(ratio <= worst)) {
            worst = ratio;
            *input = k;
        }
    }
    return worst;
}

int kinegen_resume(kinegen_solver *s, double t, const double *q, const double *v, const double *a, const double *u,
                   const double *ud, const double *a_prev, double h_prev) {
    const kinegen_model *m = s->model;
    if (s->role != NULL) return KINEGEN_MODEL;
    s->has_prev = a_prev != NULL && h_prev > 0.0;
    if (s->has_prev) {
        memcpy(s->a_prev, a_prev, sizeof(double) * (size_t)m->n_v);
        s->h_prev = h_prev;
    }
    memcpy(s->q, q, sizeof(double) * (size_t)m->n_q);
    memcpy(s->v, v, sizeof(double) * (size_t)m->n_v);
    memcpy(s->a, a, sizeof(double) * (size_t)m->n_v);
    memcpy(s->u, u, sizeof(double) * (size_t)m->n_inputs);
    memcpy(s->ud, ud, sizeof(double) * (size_t)m->n_inputs);
    s->t = t;
    phi_jac(s, s->q, u, s->phi, s->jac);
    if (factor(s, s->jac)) return KINEGEN_SINGULAR;
    memcpy(s->jac_q, s->jac, sizeof(double) * (size_t)m->n_jac);
    memcpy(s->block_sign, s->factor_block_sign, sizeof(int) * (size_t)m->n_blocks);
    s->sign = s->factor_sign;
    s->started = 1;
    return KINEGEN_OK;
}

int kinegen_trajectory(kinegen_solver *s, int count, const double *times, const double *U, const double *UD,
                       const double *UDD, double *Q, double *V, double *A, int *iterations, double *residuals,
                       double *conditions, int *status) {
    const kinegen_model *m = s->model;
    int ni = m->n_inputs, nq = m->n_q, nv = m->n_v;
    *status = KINEGEN_OK;
    for (int i = 0; i < count; ++i) {
        const double *u = U + (size_t)i * ni, *ud = UD + (size_t)i * ni, *udd = UDD + (size_t)i * ni;
        *status = s->started ? kinegen_step(s, times[i], u, ud, udd) : kinegen_start(s, times[i], m->initial_q, u, ud, udd);
        if (*status != KINEGEN_OK) return i;
        memcpy(Q + (size_t)i * nq, s->q, sizeof(double) * (size_t)nq);
        memcpy(V + (size_t)i * nv, s->v, sizeof(double) * (size_t)nv);
        memcpy(A + (size_t)i * nv, s->a, sizeof(double) * (size_t)nv);
        iterations[i] = s->iterations;
        residuals[i] = s->residual;
        conditions[i] = s->condition;
    }
    return count;
}

int kinegen_solve_batch(kinegen_solver *s, int count, const double *U, double *Q, int *converged, int *iterations,
                        double *residuals) {
    const kinegen_model *m = s->model;
    int ni = m->n_inputs, nq = m->n_q, solved = 0;
    if (s->role != NULL) return 0;
    s->have_factors = 0; /* with chord iterations, each configuration starts from the last one's factors */
    for (int k = 0; k < count; ++k) {
        int n_iterations;
        double travel, norm;
        memcpy(s->trial, Q + (size_t)k * nq, sizeof(double) * (size_t)nq);
        int status = newton(s, U + (size_t)k * ni, s->options.chord, &n_iterations, &travel, &norm);
        converged[k] = status == KINEGEN_OK;
        iterations[k] = n_iterations;
        residuals[k] = norm;
        solved += converged[k];
        memcpy(Q + (size_t)k * nq, s->trial, sizeof(double) * (size_t)nq);
    }
    s->have_factors = 0;
    return solved;
}

int kinegen_newton(kinegen_solver *s, double *q, const double *u, int *iterations, double *residual, double *travel) {
    if (s->role != NULL) return KINEGEN_MODEL;
    memcpy(s->trial, q, sizeof(double) * (size_t)s->model->n_q);
    int status = newton(s, u, 0, iterations, travel, residual);
    memcpy(q, s->trial, sizeof(double) * (size_t)s->model->n_q);
    s->have_factors = 0;
    return status;
}

int kinegen_input_effects(kinegen_solver *s, int count, const double *Q, const double *U, double *DQDU) {
    const kinegen_model *m = s->model;
    int nq = m->n_q, nv = m->n_v, ni = m->n_inputs, regular = 0;
    double *ones = s->x, *column = s->step; /* n_inputs <= n_v values; a column of Phi_q^-1 Phi_u */
    if (s->role != NULL) return 0;
    for (int j = 0; j < ni; ++j) ones[j] = 1.0;
    for (int k = 0; k < count; ++k) {
        const double *q = Q + (size_t)k * nq, *u = U + (size_t)k * ni;
        double *out = DQDU + (size_t)k * nv * ni;
        phi_jac(s, q, u, s->phi, s->jac);
        if (factor(s, s->jac)) {
            for (int i = 0; i < nv * ni; ++i) out[i] = NAN;
            continue;
        }
        nu(s, q, u, ones, s->w2); /* -Phi_u 1: -dPhi/du_j in driver j's row, n_v - n_inputs + j (kinegen_model) */
        for (int j = 0; j < ni; ++j) {
            int row = nv - ni + j;
            memset(column, 0, sizeof(double) * (size_t)nv);
            column[row] = s->w2[row];
            if (m->solve_from != NULL && m->input_pieces != NULL) /* from its driver's part of the solve */
                m->solve_from(s->store, s->off, s->perms, column, column, s->y, m->input_pieces[j]);
            else
                solve(s, column, column);
            for (int i = 0; i < nv; ++i) out[(size_t)i * ni + j] = column[i];
        }
        ++regular;
    }
    s->have_factors = 0;
    return regular;
}

/* The sensitivities' row operations over n values (a row of their n_p columns): r *= f, r = f x and
 * r += f x (r and x never overlap; r -= f x is r += (-f) x, the same bits), four values a statement: the
 * compiler makes vector instructions of those at -O2, where it leaves a loop over a variable n one value an
 * instruction. The same operations on each value: the same bits. */
static inline void rows_scale(double *r, double f, int n) {
    int j = 0;
    for (; j + 4 <= n; j += 4) {
        r[j] *= f;
        r[j + 1] *= f;
        r[j + 2] *= f;
        r[j + 3] *= f;
    }
    for (; j < n; ++j) r[j] *= f;
}

/* r = f x (f = -1: the negation, exactly) */
static inline void rows_scale_into(double *restrict r, double f, const double *restrict x, int n) {
    int j = 0;
    for (; j + 4 <= n; j += 4) {
        r[j] = f * x[j];
        r[j + 1] = f * x[j + 1];
        r[j + 2] = f * x[j + 2];
        r[j + 3] = f * x[j + 3];
    }
    for (; j < n; ++j) r[j] = f * x[j];
}

static inline void rows_plus(double *restrict r, double f, const double *restrict x, int n) {
    int j = 0;
    for (; j + 4 <= n; j += 4) {
        r[j] += f * x[j];
        r[j + 1] += f * x[j + 1];
        r[j + 2] += f * x[j + 2];
        r[j + 3] += f * x[j + 3];
    }
    for (; j < n; ++j) r[j] += f * x[j];
}

/* rhs (n_v x n_p, row-major) = the sparse matrix (values at pattern) times [X1; X2; I] (each n_v x
 * n_p): columns below n_v multiply rows of X1, the next n_v rows of X2, and the columns from
 * first_parameter on are the parameters' (identity). */
static void sparse_times(const kinegen_pattern *pattern, const double *values, const double *X1, const double *X2, int nv,
                         int np, int first_parameter, double *rhs) {
    memset(rhs, 0, sizeof(double) * (size_t)nv * (size_t)np);
    for (int e = 0; e < pattern->n; ++e) {
        int c = pattern->cols[e];
        double value = values[e], *row = rhs + (size_t)pattern->rows[e] * np;
        if (c >= first_parameter) {
            row[c - first_parameter] += value;
        } else {
            const double *x = c < nv ? X1 + (size_t)c * np : X2 + (size_t)(c - nv) * np;
            rows_plus(row, value, x, np);
        }
    }
}

/* out = -Phi_q^-1 rhs for n_p right-hand sides at once (rhs, out: n_v x n_p, row-major; y: n_v x n_p
 * of work), with the current factors: solve() on rows of n_p values. */
static void solve_negated(kinegen_solver *s, const double *rhs, int np, double *y, double *out) {
    const kinegen_model *m = s->model;
    for (int blk = 0; blk < m->n_blocks; ++blk) {
        int first = m->block_start[blk], n = m->block_start[blk + 1] - first;
        const double *A = s->store + m->block_store[blk];
        const int *piv = s->pivots + first;
        double *r = y + (size_t)first * np;
        for (int i = 0; i < n; ++i) {
            int row = first + i;
            double *ri = r + (size_t)i * np;
            memcpy(ri, rhs + (size_t)m->row_order[row] * np, sizeof(double) * (size_t)np);
            for (int e = m->off_start[row]; e < m->off_start[row + 1]; ++e) {
                double f = s->off[e];
                rows_plus(ri, -f, y + (size_t)m->off_col[e] * np, np);
            }
        }
        for (int k = 0; k < n; ++k) {
            if (piv[k] != k) {
                double *a = r + (size_t)k * np, *b = r + (size_t)piv[k] * np;
                for (int j = 0; j < np; ++j) {
                    double tmp = a[j];
                    a[j] = b[j];
                    b[j] = tmp;
                }
            }
        }
        for (int k = 0; k < n; ++k)
            for (int i = k + 1; i < n; ++i) {
                double f = A[i + k * n];
                if (f != 0.0) rows_plus(r + (size_t)i * np, -f, r + (size_t)k * np, np);
            }
        for (int k = n - 1; k >= 0; --k) {
            double inverse = 1.0 / A[k + k * n];
            rows_scale(r + (size_t)k * np, inverse, np);
            for (int i = 0; i < k; ++i) {
                double f = A[i + k * n];
                if (f != 0.0) rows_plus(r + (size_t)i * np, -f, r + (size_t)k * np, np);
            }
        }
    }
    for (int c = 0; c < m->n_v; ++c) {
        const double *from = y + (size_t)c * np;
        double *to = out + (size_t)m->col_order[c] * np;
        rows_scale_into(to, -1.0, from, np);
    }
}

int kinegen_sensitivities(kinegen_solver *s, int count, const double *Q, const double *V, const double *A, const double *U,
                          const double *UD, const double *UDD, double *S, double *DV, double *DA, double *work) {
    const kinegen_design *d = s->model->design;
    const kinegen_roles *r = &s->roles;
    if (d == NULL || r->dvel == NULL || s->role != NULL) return -1;
    const kinegen_model *m = s->model;
    int nq = m->n_q, nv = m->n_v, ni = m->n_inputs, np = d->n_design;
    size_t block = (size_t)nv * (size_t)np;
    double *rhs = work, *y = work + block, *values = work + 2 * block;
    for (int k = 0; k < count; ++k) {
        const double *q = Q + (size_t)k * nq, *v = V + (size_t)k * nv, *a = A + (size_t)k * nv;
        const double *u = U + (size_t)k * ni, *ud = UD + (size_t)k * ni, *udd = UDD + (size_t)k * ni;
        double *sk = S + (size_t)k * block, *vk = DV + (size_t)k * block, *ak = DA + (size_t)k * block;
        phi_jac(s, q, u, s->phi, s->jac);
        if (factor(s, s->jac)) {
            for (size_t i = 0; i < block; ++i) sk[i] = vk[i] = ak[i] = NAN;
            continue;
        }
        const double *x[7] = {q, v, a, u, ud, udd, s->design};
        double *y1[1] = {values};
        const double *phi_p_x[3] = {q, u, s->design}, *dvel_x[5] = {q, v, u, ud, s->design};
        r->phi_p->call(phi_p_x, y1);
        sparse_times(&d->phi_p_pattern, values, NULL, NULL, nv, np, 0, rhs);
        solve_negated(s, rhs, np, y, sk);
        r->dvel->call(dvel_x, y1);
        sparse_times(&d->dvel_pattern, values, sk, NULL, nv, np, nv, rhs);
        solve_negated(s, rhs, np, y, vk);
        r->dacc->call(x, y1);
        sparse_times(&d->dacc_pattern, values, sk, vk, nv, np, 2 * nv, rhs);
        solve_negated(s, rhs, np, y, ak);
    }
    s->have_factors = 0;
    return count;
}

/* ---- forces (kinegen_statics) ---- */

/* Q (n_v) of the weighted loads at (q, t); values: room for the loads kernel's output. */
static void load_vector(const kinegen_solver *s, const kinegen_statics *st, const double *q, double t, const double *weights,
                        double *values, double *Q) {
    memset(Q, 0, sizeof(double) * (size_t)s->model->n_v);
    if (s->roles.loads == NULL) return;
    const double *x[3] = {q, &t, s->design}; /* slots q, t[, p] */
    double *y[1] = {values};
    s->roles.loads->call(x, y);
    for (int e = 0; e < st->load_pattern.n; ++e) {
        int load = st->load_pattern.rows[e];
        Q[st->load_pattern.cols[e]] += (weights != NULL ? weights[load] : 1.0) * values[e];
    }
}

int kinegen_forces(kinegen_solver *s, int count, const double *times, const double *Q, const double *V, const double *A,
                   const double *U, const double *weights, double inertia, double *LAMBDA, double *F, double *work, int *iwork) {
    const kinegen_model *m = s->model;
    const kinegen_statics *st = m->layout->statics;
    if (st == NULL || s->role != NULL || (inertia != 0.0 && (s->roles.inertia == NULL || V == NULL || A == NULL))) return -1;
    int nq = m->n_q, nv = m->n_v, ni = m->n_inputs, ne = st->n_elements, solved = 0;
    int nf = ne > 0 ? ne : ni, first = nv - nf; /* the rows of the elements (drivers) come last */
    double *inertia_values = work, *load_values = inertia_values + st->n_inertia;
    double *rhs = load_values + (st->load_pattern.n > 0 ? st->load_pattern.n : 1), *w = rhs + nv;
    double *values = w + nv, *store = values + st->pattern.n, *off = store + st->n_store; /* with elements */
    double *ud = values, *rate = ud + ni;                                                  /* without */
    plan_view plan = {nv, st->n_blocks, st->block_start, st->block_store, st->row_order, st->col_order, st->n_store, st->n_diag,
                      st->diag_value, st->diag_slot, st->n_off, st->off_start, st->off_col, st->off_value};
    for (int k = 0; k < count; ++k) {
        const double *q = Q + (size_t)k * nq, *u = U + (size_t)k * ni;
        double *lambda = LAMBDA + (size_t)k * nv, *f = F + (size_t)k * nf;
        int singular;
        load_vector(s, st, q, times[k], weights, load_values, rhs);
        if (inertia != 0.0) {
            const double *x[4] = {q, V + (size_t)k * nv, A + (size_t)k * nv, s->design}; /* slots q, v, a[, p] */
            double *y[1] = {inertia_values};
            s->roles.inertia->call(x, y);
            for (int e = 0; e < st->n_inertia; ++e) rhs[st->inertia_cols[e]] += inertia * inertia_values[e];
        }
        if (ne > 0) {
            const double *x[2] = {q, s->design}; /* slots q[, p] */
            double *y[1] = {values};
            double low = INFINITY, high = 0.0;
            int odd = 0;
            s->roles.actuation->call(x, y);
            singular = factor_blocks(&plan, values, store, off, iwork, NULL, &low, &high, &odd) ||
                       !(low > s->options.singular_tolerance * fmax(high, 1e-300));
            if (!singular) solve_transposed_blocks(&plan, store, off, iwork, w, rhs, lambda);
            for (int j = 0; j < nf && !singular; ++j) f[j] = -lambda[first + j];
        } else {
            phi_jac(s, q, u, s->phi, s->jac);
            singular = factor(s, s->jac);
            if (!singular) solve_transposed(s, rhs, lambda);
            for (int j = 0; j < nf && !singular; ++j) { /* dPhi_j/du_j = -nu_j at a unit rate of input j */
                for (int i = 0; i < ni; ++i) ud[i] = i == j ? 1.0 : 0.0;
                nu(s, q, u, ud, rate);
                f[j] = -lambda[first + j] * rate[first + j];
            }
        }
        if (singular) {
            for (int i = 0; i < nv; ++i) lambda[i] = NAN;
            for (int j = 0; j < nf; ++j) f[j] = NAN;
        } else {
            ++solved;
        }
    }
    if (ne == 0) s->have_factors = 0; /* the case's Phi_q was factorized in the solver's store */
    return solved;
}

/* The largest square map of one body in kinegen_reactions: its velocity coordinates (6 for Euler angles,
 * 7 with a normalization row, 8 for a dual quaternion's). */
#define KINEGEN_MAX_BODY_COORDINATES 8

/* Solves a^T x = b for x, a an n x n row-major matrix (n <= KINEGEN_MAX_BODY_COORDINATES, overwritten
 * with the factors): read column-major, a is a^T, which lu_block factorizes in place; then the
 * substitutions of solve(). 1 if it is singular (a zero or non-finite pivot) or too large. */
static int small_solve_transposed(int n, double *a, const double *b, double *x) {
    int piv[KINEGEN_MAX_BODY_COORDINATES], odd = 0;
    double low = INFINITY, high = 0.0;
    if (n < 1 || n > KINEGEN_MAX_BODY_COORDINATES || lu_block(a, piv, n, &low, &high, &odd)) return 1;
    for (int i = 0; i < n; ++i) x[i] = b[i];
    for (int k = 0; k < n; ++k) {
        if (piv[k] != k) {
            double tmp = x[k];
            x[k] = x[piv[k]];
            x[piv[k]] = tmp;
        }
    }
    for (int k = 0; k < n; ++k)
        for (int i = k + 1; i < n; ++i) x[i] -= a[i + k * n] * x[k];
    for (int k = n - 1; k >= 0; --k) {
        x[k] /= a[k + k * n];
        for (int i = 0; i < k; ++i) x[i] -= a[i + k * n] * x[k];
    }
    return 0;
}

/* The frames kernel (by role) at q, v, a: KINEGEN_FRAME_VALUES per body into out. */
static void frames_at(const kinegen_solver *s, const double *q, const double *v, const double *a, double *out) {
    const double *x[3] = {q, v, a};
    double *y[1] = {out};
    s->roles.frames->call(x, y);
}

int kinegen_reactions(kinegen_solver *s, const double *q, const double *u, const double *lambda, double *out, double *work, int *iwork) {
    const kinegen_model *m = s->model;
    const kinegen_layout *l = m->layout;
    const kinegen_statics *st = l->statics;
    if (st == NULL || l->n_bodies == 0 || s->role != NULL) return -1;
    int nv = m->n_v, nb = l->n_bodies, nvb = nv / nb, n;
    if (nv % nb != 0 || nvb > KINEGEN_MAX_BODY_COORDINATES) return -1; /* (every parametrization's bodies fit) */
    double *frames = work, *unit = frames + KINEGEN_FRAME_VALUES * nb, *zero = unit + nv, *tangent = zero + nv;
    double *g = tangent + (size_t)6 * nvb * nb, *square = g + nvb, *w = square + nvb * nvb, *values = w + nvb, *phi = values;
    const int *rows, *cols;
    if (st->n_elements > 0) { /* the joint rows' values lead the force matrix's */
        const double *x[2] = {q, s->design};
        double *y[1] = {values};
        s->roles.actuation->call(x, y);
        rows = st->pattern.rows, cols = st->pattern.cols, n = st->pattern.n;
    } else { /* the case's Phi_q (its joint rows are the first) */
        double *jac = phi + nv;
        phi_jac(s, q, u, phi, jac);
        values = jac, rows = m->jac_rows, cols = m->jac_cols, n = m->n_jac;
    }
    for (int i = 0; i < st->n_joint_rows; ++i) iwork[i] = -1; /* each joint row's joint */
    for (int j = 0; j < st->n_joints; ++j)
        for (int k = st->joint_row_start[j]; k < st->joint_row_start[j + 1]; ++k) iwork[st->joint_rows[k]] = j;
    memset(zero, 0, sizeof(double) * (size_t)nv);
    for (int k = 0; k < nvb; ++k) { /* the tangent maps: column k of every body's T_v and T_w at once */
        for (int i = 0; i < nv; ++i) unit[i] = i % nvb == k ? 1.0 : 0.0;
        frames_at(s, q, unit, zero, frames);
        for (int b = 0; b < nb; ++b)
            for (int i = 0; i < 3; ++i) {
                tangent[((size_t)b * 6 + i) * nvb + k] = frames[KINEGEN_FRAME_VALUES * b + KINEGEN_FRAME_VELOCITY + i];
                tangent[((size_t)b * 6 + 3 + i) * nvb + k] = frames[KINEGEN_FRAME_VALUES * b + KINEGEN_FRAME_ANGULAR_VELOCITY + i];
            }
    }
    frames_at(s, q, zero, zero, frames); /* the poses */
    for (int j = 0; j < st->n_joints; ++j) {
        int b = st->joint_body[j], first = b * nvb;
        double *r = out + (size_t)6 * j;
        memset(g, 0, sizeof(double) * (size_t)nvb);
        memcpy(square, tangent + (size_t)b * 6 * nvb, sizeof(double) * (size_t)(6 * nvb));
        for (int e = 0; e < n; ++e) {
            int row = rows[e], c = cols[e] - first;
            if (row >= st->n_joint_rows || c < 0 || c >= nvb) continue;
            if (iwork[row] == j) g[c] -= lambda[row] * values[e];
            for (int k = st->body_norm_start[b]; k < st->body_norm_start[b + 1]; ++k)
                if (st->body_norm_rows[k] == row) square[(6 + k - st->body_norm_start[b]) * nvb + c] = values[e];
        }
        if (small_solve_transposed(nvb, square, g, w)) {
            for (int i = 0; i < 6; ++i) r[i] = NAN;
            continue;
        }
        double sign = st->joint_sign[j], point[3], velocity[3], acceleration[3];
        const double *local = st->joint_local + 3 * j, *origin = frames + KINEGEN_FRAME_VALUES * b + KINEGEN_FRAME_ORIGIN;
        if (st->joint_point_body[j] < 0) {
            for (int i = 0; i < 3; ++i) point[i] = local[i];
        } else {
            kinegen_point_kinematics(frames + KINEGEN_FRAME_VALUES * st->joint_point_body[j], local, point, velocity, acceleration);
        }
        double arm[3] = {point[0] - origin[0], point[1] - origin[1], point[2] - origin[2]};
        double f[3] = {sign * w[0], sign * w[1], sign * w[2]};
        r[0] = f[0], r[1] = f[1], r[2] = f[2]; /* the moment about the point: M_O - arm x F */
        r[3] = sign * w[3] - (arm[1] * f[2] - arm[2] * f[1]);
        r[4] = sign * w[4] - (arm[2] * f[0] - arm[0] * f[2]);
        r[5] = sign * w[5] - (arm[0] * f[1] - arm[1] * f[0]);
    }
    return st->n_joints;
}

const char *kinegen_status_text(int status) {
    switch (status) {
    case KINEGEN_OK:
        return "ok";
    case KINEGEN_NOT_CONVERGED:
        return "Newton-Raphson did not converge";
    case KINEGEN_SINGULAR:
        return "singular Jacobian";
    case KINEGEN_BRANCH:
        return "the step could not be certified to continue the last solution, even halved (a block's assembly mode "
               "flips: a singular pose lies within the step; or the inputs change too fast for the step)";
    case KINEGEN_NOT_STARTED:
        return "no initial pose solved yet (kinegen_start)";
    case KINEGEN_INPUTS:
        return "the driver inputs are not finite inside the step (a time function leaves its domain between two time points)";
    case KINEGEN_MODEL:
        return "the model's kernel tables lack a kernel the solver calls, or declare it with other slots or sizes "
               "(kinegen_init: the solver's role names it)";
    default:
        return "unknown status";
    }
}

void kinegen_quaternion_from_matrix(const double *r, double *q) {
    /* the largest of w^2, x^2, y^2, z^2 from the diagonal, the others from off-diagonal sums */
    double trace = r[0] + r[4] + r[8];
    double candidates[4] = {trace, r[0], r[4], r[8]};
    int k = 0;
    for (int i = 1; i < 4; ++i)
        if (candidates[i] > candidates[k]) k = i;
    double d = 1.0 + 2.0 * candidates[k] - trace;
    double wx = r[7] - r[5], wy = r[2] - r[6], wz = r[3] - r[1];
    double xy = r[1] + r[3], xz = r[2] + r[6], yz = r[5] + r[7];
    double rows[4][4] = {{d, wx, wy, wz}, {wx, d, xy, xz}, {wy, xy, d, yz}, {wz, xz, yz, d}};
    double norm = sqrt(rows[k][0] * rows[k][0] + rows[k][1] * rows[k][1] + rows[k][2] * rows[k][2] + rows[k][3] * rows[k][3]);
    double sign = rows[k][0] < 0.0 ? -1.0 : 1.0;
    for (int i = 0; i < 4; ++i) q[i] = sign * rows[k][i] / norm;
}

void kinegen_point_kinematics(const double *f, const double *s, double *p, double *v, double *a) {
    /* f: one body's frame values (enum kinegen_frame) */
    const double *A = f + KINEGEN_FRAME_ROTATION, *w = f + KINEGEN_FRAME_ANGULAR_VELOCITY, *wd = f + KINEGEN_FRAME_ANGULAR_ACCELERATION;
    double arm[3];
    for (int i = 0; i < 3; ++i) arm[i] = A[3 * i] * s[0] + A[1 + 3 * i] * s[1] + A[2 + 3 * i] * s[2];
    double wa[3] = {w[1] * arm[2] - w[2] * arm[1], w[2] * arm[0] - w[0] * arm[2], w[0] * arm[1] - w[1] * arm[0]};
    double wwa[3] = {w[1] * wa[2] - w[2] * wa[1], w[2] * wa[0] - w[0] * wa[2], w[0] * wa[1] - w[1] * wa[0]};
    double wda[3] = {wd[1] * arm[2] - wd[2] * arm[1], wd[2] * arm[0] - wd[0] * arm[2], wd[0] * arm[1] - wd[1] * arm[0]};
    for (int i = 0; i < 3; ++i) {
        p[i] = f[KINEGEN_FRAME_ORIGIN + i] + arm[i];
        v[i] = f[KINEGEN_FRAME_VELOCITY + i] + wa[i];
        a[i] = f[KINEGEN_FRAME_ACCELERATION + i] + wda[i] + wwa[i];
    }
}


/* ---- self-description (kinegen_solver.h: kinegen_fields) ---- */

#define FIELD(structure, field, type) {#structure, #field, type, (int)offsetof(structure, field), (int)sizeof(((structure *)0)->field)}

const kinegen_field kinegen_fields[] = {
    FIELD(kinegen_options, tolerance, "double"), FIELD(kinegen_options, singular_tolerance, "double"),
    FIELD(kinegen_options, divergence_limit, "double"), FIELD(kinegen_options, chord_rate, "double"),
    FIELD(kinegen_options, safety, "double"), FIELD(kinegen_options, max_iterations, "int"),
    FIELD(kinegen_options, predictor, "int"), FIELD(kinegen_options, chord, "int"), FIELD(kinegen_options, polish, "int"),
    FIELD(kinegen_options, keep_branch, "int"), FIELD(kinegen_options, condition, "int"),
    FIELD(kinegen_options, max_refinements, "int"), FIELD(kinegen_options, case_inputs, "int"),

    FIELD(kinegen_kernel, name, "char*"), FIELD(kinegen_kernel, slots, "char*"), FIELD(kinegen_kernel, n_outputs, "int"),
    FIELD(kinegen_kernel, output_names, "pointer"), FIELD(kinegen_kernel, output_sizes, "int*"),
    FIELD(kinegen_kernel, call, "function"),

    FIELD(kinegen_point, body, "int"), FIELD(kinegen_point, name, "char*"), FIELD(kinegen_point, local, "double"),

    FIELD(kinegen_actuator, name, "char*"), FIELD(kinegen_actuator, point1, "int"), FIELD(kinegen_actuator, point2, "int"),
    FIELD(kinegen_actuator, has_range, "int"), FIELD(kinegen_actuator, min, "double"), FIELD(kinegen_actuator, max, "double"),

    FIELD(kinegen_layout, model, "char*"), FIELD(kinegen_layout, parametrization, "char*"), FIELD(kinegen_layout, source, "char*"),
    FIELD(kinegen_layout, source_sha256, "char*"), FIELD(kinegen_layout, kinegen_version, "char*"),
    FIELD(kinegen_layout, n_q, "int"), FIELD(kinegen_layout, n_v, "int"), FIELD(kinegen_layout, n_bodies, "int"),
    FIELD(kinegen_layout, body_names, "pointer"), FIELD(kinegen_layout, stored_names, "pointer"),
    FIELD(kinegen_layout, velocity_names, "pointer"), FIELD(kinegen_layout, n_points, "int"),
    FIELD(kinegen_layout, points, "pointer"), FIELD(kinegen_layout, n_actuators, "int"), FIELD(kinegen_layout, actuators, "pointer"),
    FIELD(kinegen_layout, n_kernels, "int"), FIELD(kinegen_layout, kernels, "pointer"),
    FIELD(kinegen_layout, statics, "pointer"),

    FIELD(kinegen_statics, n_elements, "int"), FIELD(kinegen_statics, element_names, "pointer"),
    FIELD(kinegen_statics, element_kinds, "pointer"), FIELD(kinegen_statics, n_joint_rows, "int"),
    FIELD(kinegen_statics, pattern, "kinegen_pattern"),
    FIELD(kinegen_statics, n_loads, "int"), FIELD(kinegen_statics, load_names, "pointer"),
    FIELD(kinegen_statics, load_pattern, "kinegen_pattern"),
    FIELD(kinegen_statics, n_inertia, "int"), FIELD(kinegen_statics, inertia_cols, "int*"),
    FIELD(kinegen_statics, n_blocks, "int"), FIELD(kinegen_statics, block_start, "int*"), FIELD(kinegen_statics, block_store, "int*"),
    FIELD(kinegen_statics, row_order, "int*"), FIELD(kinegen_statics, col_order, "int*"), FIELD(kinegen_statics, n_store, "int"),
    FIELD(kinegen_statics, n_diag, "int"), FIELD(kinegen_statics, diag_value, "int*"), FIELD(kinegen_statics, diag_slot, "int*"),
    FIELD(kinegen_statics, n_off, "int"), FIELD(kinegen_statics, off_start, "int*"), FIELD(kinegen_statics, off_col, "int*"),
    FIELD(kinegen_statics, off_value, "int*"), FIELD(kinegen_statics, work_doubles, "int"), FIELD(kinegen_statics, work_ints, "int"),
    FIELD(kinegen_statics, n_joints, "int"), FIELD(kinegen_statics, joint_names, "pointer"), FIELD(kinegen_statics, joint_body, "int*"),
    FIELD(kinegen_statics, joint_sign, "int*"), FIELD(kinegen_statics, joint_point_body, "int*"),
    FIELD(kinegen_statics, joint_local, "double*"), FIELD(kinegen_statics, joint_row_start, "int*"),
    FIELD(kinegen_statics, joint_rows, "int*"), FIELD(kinegen_statics, body_norm_start, "int*"),
    FIELD(kinegen_statics, body_norm_rows, "int*"), FIELD(kinegen_statics, element_hydraulics, "double*"),
    FIELD(kinegen_statics, reaction_doubles, "int"), FIELD(kinegen_statics, reaction_ints, "int"),

    FIELD(kinegen_model, layout, "pointer"), FIELD(kinegen_model, case_name, "char*"), FIELD(kinegen_model, n_q, "int"),
    FIELD(kinegen_model, n_v, "int"), FIELD(kinegen_model, n_inputs, "int"), FIELD(kinegen_model, n_jac, "int"),
    FIELD(kinegen_model, t0, "double"), FIELD(kinegen_model, t1, "double"), FIELD(kinegen_model, steps, "int"),
    FIELD(kinegen_model, initial_q, "double*"), FIELD(kinegen_model, constraint_names, "pointer"),
    FIELD(kinegen_model, driver_names, "pointer"), FIELD(kinegen_model, jac_rows, "int*"), FIELD(kinegen_model, jac_cols, "int*"),
    FIELD(kinegen_model, retract, "function"), FIELD(kinegen_model, n_blocks, "int"),
    FIELD(kinegen_model, block_start, "int*"), FIELD(kinegen_model, block_store, "int*"), FIELD(kinegen_model, row_order, "int*"),
    FIELD(kinegen_model, col_order, "int*"), FIELD(kinegen_model, n_store, "int"), FIELD(kinegen_model, n_diag, "int"),
    FIELD(kinegen_model, diag_value, "int*"), FIELD(kinegen_model, diag_slot, "int*"), FIELD(kinegen_model, n_off, "int"),
    FIELD(kinegen_model, off_start, "int*"), FIELD(kinegen_model, off_col, "int*"), FIELD(kinegen_model, off_value, "int*"),
    FIELD(kinegen_model, solve, "function"), FIELD(kinegen_model, solve_transposed, "function"),
    FIELD(kinegen_model, solve_from, "function"), FIELD(kinegen_model, input_pieces, "int*"),
    FIELD(kinegen_model, work_doubles, "int"), FIELD(kinegen_model, work_ints, "int"), FIELD(kinegen_model, n_kernels, "int"),
    FIELD(kinegen_model, kernels, "pointer"), FIELD(kinegen_model, design, "pointer"),

    FIELD(kinegen_pattern, n, "int"), FIELD(kinegen_pattern, rows, "int*"), FIELD(kinegen_pattern, cols, "int*"),

    FIELD(kinegen_design, n_design, "int"), FIELD(kinegen_design, nominal, "double*"),
    FIELD(kinegen_design, phi_p_pattern, "kinegen_pattern"), FIELD(kinegen_design, dvel_pattern, "kinegen_pattern"),
    FIELD(kinegen_design, dacc_pattern, "kinegen_pattern"), FIELD(kinegen_design, sensitivity_doubles, "int"),

    FIELD(kinegen_roles, phi_jac, "pointer"), FIELD(kinegen_roles, nu, "pointer"), FIELD(kinegen_roles, gamma, "pointer"),
    FIELD(kinegen_roles, inputs, "pointer"), FIELD(kinegen_roles, input_ranges, "pointer"), FIELD(kinegen_roles, phi_p, "pointer"),
    FIELD(kinegen_roles, dvel, "pointer"), FIELD(kinegen_roles, dacc, "pointer"), FIELD(kinegen_roles, frames, "pointer"),
    FIELD(kinegen_roles, actuation, "pointer"), FIELD(kinegen_roles, loads, "pointer"), FIELD(kinegen_roles, inertia, "pointer"),

    FIELD(kinegen_solver, model, "pointer"), FIELD(kinegen_solver, options, "kinegen_options"), FIELD(kinegen_solver, t, "double"),
    FIELD(kinegen_solver, q, "double*"), FIELD(kinegen_solver, v, "double*"), FIELD(kinegen_solver, a, "double*"),
    FIELD(kinegen_solver, started, "int"), FIELD(kinegen_solver, iterations, "int"), FIELD(kinegen_solver, residual, "double"),
    FIELD(kinegen_solver, condition, "double"), FIELD(kinegen_solver, sign, "int"), FIELD(kinegen_solver, have_factors, "int"),
    FIELD(kinegen_solver, factor_sign, "int"), FIELD(kinegen_solver, trial, "double*"), FIELD(kinegen_solver, phi, "double*"),
    FIELD(kinegen_solver, jac, "double*"), FIELD(kinegen_solver, store, "double*"), FIELD(kinegen_solver, off, "double*"),
    FIELD(kinegen_solver, rhs, "double*"), FIELD(kinegen_solver, step, "double*"), FIELD(kinegen_solver, y, "double*"),
    FIELD(kinegen_solver, x, "double*"), FIELD(kinegen_solver, pivots, "int*"), FIELD(kinegen_solver, perms, "int*"), FIELD(kinegen_solver, design, "double*"),
    FIELD(kinegen_solver, u, "double*"), FIELD(kinegen_solver, ud, "double*"), FIELD(kinegen_solver, jac_q, "double*"),
    FIELD(kinegen_solver, moved, "double*"), FIELD(kinegen_solver, w1, "double*"), FIELD(kinegen_solver, w2, "double*"),
    FIELD(kinegen_solver, block_sign, "int*"), FIELD(kinegen_solver, factor_block_sign, "int*"),
    FIELD(kinegen_solver, refinements, "int"), FIELD(kinegen_solver, branch_block, "int"), FIELD(kinegen_solver, bound, "double"),
    FIELD(kinegen_solver, branch_time, "double"), FIELD(kinegen_solver, cert, "double*"), FIELD(kinegen_solver, branch_input, "int"),
    FIELD(kinegen_solver, moving, "int*"), FIELD(kinegen_solver, turning, "int*"), FIELD(kinegen_solver, n_turning, "int"),
    FIELD(kinegen_solver, path, "double*"), FIELD(kinegen_solver, bound_store, "double*"),
    FIELD(kinegen_solver, bound_off, "double*"), FIELD(kinegen_solver, have_bound, "int"),
    FIELD(kinegen_solver, a_start, "double*"), FIELD(kinegen_solver, a_prev, "double*"), FIELD(kinegen_solver, h_prev, "double"),
    FIELD(kinegen_solver, has_prev, "int"),
    FIELD(kinegen_solver, roles, "kinegen_roles"),
    FIELD(kinegen_solver, role, "char*"),
    {NULL, NULL, NULL, 0, 0},
};

#undef FIELD
#define STRUCT(structure) {#structure, (int)sizeof(structure)}

const kinegen_struct kinegen_structs[] = {
    STRUCT(kinegen_options), STRUCT(kinegen_kernel), STRUCT(kinegen_point), STRUCT(kinegen_actuator), STRUCT(kinegen_layout),
    STRUCT(kinegen_statics), STRUCT(kinegen_model), STRUCT(kinegen_pattern), STRUCT(kinegen_design), STRUCT(kinegen_roles), STRUCT(kinegen_solver),
    {NULL, 0},
};

#undef STRUCT

/* Every public function as data (kinegen_functions). Each is declared here once more from the same list the
 * table is made of: a list that disagreed with kinegen_solver.h's prototypes would not compile. */
#define FUNCTIONS(X)                                                                                                   \
    X(void, kinegen_default_options, (kinegen_options *options))                                                      \
    X(int, kinegen_init, (kinegen_solver *s, const kinegen_model *model, const kinegen_options *options, double *doubles, \
                          int *ints))                                                                                   \
    X(const kinegen_kernel *, kinegen_find_kernel, (const kinegen_model *model, const char *name))                    \
    X(int, kinegen_case_inputs, (const kinegen_model *model, double t, double *out))                                  \
    X(int, kinegen_kernel_each, (const kinegen_kernel *kernel, int count, const double *const *arguments,            \
                                 const int *strides, double *const *outputs))                                          \
    X(void, kinegen_set_design, (kinegen_solver *s, const double *p))                                                 \
    X(int, kinegen_start, (kinegen_solver *s, double t, const double *q0, const double *u, const double *ud, const double *udd)) \
    X(int, kinegen_step, (kinegen_solver *s, double t, const double *u, const double *ud, const double *udd))        \
    X(double, kinegen_table_mismatch, (int n, double h, const double *u0, const double *ud0, const double *udd0,       \
                                       const double *u1, const double *ud1, const double *udd1, int *input))           \
    X(int, kinegen_resume, (kinegen_solver *s, double t, const double *q, const double *v, const double *a,           \
                            const double *u, const double *ud, const double *a_prev, double h_prev))                   \
    X(int, kinegen_trajectory, (kinegen_solver *s, int count, const double *times, const double *U, const double *UD,  \
                                const double *UDD, double *Q, double *V, double *A, int *iterations, double *residuals, \
                                double *conditions, int *status))                                                      \
    X(int, kinegen_solve_batch, (kinegen_solver *s, int count, const double *U, double *Q, int *converged,            \
                                 int *iterations, double *residuals))                                                  \
    X(int, kinegen_newton, (kinegen_solver *s, double *q, const double *u, int *iterations, double *residual,         \
                            double *travel))                                                                           \
    X(int, kinegen_input_effects, (kinegen_solver *s, int count, const double *Q, const double *U, double *DQDU))     \
    X(int, kinegen_sensitivities, (kinegen_solver *s, int count, const double *Q, const double *V, const double *A,   \
                                   const double *U, const double *UD, const double *UDD, double *S, double *DV,        \
                                   double *DA, double *work))                                                          \
    X(int, kinegen_forces, (kinegen_solver *s, int count, const double *times, const double *Q, const double *V,      \
                            const double *A, const double *U, const double *weights, double inertia, double *LAMBDA,   \
                            double *F, double *work, int *iwork))                                                      \
    X(int, kinegen_reactions, (kinegen_solver *s, const double *q, const double *u, const double *lambda, double *out, \
                               double *work, int *iwork))                                                              \
    X(const char *, kinegen_status_text, (int status))                                                                 \
    X(void, kinegen_quaternion_from_matrix, (const double *matrix, double *quaternion))                               \
    X(void, kinegen_point_kinematics, (const double *frame, const double *local, double *position, double *velocity,  \
                                       double *acceleration))
#define DECLARE(result, name, parameters) result name parameters;
FUNCTIONS(DECLARE)
#undef DECLARE
#define ENTRY(result, name, parameters) {#name, #result, #parameters},

const kinegen_function kinegen_functions[] = {FUNCTIONS(ENTRY){NULL, NULL, NULL}};

#undef ENTRY
#undef FUNCTIONS

/* by code: each name beside its enum kinegen_status constant */
const char *const kinegen_status_names[] = {
    [KINEGEN_OK] = "ok", [KINEGEN_NOT_CONVERGED] = "not_converged", [KINEGEN_SINGULAR] = "singular",
    [KINEGEN_BRANCH] = "branch", [KINEGEN_NOT_STARTED] = "not_started", [KINEGEN_INPUTS] = "inputs", [KINEGEN_MODEL] = "model",
    [KINEGEN_MODEL + 1] = NULL,
};

/* the frames kernel's layout (enum kinegen_frame), by name */
const kinegen_frame_field kinegen_frame_fields[] = {
    {"origin", KINEGEN_FRAME_ORIGIN, 3},
    {"rotation", KINEGEN_FRAME_ROTATION, 9},
    {"velocity", KINEGEN_FRAME_VELOCITY, 3},
    {"angular_velocity", KINEGEN_FRAME_ANGULAR_VELOCITY, 3},
    {"acceleration", KINEGEN_FRAME_ACCELERATION, 3},
    {"angular_acceleration", KINEGEN_FRAME_ANGULAR_ACCELERATION, 3},
    {NULL, KINEGEN_FRAME_VALUES, 0},
};
