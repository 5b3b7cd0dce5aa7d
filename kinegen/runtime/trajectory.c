/* kinegen: the trajectory loop of kinegen.runtime.solver.Solver in C (the compiled path).
 *
 * Compiled together with a generated module's C (kinegen/runtime/compiled.py). It repeats
 * the solver's usual step -- predictor, Newton/chord iterations, factorization at the
 * solution, branch checks, polishing correction, velocity and acceleration -- and returns
 * at the first step where anything unusual happens (no convergence, a singular Phi_q, a
 * changed sign of det(Phi_q), an implausibly long Newton correction): Python then solves
 * that step with all its fallbacks and refinements and hands back. So this file holds no
 * decisions of its own; every threshold comes from SolverOptions.
 *
 * Conventions: arrays of time points are row-major (step, component); Phi_q is square
 * (n constraints, n velocity coordinates) and given by its values at a fixed pattern;
 * LAPACK is called through function pointers (SciPy's cython_lapack), Fortran style.
 * Quaternions are stored (w, x, y, z) and moved by exp(theta/2) (x) q.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef void (*phi_jac_fn)(const double *q, const double *u, double *phi, double *jac);
typedef void (*nu_fn)(const double *q, const double *u, const double *ud, double *out);
typedef void (*gamma_fn)(const double *q, const double *v, const double *u, const double *ud, const double *udd,
                         double *out);
typedef void (*getrf_fn)(int *m, int *n, double *a, int *lda, int *ipiv, int *info);
typedef void (*getrs_fn)(char *trans, int *n, int *nrhs, double *a, int *lda, int *ipiv, double *b, int *ldb,
                         int *info);
typedef void (*gbtrf_fn)(int *m, int *n, int *kl, int *ku, double *ab, int *ldab, int *ipiv, int *info);
typedef void (*gbtrs_fn)(char *trans, int *n, int *kl, int *ku, int *nrhs, double *ab, int *ldab, int *ipiv,
                         double *b, int *ldb, int *info);
typedef void (*gecon_fn)(char *norm, int *n, double *a, int *lda, double *anorm, double *rcond, double *work,
                         int *iwork, int *info);
typedef void (*gbcon_fn)(char *norm, int *n, int *kl, int *ku, double *ab, int *ldab, int *ipiv, double *anorm,
                         double *rcond, double *work, int *iwork, int *info);

/* Mirrored field by field by kinegen.runtime.compiled._Problem (ctypes). */
struct kinegen_problem {
    int n_stored, n, n_inputs, entries;
    const int *flat;      /* position of each Phi_q value in the column-major dense or band matrix */
    const int *cols;      /* its column (for the 1-norm of the condition estimate) */
    int band, kl, ku, ld; /* band: 0 dense (getrf), 1 band (gbtrf); ld: leading dimension */
    const int *row_order; /* band: rows and columns of the band matrix in the original order */
    const int *col_order;
    int n_positions, n_rotations;  /* retraction: q[position_q] += step[position_v]; quaternions */
    const int *position_q, *position_v, *rotation_q, *rotation_v; /* rotation_*: (4 or 3, bodies) */
    void *phi_jac, *nu, *gamma;
    void *getrf, *getrs, *gbtrf, *gbtrs, *gecon, *gbcon;
    double tolerance, singular_tolerance, divergence_limit, chord_rate, jump_ratio, jump_floor;
    int max_iterations, predictor, chord, polish, keep_branch, condition;
};

struct workspace {
    double *lu, *phi, *values, *step, *rhs, *tmp, *work, *motion;
    int *ipiv, *iwork;
    double anorm;
};

static double max_abs(const double *x, int n) {
    double m = 0.0;
    for (int i = 0; i < n; ++i) {
        double a = fabs(x[i]);
        if (!(a <= m)) m = a; /* NaN wins, as in NumPy's max */
    }
    return m;
}

/* q moved by step (velocity coordinates): positions added, quaternions by the exponential map. */
static void retract(const struct kinegen_problem *p, double *q, const double *step) {
    if (p->n_rotations == 0) {
        for (int i = 0; i < p->n; ++i) q[i] += step[i];
        return;
    }
    for (int k = 0; k < p->n_positions; ++k) q[p->position_q[k]] += step[p->position_v[k]];
    int b = p->n_rotations;
    for (int k = 0; k < b; ++k) {
        double tx = step[p->rotation_v[k]], ty = step[p->rotation_v[b + k]], tz = step[p->rotation_v[2 * b + k]];
        double *w = q + p->rotation_q[k], *x = q + p->rotation_q[b + k];
        double *y = q + p->rotation_q[2 * b + k], *z = q + p->rotation_q[3 * b + k];
        double angle = sqrt(tx * tx + ty * ty + tz * tz), half = 0.5 * angle;
        double scale = angle <= 1e-8 ? 0.5 - angle * angle / 48.0 : sin(half) / angle;
        double pw = cos(half), px = scale * tx, py = scale * ty, pz = scale * tz;
        double qw = *w, qx = *x, qy = *y, qz = *z;
        *w = pw * qw - px * qx - py * qy - pz * qz;
        *x = pw * qx + px * qw + py * qz - pz * qy;
        *y = pw * qy - px * qz + py * qw + pz * qx;
        *z = pw * qz + px * qy - py * qx + pz * qw;
    }
}

/* Entry j of U's diagonal in the factors (dense: lu[j, j]; band: row kl + ku of AB). */
static double u_diagonal(const struct kinegen_problem *p, const struct workspace *ws, int j) {
    return p->band ? ws->lu[p->kl + p->ku + j * p->ld] : ws->lu[j * p->ld + j];
}

/* LU factors of Phi_q (values) into ws->lu / ws->ipiv; 0, or 1 when (nearly) singular. */
static int factor(const struct kinegen_problem *p, struct workspace *ws, const double *values) {
    int n = p->n, ld = p->ld, info = 0, kl = p->kl, ku = p->ku;
    memset(ws->lu, 0, sizeof(double) * (size_t)ld * (size_t)n);
    for (int k = 0; k < p->entries; ++k) ws->lu[p->flat[k]] = values[k];
    if (p->condition) {
        memset(ws->tmp, 0, sizeof(double) * (size_t)n);
        for (int k = 0; k < p->entries; ++k) ws->tmp[p->cols[k]] += fabs(values[k]);
        ws->anorm = max_abs(ws->tmp, n);
    }
    if (p->band) {
        ((gbtrf_fn)p->gbtrf)(&n, &n, &kl, &ku, ws->lu, &ld, ws->ipiv, &info);
    } else {
        ((getrf_fn)p->getrf)(&n, &n, ws->lu, &ld, ws->ipiv, &info);
    }
    if (info != 0) return 1;
    double low = INFINITY, high = 0.0;
    for (int j = 0; j < n; ++j) {
        double d = fabs(u_diagonal(p, ws, j));
        if (!(d >= low)) low = d;
        if (!(d <= high)) high = d;
    }
    return !(low > p->singular_tolerance * fmax(high, 1e-300));
}

/* Sign of det(P L U): row interchanges and negative pivots. */
static int sign_of(const struct kinegen_problem *p, const struct workspace *ws) {
    int odd = 0;
    for (int j = 0; j < p->n; ++j) {
        odd ^= ws->ipiv[j] != j + 1;
        odd ^= u_diagonal(p, ws, j) < 0.0;
    }
    return odd ? -1 : 1;
}

/* x = Phi_q^-1 rhs with the current factors (x and rhs may not alias). */
static void solve(const struct kinegen_problem *p, struct workspace *ws, const double *rhs, double *x) {
    int n = p->n, ld = p->ld, kl = p->kl, ku = p->ku, one = 1, info = 0;
    char trans = 'N';
    if (p->band) {
        for (int i = 0; i < n; ++i) ws->tmp[i] = rhs[p->row_order[i]];
        ((gbtrs_fn)p->gbtrs)(&trans, &n, &kl, &ku, &one, ws->lu, &ld, ws->ipiv, ws->tmp, &n, &info);
        for (int i = 0; i < n; ++i) x[p->col_order[i]] = ws->tmp[i];
    } else {
        memcpy(x, rhs, sizeof(double) * (size_t)n);
        ((getrs_fn)p->getrs)(&trans, &n, &one, ws->lu, &ld, ws->ipiv, x, &n, &info);
    }
}

static double condition_number(const struct kinegen_problem *p, struct workspace *ws) {
    int n = p->n, ld = p->ld, kl = p->kl, ku = p->ku, info = 0;
    char norm = '1';
    double rcond = 0.0;
    if (p->band) {
        ((gbcon_fn)p->gbcon)(&norm, &n, &kl, &ku, ws->lu, &ld, ws->ipiv, &ws->anorm, &rcond, ws->work, ws->iwork, &info);
    } else {
        ((gecon_fn)p->gecon)(&norm, &n, ws->lu, &ld, &ws->anorm, &rcond, ws->work, ws->iwork, &info);
    }
    return rcond == 0.0 ? INFINITY : 1.0 / rcond;
}

/* Steps first..steps-1 from the solved step first-1 (rows of Q, V, A; its det sign sign0).
 * Returns the first step it did not solve (== steps when all are solved). */
int kinegen_trajectory(const struct kinegen_problem *p, int first, int steps, const double *times, const double *U,
                       const double *UD, const double *UDD, double *Q, double *V, double *A, int *iterations,
                       double *residuals, double *conditions, int sign0) {
    int n = p->n, ns = p->n_stored, ni = p->n_inputs, ld = p->ld;
    struct workspace ws;
    double *block = calloc((size_t)ld * n + 8 * (size_t)n + (size_t)p->entries + (size_t)ns, sizeof(double));
    int *iblock = calloc(2 * (size_t)n, sizeof(int));
    if (block == NULL || iblock == NULL) {
        free(block);
        free(iblock);
        return first;
    }
    ws.lu = block;
    ws.phi = ws.lu + (size_t)ld * n;
    ws.step = ws.phi + n;
    ws.rhs = ws.step + n;
    ws.tmp = ws.rhs + n;
    ws.motion = ws.tmp + n;
    ws.work = ws.motion + n; /* 3n (gbcon) or 4n (gecon) */
    ws.values = ws.work + 4 * (size_t)n;
    ws.ipiv = iblock;
    ws.iwork = iblock + n;
    ws.anorm = 0.0;
    phi_jac_fn phi_jac = (phi_jac_fn)p->phi_jac;
    int sign = sign0, have = 0, i = first;
    for (; i < steps; ++i) {
        const double *u = U + (size_t)i * ni, *ud = UD + (size_t)i * ni, *udd = UDD + (size_t)i * ni;
        double h = times[i] - times[i - 1], largest_motion = 0.0;
        double *q = Q + (size_t)i * ns, *v = V + (size_t)i * n, *a = A + (size_t)i * n;
        memcpy(q, Q + (size_t)(i - 1) * ns, sizeof(double) * (size_t)ns);
        if (p->predictor) {
            const double *v0 = V + (size_t)(i - 1) * n, *a0 = A + (size_t)(i - 1) * n;
            for (int j = 0; j < n; ++j) ws.motion[j] = v0[j] * h + 0.5 * a0[j] * h * h;
            largest_motion = max_abs(ws.motion, n);
            retract(p, q, ws.motion);
        }
        /* Newton, or chord iterations from the factors of the last solution */
        if (!p->chord || i == first) have = 0;
        phi_jac(q, u, ws.phi, ws.values);
        double norm = max_abs(ws.phi, n), travel = 0.0;
        int count = 0;
        while (!(norm <= p->tolerance)) {
            if (count >= p->max_iterations || !isfinite(norm) || norm > p->divergence_limit) goto handover;
            if (!have) {
                if (factor(p, &ws, ws.values)) goto handover;
                have = 1;
            }
            for (int j = 0; j < n; ++j) ws.rhs[j] = -ws.phi[j];
            solve(p, &ws, ws.rhs, ws.step);
            ++count;
            travel += max_abs(ws.step, n);
            retract(p, q, ws.step);
            phi_jac(q, u, ws.phi, ws.values);
            double next = max_abs(ws.phi, n);
            if (!p->chord || !(next <= p->chord_rate * norm)) have = 0;
            norm = next;
        }
        /* the factors at the solution: branch checks, polishing, velocity, acceleration */
        if (factor(p, &ws, ws.values)) goto handover;
        have = 1;
        int s = sign_of(p, &ws);
        if (p->keep_branch) {
            if (s != sign) goto handover;
            if (p->predictor && travel > fmax(p->jump_ratio * largest_motion, p->jump_floor)) goto handover;
        }
        if ((p->polish || p->chord) && count > 0) {
            solve(p, &ws, ws.phi, ws.step);
            for (int j = 0; j < n; ++j) ws.step[j] = -ws.step[j];
            retract(p, q, ws.step);
        }
        ((nu_fn)p->nu)(q, u, ud, ws.rhs);
        solve(p, &ws, ws.rhs, v);
        ((gamma_fn)p->gamma)(q, v, u, ud, udd, ws.rhs);
        solve(p, &ws, ws.rhs, a);
        iterations[i] = count;
        residuals[i] = norm;
        conditions[i] = p->condition ? condition_number(p, &ws) : NAN;
        sign = s;
    }
handover:
    free(block);
    free(iblock);
    return i;
}
