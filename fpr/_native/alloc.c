/* The allocation tick of controllers/allocation.py's Allocator in C: the same computation as its
 * Python reference (Allocator._solve_python, controllers/box_qp.py's solve_box_qp_state), without the
 * interpreter's and numpy's per-call costs (about a microsecond per small-array call there).
 *
 * tick(m_inv_a, j_f, a_tau, c, f_d, u_a, constants, state):
 *   1. no bound active in `state` (all FREE): the thesis' law (2.24) by one Cholesky solve of A_tau A_tau^T;
 *      if every w^2 is within [0, w_max^2] it is the QP's minimiser (route 0);
 *   2. else the scaled QP's H and g (Allocator._lean_qp) and the primal-dual active-set method
 *      (box_qp.solve_box_qp_state), warm-started from `state` or from the bounds the law crosses (route 1).
 *   Returns (route, iterations, w^2 (n_d, 4), thrust (n_d,), torque (n_d, 3), saturation bits) and writes the
 *   final active bounds into `state` (all FREE when none); or None, `state` untouched, when the Python
 *   reference must decide (A_tau A_tau^T not positive definite, the active-set method cycled or met a
 *   singular block, an input not finite): the caller then runs the Python path (its pinv builder, ProxQP).
 * box_qp(h, g, state, max_iterations, tolerance): solve_box_qp_state alone (for the tests):
 *   (x list, state tuple, iterations) or None.
 * inner(q, v, force, roll_rate, roll_acceleration, constants): the float part of controllers/ctc.py's inner
 *   loop (CascadedController._inner_python, the same operations in the same order): the desired rolls
 *   atan2(-F_y, F_z), the thrusts b_z(phi_i) . F_i - m_i d_i phi_i'^2, the pitch reference of the lateral loop
 *   and u_a; returns (thrust (n_d,), u_a (n_a,), roll_desired (n_d,), pitch). `constants`
 *   (CascadedController._inner_constants): n_d, lateral flag, x index, K_p and K_d of the lateral loop, its
 *   sensitivity, max pitch, then the rolls' indices (n_d), the attitude indices (n_a = 2 + n_d), m_i d_i
 *   (n_d), K_pa (n_a), K_da (n_a).
 *
 * `constants` (Allocator._kernel_constants, one float64 vector): n_d, n_a, w_max^2, saturation tolerance,
 * epsilon, unit-weight flag, then W_a (n_a), R_f^-1's thrust columns (n, n_d) and torque columns (n, 3 n_d),
 * S_f w_max^2 (n_d, n), S_tau w_max^2 (3 n_d, n), H's constant part (n, n), g's thrust matrix (n, n_d), all
 * row-major; n = 4 n_d. Input arrays may have any strides (m_inv_a is a transposed view).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <math.h>
#include <string.h>

#include "dense.h"  /* View, view, AT, cholesky, cholesky_solve */
#include "kernels.h"  /* FprAllocApi: the kernels for the native loop */

#define MAX_N 32    /* rotor variables (8 drones) */
#define MAX_A 24    /* attitude rows */
#define MAX_V 64    /* coordinates */
#define FREE 0
#define AT_LOWER 1
#define AT_UPPER 2
#define HEADER 6


/* box_qp.solve_box_qp_state: min 0.5 x^T H x + g^T x over [0, 1]^n (H n x n, row-major, symmetric), from
 * the guess `state` (updated in place on success). Returns the iterations, 0 when the guesses cycled or a
 * block was not positive definite (state then untouched). */
static int active_set(const double *h, const double *g, int n, signed char *state, int max_iterations,
                      double tolerance, double *x)
{
    double gmax = 1.0;
    for (int i = 0; i < n; i++) {
        if (g[i] > gmax) gmax = g[i];
        if (-g[i] > gmax) gmax = -g[i];
    }
    const double slack = tolerance * gmax, above = 1.0 + slack, below = -slack;
    signed char guess[MAX_N], next[MAX_N];
    int free[MAX_N];
    double t[MAX_N], grad[MAX_N], block[MAX_N * MAX_N], r[MAX_N * MAX_N], rhs[MAX_N];
    memcpy(guess, state, n);
    for (int iteration = 1; iteration <= max_iterations; iteration++) {
        int k = 0;
        for (int i = 0; i < n; i++) {
            x[i] = guess[i] == AT_UPPER ? 1.0 : 0.0;
            if (guess[i] == FREE) free[k++] = i;
        }
        for (int i = 0; i < n; i++) {  /* t = H x_0 + g */
            double s = 0.0;
            for (int j = 0; j < n; j++) s += h[i * n + j] * x[j];
            t[i] = s + g[i];
        }
        if (k > 0) {
            for (int a = 0; a < k; a++) {
                for (int b = 0; b < k; b++) block[a * k + b] = h[free[a] * n + free[b]];
                rhs[a] = -t[free[a]];
            }
            if (!cholesky(block, k, k, r)) return 0;
            cholesky_solve(r, k, rhs);
            for (int a = 0; a < k; a++) x[free[a]] = rhs[a];
        }
        for (int i = 0; i < n; i++) {  /* H x + g = t + H[:, F] x_F */
            double s = t[i];
            for (int a = 0; a < k; a++) s += h[i * n + free[a]] * rhs[a];
            grad[i] = s;
        }
        int same = 1;
        for (int i = 0; i < n; i++) {
            signed char s = guess[i], u;
            if (s == AT_LOWER) u = grad[i] >= below ? AT_LOWER : FREE;
            else if (s == AT_UPPER) u = grad[i] <= slack ? AT_UPPER : FREE;
            else u = x[i] < below ? AT_LOWER : x[i] > above ? AT_UPPER : FREE;
            next[i] = u;
            same &= u == s;
        }
        if (same) {
            for (int i = 0; i < n; i++) x[i] = x[i] < 0.0 ? 0.0 : x[i] > 1.0 ? 1.0 : x[i];
            memcpy(state, guess, n);
            return iteration;
        }
        memcpy(guess, next, n);
    }
    return 0;
}

static PyObject *new_array(int rows, int cols, const double *values, double factor)
{
    npy_intp dims[2] = {rows, cols};
    PyObject *out = cols ? PyArray_SimpleNew(2, dims, NPY_DOUBLE) : PyArray_SimpleNew(1, dims, NPY_DOUBLE);
    if (out == NULL) return NULL;
    double *d = (double *)PyArray_DATA((PyArrayObject *)out);
    int count = cols ? rows * cols : rows;
    for (int i = 0; i < count; i++) d[i] = values[i] * factor;
    return out;
}

/* The allocation tick on plain row-major arrays (the kernel of `tick`, also the native loop's through the module's
 * capsule, kernels.h): m (na x nv), jf (nd x nv), at (na x 3 nd), c (nv), fd (nd), u (na). Returns 1 with the
 * results (z: w^2 (4 nd), thrust (nd), tau (3 nd), saturation bits, route, iterations; `state` updated), 0 when
 * the Python reference must decide (`state` untouched), -1 when the constants or the sizes do not fit. */
static int tick_kernel(const double *m, const double *jf, const double *at, const double *c, int nv,
                       const double *fd, const double *u, const double *k, long k_len, signed char *state,
                       double *z, double *thrust, double *tau, unsigned long long *bits_out, int *route_out,
                       int *iterations_out)
{
    if (k_len < HEADER) return -1;
    const int nd = (int)k[0], na = (int)k[1], n = 4 * nd, nt = 3 * nd;
    const double scale = k[2], tol = k[3], reg = k[4];
    const int unit_weight = k[5] != 0.0;
    if (nd < 1 || n > MAX_N || na < 1 || na > MAX_A || nv < 1 || nv > MAX_V
        || k_len != HEADER + na + n * nd + n * nt + nd * n + nt * n + n * n + n * nd)
        return -1;
    const double *w_a = k + HEADER, *inv_f = w_a + na, *inv_tau = inv_f + n * nd, *ssf = inv_tau + n * nt,
                 *sst = ssf + nd * n, *hconst = sst + nt * n, *thrust_g = hconst + n * n;
    double gram[MAX_A * MAX_A], rg[MAX_A * MAX_A], zeta[MAX_N];
    for (int i = 0; i < na; i++)  /* A_tau A_tau^T: its upper triangle (the Cholesky reads it) */
        for (int j = i; j < na; j++) {
            double s = 0.0;
            for (int p = 0; p < nt; p++) s += at[i * nt + p] * at[j * nt + p];
            gram[i * na + j] = s;
        }
    if (!cholesky(gram, na, na, rg)) return 0;  /* rank deficient (never on these robots): the Python path's pinv */
    int bounded = 0, iterations = 0;
    for (int i = 0; i < n; i++) bounded |= state[i] != FREE;
    signed char guess[MAX_N];
    memcpy(guess, state, n);
    if (!bounded) {  /* route 1: the law; tau = A_tau^T (A A^T)^-1 (u_a + M_inv,a (c - J_f^T f_d)) */
        double y[MAX_V], x[MAX_A];
        for (int p = 0; p < nv; p++) {
            double s = c[p];
            for (int i = 0; i < nd; i++) s -= jf[i * nv + p] * fd[i];
            y[p] = s;
        }
        for (int i = 0; i < na; i++) {
            double s = 0.0;
            for (int p = 0; p < nv; p++) s += m[i * nv + p] * y[p];
            x[i] = u[i] + s;
        }
        cholesky_solve(rg, na, x);
        for (int p = 0; p < nt; p++) {
            double s = 0.0;
            for (int i = 0; i < na; i++) s += at[i * nt + p] * x[i];
            tau[p] = s;
        }
        double lowest = INFINITY, highest = -INFINITY;
        int finite = 1;
        for (int i = 0; i < n; i++) {
            double s = 0.0;
            for (int j = 0; j < nd; j++) s += inv_f[i * nd + j] * fd[j];
            for (int j = 0; j < nt; j++) s += inv_tau[i * nt + j] * tau[j];
            z[i] = s;
            finite &= isfinite(s) != 0;
            if (s < lowest) lowest = s;
            if (s > highest) highest = s;
        }
        if (!finite) return 0;  /* a non-finite input: the Python path decides (the reference's behaviour) */
        if (lowest >= 0.0 && highest <= scale) {
            unsigned long long bits = 0;
            if (!(lowest > tol && highest < scale - tol))
                for (int i = 0; i < n; i++)
                    if (z[i] <= tol || z[i] >= scale - tol) bits |= 1ULL << i;
            memcpy(thrust, fd, sizeof(double) * nd);
            *bits_out = bits;
            *route_out = 0;
            *iterations_out = 0;
            return 1;
        }
        for (int i = 0; i < n; i++) guess[i] = z[i] < 0.0 ? AT_LOWER : z[i] > scale ? AT_UPPER : FREE;
    }
    /* route 2: H and g of the scaled QP (Allocator._lean_qp) */
    double b[MAX_A * MAX_N], a[MAX_A * MAX_N], xb[MAX_A * MAX_N], mj[MAX_A * MAX_N], r[MAX_A];
    double h[MAX_N * MAX_N], g[MAX_N], col[MAX_A];
    for (int i = 0; i < na; i++) {
        for (int j = 0; j < nd; j++) {  /* M_inv,a J_f^T */
            double s = 0.0;
            for (int p = 0; p < nv; p++) s += m[i * nv + p] * jf[j * nv + p];
            mj[i * nd + j] = s;
        }
        for (int j = 0; j < n; j++) {  /* B = A_tau S_tau, A = B + M_inv,a J_f^T S_f (scaled) */
            double s = 0.0, t = 0.0;
            for (int p = 0; p < nt; p++) s += at[i * nt + p] * sst[p * n + j];
            for (int p = 0; p < nd; p++) t += mj[i * nd + p] * ssf[p * n + j];
            b[i * n + j] = s;
            a[i * n + j] = s + t;
        }
        double s = 0.0;
        for (int p = 0; p < nv; p++) s += m[i * nv + p] * c[p];
        r[i] = u[i] + s;
        if (!unit_weight) {
            for (int j = 0; j < n; j++) a[i * n + j] *= w_a[i];
            r[i] *= w_a[i];
        }
    }
    for (int j = 0; j < n; j++) {  /* X = (A_tau A_tau^T)^-1 B, column by column */
        for (int i = 0; i < na; i++) col[i] = b[i * n + j];
        cholesky_solve(rg, na, col);
        for (int i = 0; i < na; i++) xb[i * n + j] = col[i];
    }
    for (int i = 0; i < n; i++) {  /* H = A^T A + const - eps B^T X (upper triangle, mirrored) */
        for (int j = i; j < n; j++) {
            double s = 0.0, t = 0.0;
            for (int p = 0; p < na; p++) {
                s += a[p * n + i] * a[p * n + j];
                t += b[p * n + i] * xb[p * n + j];
            }
            h[i * n + j] = h[j * n + i] = s + hconst[i * n + j] - reg * t;
        }
        double s = 0.0, t = 0.0;
        for (int p = 0; p < nd; p++) s += thrust_g[i * nd + p] * fd[p];
        for (int p = 0; p < na; p++) t += a[p * n + i] * r[p];
        g[i] = s - t;
    }
    int finite = 1;
    for (int i = 0; i < n * n; i++) finite &= isfinite(h[i]) != 0;
    for (int i = 0; i < n; i++) finite &= isfinite(g[i]) != 0;
    iterations = finite ? active_set(h, g, n, guess, 12, 1e-12, zeta) : 0;
    if (iterations == 0) return 0;  /* cycled, singular or not finite: the Python path (its ProxQP) decides */
    int any = 0;
    for (int i = 0; i < n; i++) any |= guess[i] != FREE;
    if (any) memcpy(state, guess, n);
    else memset(state, FREE, n);
    unsigned long long bits = 0;
    const double low = tol / scale, high = 1.0 - tol / scale;
    for (int i = 0; i < n; i++)
        if (zeta[i] <= low || zeta[i] >= high) bits |= 1ULL << i;
    for (int i = 0; i < nd; i++) {  /* [f; tau] = [S_f; S_tau] w_max^2 zeta */
        double s = 0.0;
        for (int j = 0; j < n; j++) s += ssf[i * n + j] * zeta[j];
        thrust[i] = s;
    }
    for (int i = 0; i < nt; i++) {
        double s = 0.0;
        for (int j = 0; j < n; j++) s += sst[i * n + j] * zeta[j];
        tau[i] = s;
    }
    for (int i = 0; i < n; i++) z[i] = zeta[i] * scale;
    *bits_out = bits;
    *route_out = 1;
    *iterations_out = iterations;
    return 1;
}

/* A row-major copy of a view (rows x cols) into out */
static void copy_view(const View *v, double *out)
{
    for (npy_intp i = 0; i < v->rows; i++)
        for (npy_intp j = 0; j < v->cols; j++) out[i * v->cols + j] = AT(*v, i, j);
}

static PyObject *tick(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *o_m, *o_jf, *o_at, *o_c, *o_f, *o_u, *o_k, *o_state;
    if (!PyArg_UnpackTuple(args, "tick", 8, 8, &o_m, &o_jf, &o_at, &o_c, &o_f, &o_u, &o_k, &o_state))
        return NULL;
    npy_intp k_len = 0;
    const double *k = constants_of(o_k, &k_len);
    if (k == NULL || !PyArray_Check(o_state) || PyArray_TYPE((PyArrayObject *)o_state) != NPY_INT8
        || !PyArray_IS_C_CONTIGUOUS((PyArrayObject *)o_state) || !PyArray_ISWRITEABLE((PyArrayObject *)o_state)) {
        PyErr_SetString(PyExc_TypeError, "tick: constants must be contiguous float64, state writable int8");
        return NULL;
    }
    if (k_len < HEADER) goto bad_constants;
    const int nd = (int)k[0], na = (int)k[1], n = 4 * nd, nt = 3 * nd;
    if (nd < 1 || n > MAX_N || na < 1 || na > MAX_A || PyArray_SIZE((PyArrayObject *)o_state) != n)
        goto bad_constants;
    signed char *state = (signed char *)PyArray_DATA((PyArrayObject *)o_state);

    View m = {0}, jf = {0}, at = {0}, c = {0}, f = {0}, u = {0};
    PyObject *result = NULL;
    if (!view(o_m, 2, &m) || !view(o_jf, 2, &jf) || !view(o_at, 2, &at) || !view(o_c, 1, &c)
        || !view(o_f, 1, &f) || !view(o_u, 1, &u))
        goto done;
    const int nv = (int)m.cols;
    if (m.rows != na || nv > MAX_V || jf.rows != nd || jf.cols != nv || at.rows != na || at.cols != nt
        || c.cols != nv || f.cols != nd || u.cols != na) {
        PyErr_SetString(PyExc_ValueError, "tick: the attitude model's or the inputs' shapes do not fit");
        goto done;
    }
    double mc[MAX_A * MAX_V], jfc[MAX_N * MAX_V], atc[MAX_A * MAX_N], cc[MAX_V], fd[MAX_N], uc[MAX_A];
    double z[MAX_N], thrust[MAX_N], tau[MAX_N];
    copy_view(&m, mc);
    copy_view(&jf, jfc);
    copy_view(&at, atc);
    copy_view(&c, cc);
    copy_view(&f, fd);
    copy_view(&u, uc);
    unsigned long long bits = 0;
    int route = 0, iterations = 0;
    const int found = tick_kernel(mc, jfc, atc, cc, nv, fd, uc, k, (long)k_len, state, z, thrust, tau, &bits,
                                  &route, &iterations);
    if (found < 0) {
        PyErr_SetString(PyExc_ValueError, "tick: the constants vector does not fit its header");
        goto done;
    }
    if (found == 0) {
        result = Py_None;
        Py_INCREF(result);
        goto done;
    }
    result = Py_BuildValue("iiNNNK", route, iterations, new_array(nd, 4, z, 1.0), new_array(nd, 0, thrust, 1.0),
                           new_array(nd, 3, tau, 1.0), bits);
done:
    Py_XDECREF(m.array);
    Py_XDECREF(jf.array);
    Py_XDECREF(at.array);
    Py_XDECREF(c.array);
    Py_XDECREF(f.array);
    Py_XDECREF(u.array);
    return result;
bad_constants:
    PyErr_SetString(PyExc_ValueError, "tick: the constants vector does not fit its header");
    return NULL;
}

static PyObject *box_qp(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *o_h, *o_g, *o_state;
    int max_iterations = 12;
    double tolerance = 1e-12;
    if (!PyArg_ParseTuple(args, "OOO|id", &o_h, &o_g, &o_state, &max_iterations, &tolerance)) return NULL;
    View hv = {0}, gv = {0};
    PyObject *result = NULL, *seq = NULL;
    if (!view(o_h, 2, &hv) || !view(o_g, 1, &gv)) goto done;
    const int n = (int)gv.cols;
    if (hv.rows != n || hv.cols != n || n > MAX_N) {
        PyErr_SetString(PyExc_ValueError, "box_qp: H must be (n, n), g (n,), n <= 32");
        goto done;
    }
    seq = PySequence_Fast(o_state, "box_qp: state must be a sequence");
    if (seq == NULL) goto done;
    if (PySequence_Fast_GET_SIZE(seq) != n) {
        PyErr_SetString(PyExc_ValueError, "box_qp: state must have n entries");
        goto done;
    }
    signed char state[MAX_N];
    double h[MAX_N * MAX_N], g[MAX_N], x[MAX_N];
    for (int i = 0; i < n; i++) {
        long s = PyLong_AsLong(PySequence_Fast_GET_ITEM(seq, i));
        if (s == -1 && PyErr_Occurred()) goto done;
        state[i] = (signed char)s;
        g[i] = AT(gv, 0, i);
        for (int j = 0; j < n; j++) h[i * n + j] = AT(hv, i, j);
    }
    int iterations = active_set(h, g, n, state, max_iterations, tolerance, x);
    if (iterations == 0) {
        result = Py_None;
        Py_INCREF(result);
        goto done;
    }
    PyObject *xs = PyList_New(n), *ss = PyTuple_New(n);
    if (xs == NULL || ss == NULL) {
        Py_XDECREF(xs);
        Py_XDECREF(ss);
        goto done;
    }
    for (int i = 0; i < n; i++) {
        PyList_SET_ITEM(xs, i, PyFloat_FromDouble(x[i]));
        PyTuple_SET_ITEM(ss, i, PyLong_FromLong(state[i]));
    }
    result = Py_BuildValue("NNi", xs, ss, iterations);
done:
    Py_XDECREF(seq);
    Py_XDECREF(hv.array);
    Py_XDECREF(gv.array);
    return result;
}

#define INNER_HEADER 7

/* sin, cos and x ** 2 called as Python calls them: through pointers the compiler cannot see through, so that
 * it does not fuse sin and cos into one sincos call nor turn pow(x, 2) into x * x, each of which may round
 * differently in the last bit (Python's x ** 2 is libm's pow) */
static double (*volatile libm_sin)(double) = sin;
static double (*volatile libm_cos)(double) = cos;
static double (*volatile libm_pow)(double, double) = pow;

/* The inner loop's float part on plain arrays (the kernel of `inner`, also the native loop's through the module's
 * capsule, kernels.h): q, v (n), force (nd x 2, row-major), rate, acc (nd). Returns 1 with thrust (nd), u_a
 * (nd + 2), target (nd: the drones' desired rolls) and pitch; 0 when a result is not finite (the Python reference
 * then decides); -1 when the constants do not fit q (their indices out of range) or their header. */
static int inner_kernel(const double *q, const double *v, int n, const double *force, const double *rv,
                        const double *av, const double *k, long k_len, double *thrust, double *u_a, double *roll,
                        double *pitch_out)
{
    if (k_len < INNER_HEADER) return -1;
    const int nd = (int)k[0], na = nd + 2, lateral = k[1] != 0.0, ix = (int)k[2];
    const double kp_lat = k[3], kd_lat = k[4], pitch_gain = k[5], max_pitch = k[6];
    if (nd < 1 || nd > MAX_A - 2 || k_len != INNER_HEADER + nd + na + nd + 2 * na) return -1;
    const double *rolls = k + INNER_HEADER, *att = rolls + nd, *md = att + na, *kp = md + nd, *kd = kp + na;
    int ok = !lateral || (ix >= 0 && ix < n);
    for (int i = 0; i < nd; i++) ok = ok && rolls[i] >= 0 && rolls[i] < n;
    for (int i = 0; i < na; i++) ok = ok && att[i] >= 0 && att[i] < n;
    if (!ok) return -1;
    double target[MAX_A], rate[MAX_A], acc[MAX_A];
    for (int i = 0; i < nd; i++) {
        const double fy = force[2 * i], fz = force[2 * i + 1], phi = q[(int)rolls[i]], dphi = v[(int)rolls[i]];
        target[2 + i] = atan2(-fy, fz);  /* (2.20) */
        thrust[i] = -libm_sin(phi) * fy + libm_cos(phi) * fz - md[i] * libm_pow(dphi, 2.0);
        rate[2 + i] = rv[i];
        acc[2 + i] = av[i];
    }
    double pitch = 0.0;
    if (lateral) {
        pitch = (-kp_lat * q[ix] - kd_lat * v[ix]) / pitch_gain;
        if (-max_pitch > pitch) pitch = -max_pitch;  /* min(max(pitch, -max_pitch), max_pitch), as Python's */
        if (max_pitch < pitch) pitch = max_pitch;
    }
    target[0] = 0.0, target[1] = pitch, rate[0] = rate[1] = acc[0] = acc[1] = 0.0;
    for (int a = 0; a < na; a++) {
        const int i = (int)att[a];
        double error = q[i] - target[a];
        if (a >= 2) error = remainder(error, 2 * Py_MATH_PI);  /* rolls: the shortest angle */
        u_a[a] = acc[a] - kp[a] * error - kd[a] * (v[i] - rate[a]);
    }
    int finite = isfinite(pitch);
    for (int i = 0; i < nd; i++) finite = finite && isfinite(thrust[i]) && isfinite(target[2 + i]);
    for (int a = 0; a < na; a++) finite = finite && isfinite(u_a[a]);
    if (!finite) return 0;  /* overflow or a non-finite state: the Python reference decides (it may raise) */
    for (int i = 0; i < nd; i++) roll[i] = target[2 + i];
    *pitch_out = pitch;
    return 1;
}

static PyObject *inner(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *o[5], *o_k;
    if (!PyArg_UnpackTuple(args, "inner", 6, 6, &o[0], &o[1], &o[2], &o[3], &o[4], &o_k)) return NULL;
    npy_intp k_len = 0;
    const double *k = constants_of(o_k, &k_len);
    if (k == NULL || k_len < INNER_HEADER) {
        PyErr_SetString(PyExc_TypeError, "inner: constants must be a contiguous float64 vector");
        return NULL;
    }
    const int nd = (int)k[0], na = nd + 2;
    View qv = {0}, vv = {0}, fv = {0}, rv = {0}, av = {0};
    PyObject *result = NULL;
    if (nd < 1 || nd > MAX_A - 2 || k_len != INNER_HEADER + nd + na + nd + 2 * na) {
        PyErr_SetString(PyExc_ValueError, "inner: the constants vector does not fit its header");
        return NULL;
    }
    if (!view(o[0], 1, &qv) || !view(o[1], 1, &vv) || !view(o[2], 2, &fv) || !view(o[3], 1, &rv)
        || !view(o[4], 1, &av))
        goto done;
    const npy_intp n = qv.cols;
    if (!(vv.cols == n && n <= MAX_V && fv.rows == nd && fv.cols == 2 && rv.cols == nd && av.cols == nd)) {
        PyErr_SetString(PyExc_ValueError, "inner: q, v, force, roll_rate or roll_acceleration do not fit");
        goto done;
    }
    double qc[MAX_V], vc[MAX_V], fc[2 * MAX_A], rc[MAX_A], ac[MAX_A];
    copy_view(&qv, qc);
    copy_view(&vv, vc);
    copy_view(&fv, fc);
    copy_view(&rv, rc);
    copy_view(&av, ac);
    double thrust[MAX_A], u_a[MAX_A], roll[MAX_A], pitch = 0.0;
    const int found = inner_kernel(qc, vc, (int)n, fc, rc, ac, k, (long)k_len, thrust, u_a, roll, &pitch);
    if (found < 0) {
        PyErr_SetString(PyExc_ValueError, "inner: q, v, force, roll_rate or roll_acceleration do not fit");
        goto done;
    }
    if (found == 0) {
        Py_INCREF(Py_None);
        result = Py_None;
        goto done;
    }
    PyObject *o_t = new_array(nd, 0, thrust, 1.0), *o_u = new_array(na, 0, u_a, 1.0),
             *o_r = new_array(nd, 0, roll, 1.0);
    if (o_t != NULL && o_u != NULL && o_r != NULL) result = Py_BuildValue("NNNd", o_t, o_u, o_r, pitch);
    else {
        Py_XDECREF(o_t);
        Py_XDECREF(o_u);
        Py_XDECREF(o_r);
    }
done:
    Py_XDECREF(qv.array);
    Py_XDECREF(vv.array);
    Py_XDECREF(fv.array);
    Py_XDECREF(rv.array);
    Py_XDECREF(av.array);
    return result;
}

static const FprAllocApi alloc_api = {FPR_KERNELS_VERSION, tick_kernel, inner_kernel};

static PyMethodDef methods[] = {
    {"tick", tick, METH_VARARGS, "One allocation tick (see the module's C source): a tuple or None."},
    {"box_qp", box_qp, METH_VARARGS, "box_qp(h, g, state, max_iterations=12, tolerance=1e-12): "
                                     "controllers.box_qp.solve_box_qp_state in C."},
    {"inner", inner, METH_VARARGS, "The inner loop's float part (see the module's C source): a tuple, or None "
                                   "when a result is not finite (the Python reference then decides)."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "fpr._native._alloc",
                                    "The rotor allocation's tick in C (controllers.allocation.Allocator).", -1,
                                    methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__alloc(void)
{
    import_array();
    PyObject *mod = PyModule_Create(&module);
    if (mod == NULL) return NULL;
    PyModule_AddIntConstant(mod, "MAX_ROTORS", MAX_N);
    PyModule_AddIntConstant(mod, "MAX_ATTITUDE", MAX_A);
    PyModule_AddIntConstant(mod, "MAX_COORDINATES", MAX_V);
    PyObject *capsule = PyCapsule_New((void *)&alloc_api, "fpr._native._alloc._C_API", NULL);
    if (capsule == NULL || PyModule_AddObject(mod, "_C_API", capsule) < 0) {
        Py_XDECREF(capsule);
        Py_DECREF(mod);
        return NULL;
    }
    return mod;
}
