/* kinegen_interval.h -- the interval arithmetic a generated model's input_ranges kernels call.
 *
 * An interval [lo, hi] encloses a real quantity. Every helper returns an interval that contains
 * the exact real result for every value in its arguments' intervals: bounds rounded outward (by
 * KINEGEN_IV_RELATIVE of their magnitude plus KINEGEN_IV_ABSOLUTE, which covers IEEE arithmetic's
 * and libm's rounding), a bound that cannot be computed (a function outside its domain over part
 * of the interval, an overflow: NaN) made infinite, 0 times an infinite bound counted as 0. The
 * Python backend's helpers (kinegen/codegen/backends/python/intervals.py) are the same functions
 * over NumPy arrays. C99 and libm only.
 */
#ifndef KINEGEN_INTERVAL_H
#define KINEGEN_INTERVAL_H

#include <math.h>

typedef struct kinegen_interval {
    double lo, hi;
} kinegen_interval;

/* The larger helpers the generated code calls: not inlined where the compiler can be told so. Inlined
 * into the input_ranges kernels (hundreds of calls each), they took the excavator's nine kernels
 * 1.36-1.39 CPU-s to compile at the runtime's -O1 -- a third of its first library's compile -- against
 * 0.52 s as calls, which cost 0.45 % of a certified step's instructions (docs/performance.md). The sum
 * and the integer power stay inline (as a call, pow with an exponent that is no constant: +2.2 % of a
 * step). The same operations either way: the same bits. "unused": a part that calls none of them
 * compiles without a warning. */
#if defined(__GNUC__) || defined(__clang__)
#define KINEGEN_IV_HELPER __attribute__((noinline, unused))
#else
#define KINEGEN_IV_HELPER inline
#endif

#define KINEGEN_IV_RELATIVE 1.7763568394002505e-15 /* 2^-49 */
#define KINEGEN_IV_ABSOLUTE 1e-300
#define KINEGEN_IV_PI 3.141592653589793

/* fmin and fmax (the other argument where one is NaN), inline: at -O1 -std=c99 the library's are calls */
static inline double kinegen_iv_min(double a, double b) { return a < b || isnan(b) ? a : b; }
static inline double kinegen_iv_max(double a, double b) { return a > b || isnan(b) ? a : b; }

/* [lo, hi] rounded outward; a NaN bound infinite */
static inline kinegen_interval kinegen_iv_out(double lo, double hi) {
    kinegen_interval r;
    r.lo = lo - (fabs(lo) * KINEGEN_IV_RELATIVE + KINEGEN_IV_ABSOLUTE);
    r.hi = hi + (fabs(hi) * KINEGEN_IV_RELATIVE + KINEGEN_IV_ABSOLUTE);
    if (isnan(r.lo)) r.lo = -INFINITY;
    if (isnan(r.hi)) r.hi = INFINITY;
    return r;
}

static inline kinegen_interval kinegen_iv_const(double lo, double hi) {
    kinegen_interval r;
    r.lo = lo;
    r.hi = hi;
    return r;
}

static inline kinegen_interval kinegen_iv_add(kinegen_interval a, kinegen_interval b) {
    return kinegen_iv_out(a.lo + b.lo, a.hi + b.hi);
}

static inline kinegen_interval kinegen_iv_neg(kinegen_interval a) {
    return kinegen_iv_const(-a.hi, -a.lo);
}

static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_mul(kinegen_interval a, kinegen_interval b) {
    /* fmin/fmax skip the NaN of 0 * inf; all four NaN: unbounded (kinegen_iv_out) */
    double p0 = a.lo * b.lo, p1 = a.lo * b.hi, p2 = a.hi * b.lo, p3 = a.hi * b.hi;
    return kinegen_iv_out(kinegen_iv_min(kinegen_iv_min(p0, p1), kinegen_iv_min(p2, p3)), kinegen_iv_max(kinegen_iv_max(p0, p1), kinegen_iv_max(p2, p3)));
}

/* c a for a constant c: kinegen_iv_mul of [c, c] and a to the bit (its four products are these two, twice),
 * at half the multiplications and a third of the comparisons, inline. The generated code scales by every
 * exactly representable constant factor with it: chain-100's drivers' 300 factors of +-1/2 made kinegen_iv_mul
 * 2.9 % of its certified step. */
static inline kinegen_interval kinegen_iv_scale(double c, kinegen_interval a) {
    double p0 = c * a.lo, p1 = c * a.hi;
    return kinegen_iv_out(kinegen_iv_min(p0, p1), kinegen_iv_max(p0, p1));
}

static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_inv(kinegen_interval a) {
    if (a.lo > 0.0 || a.hi < 0.0) return kinegen_iv_out(1.0 / a.hi, 1.0 / a.lo);
    return kinegen_iv_const(-INFINITY, INFINITY);
}

/* a^n, n a positive integer */
static inline kinegen_interval kinegen_iv_powi(kinegen_interval a, int n) {
    double lo = pow(a.lo, n), hi = pow(a.hi, n);
    if (n % 2) return kinegen_iv_out(lo, hi);
    return kinegen_iv_out(a.lo < 0.0 && a.hi > 0.0 ? 0.0 : kinegen_iv_min(lo, hi), kinegen_iv_max(lo, hi));
}

/* a^r, r a real exponent in [r_lo, r_hi], a >= 0 (the real function's domain): monotone in a and in r,
 * so its range is at the corners */
static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_powr(kinegen_interval a, double r_lo, double r_hi) {
    double x = kinegen_iv_max(a.lo, 0.0), y = kinegen_iv_max(a.hi, 0.0);
    double c0 = pow(x, r_lo), c1 = pow(x, r_hi), c2 = pow(y, r_lo), c3 = pow(y, r_hi);
    return kinegen_iv_out(kinegen_iv_min(kinegen_iv_min(c0, c1), kinegen_iv_min(c2, c3)),
                          kinegen_iv_max(kinegen_iv_max(c0, c1), kinegen_iv_max(c2, c3)));
}

static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_sqrt(kinegen_interval a) {
    return kinegen_iv_out(sqrt(kinegen_iv_max(a.lo, 0.0)), sqrt(kinegen_iv_max(a.hi, 0.0)));
}

static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_exp(kinegen_interval a) { return kinegen_iv_out(exp(a.lo), exp(a.hi)); }
static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_log(kinegen_interval a) { return kinegen_iv_out(log(kinegen_iv_max(a.lo, 0.0)), log(a.hi)); }
static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_atan(kinegen_interval a) { return kinegen_iv_out(atan(a.lo), atan(a.hi)); }
static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_sinh(kinegen_interval a) { return kinegen_iv_out(sinh(a.lo), sinh(a.hi)); }
static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_tanh(kinegen_interval a) { return kinegen_iv_out(tanh(a.lo), tanh(a.hi)); }

static inline double kinegen_iv_clip(double x) { return x < -1.0 ? -1.0 : (x > 1.0 ? 1.0 : x); }
static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_asin(kinegen_interval a) {
    return kinegen_iv_out(asin(kinegen_iv_clip(a.lo)), asin(kinegen_iv_clip(a.hi)));
}
static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_acos(kinegen_interval a) {
    return kinegen_iv_out(acos(kinegen_iv_clip(a.hi)), acos(kinegen_iv_clip(a.lo)));
}

static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_sign(kinegen_interval a) {
    return kinegen_iv_const(a.lo > 0.0 ? 1.0 : (a.lo < 0.0 ? -1.0 : 0.0), a.hi > 0.0 ? 1.0 : (a.hi < 0.0 ? -1.0 : 0.0));
}

static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_abs(kinegen_interval a) {
    double lo = fabs(a.lo), hi = fabs(a.hi);
    return kinegen_iv_const(a.lo < 0.0 && a.hi > 0.0 ? 0.0 : kinegen_iv_min(lo, hi), kinegen_iv_max(lo, hi));
}

static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_cosh(kinegen_interval a) {
    double lo = cosh(a.lo), hi = cosh(a.hi);
    return kinegen_iv_out(a.lo < 0.0 && a.hi > 0.0 ? 1.0 : kinegen_iv_min(lo, hi), kinegen_iv_max(lo, hi));
}

/* whether [a] holds a point phase + k period (with a margin: a near miss counts as a hit) */
static inline int kinegen_iv_reaches(kinegen_interval a, double phase, double period) {
    double first = ceil((a.lo - phase) / period - 1e-9) * period + phase;
    return !(first > a.hi + 1e-12 * (1.0 + fabs(a.hi)));
}

/* a 2 pi-periodic function of range [-1, 1] whose maxima lie at top and minima at bottom (+ 2 k pi) */
static inline kinegen_interval kinegen_iv_periodic(double fa, double fb, kinegen_interval a, double top, double bottom) {
    int whole = !(a.hi - a.lo < 2.0 * KINEGEN_IV_PI); /* a whole period, or not finite */
    double lo = whole || kinegen_iv_reaches(a, bottom, 2.0 * KINEGEN_IV_PI) ? -1.0 : kinegen_iv_min(fa, fb);
    double hi = whole || kinegen_iv_reaches(a, top, 2.0 * KINEGEN_IV_PI) ? 1.0 : kinegen_iv_max(fa, fb);
    return kinegen_iv_out(lo, hi);
}

static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_sin(kinegen_interval a) {
    return kinegen_iv_periodic(sin(a.lo), sin(a.hi), a, KINEGEN_IV_PI / 2.0, -KINEGEN_IV_PI / 2.0);
}

static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_cos(kinegen_interval a) {
    return kinegen_iv_periodic(cos(a.lo), cos(a.hi), a, 0.0, KINEGEN_IV_PI);
}

/* kinegen_iv_sin and kinegen_iv_cos of one interval into *s and *c, to the bit: the sine and cosine of each
 * bound side by side, which a compiler that knows libm's sincos makes one call (GCC does, -std=c99 too;
 * glibc's sincos gives sin's and cos's bits: 40 million arguments compared, 2026-12-04). The generated code
 * calls it where both of an interval are wanted (every driver that is a sine or cosine of time: its value's
 * and its acceleration's one, its rate's the other). */
static KINEGEN_IV_HELPER void kinegen_iv_sincos(kinegen_interval a, kinegen_interval *s, kinegen_interval *c) {
    double sin_lo = sin(a.lo), cos_lo = cos(a.lo), sin_hi = sin(a.hi), cos_hi = cos(a.hi);
    *s = kinegen_iv_periodic(sin_lo, sin_hi, a, KINEGEN_IV_PI / 2.0, -KINEGEN_IV_PI / 2.0);
    *c = kinegen_iv_periodic(cos_lo, cos_hi, a, 0.0, KINEGEN_IV_PI);
}

static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_tan(kinegen_interval a) {
    if (!(a.hi - a.lo < KINEGEN_IV_PI) || kinegen_iv_reaches(a, KINEGEN_IV_PI / 2.0, KINEGEN_IV_PI))
        return kinegen_iv_const(-INFINITY, INFINITY);
    return kinegen_iv_out(tan(a.lo), tan(a.hi));
}

/* atan2(y, x) over the box y x x: its corners' range, or [-pi, pi] where the box holds the origin or
 * crosses the negative x axis (where atan2 jumps) */
static KINEGEN_IV_HELPER kinegen_interval kinegen_iv_atan2(kinegen_interval y, kinegen_interval x) {
    if (x.lo <= 0.0 && y.lo <= 0.0 && y.hi >= 0.0) return kinegen_iv_out(-KINEGEN_IV_PI, KINEGEN_IV_PI);
    double c0 = atan2(y.lo, x.lo), c1 = atan2(y.lo, x.hi), c2 = atan2(y.hi, x.lo), c3 = atan2(y.hi, x.hi);
    return kinegen_iv_out(kinegen_iv_min(kinegen_iv_min(c0, c1), kinegen_iv_min(c2, c3)), kinegen_iv_max(kinegen_iv_max(c0, c1), kinegen_iv_max(c2, c3)));
}

#endif
