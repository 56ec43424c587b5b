/* The numpy part of fpr/model/robot.py's Robot.attitude_model in C: the same quantities as its
 * Python reference (Robot._attitude_python) from the same Pinocchio outputs, without numpy's per-call costs
 * (about a microsecond per small-array call; the Python path makes a dozen).
 *
 * post(m_p, nle_p, jacobians, constants) -> (m_inv_a, j_tau, j_f, a_tau, c) or None
 *   m_p: Pinocchio's joint-space inertia (n, n), its upper triangle read (as LAPACK's posv reads it);
 *   nle_p: Pinocchio's nonlinear effects (n,);
 *   jacobians: a tuple of the n_d drone-centre frame Jacobians (6, n) in Pinocchio's coordinates (LOCAL);
 *   constants (Robot._attitude_constants, one contiguous float64 vector): n, n_d, n_a, the attitude
 *   coordinates' indices (n_a), T (n, n) and T^-1 (n, n), row-major (q_pin = T q).
 *   Returns, in the thesis' coordinates: c = T^T nle_p; each drone's thrust row (2) and torque rows (3-5) of
 *   J T; m_inv_a = (T^-1 X)^T with M_p X = (T^-1)[a]^T (Cholesky), the attitude rows of M^-1; a_tau =
 *   m_inv_a j_tau^T. None when M_p is not positive definite (or not finite): the caller then runs the Python
 *   path, which decides.
 * Inputs may have any strides (Pinocchio returns column-major matrices).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <math.h>

#include "dense.h"  /* View, view, AT, cholesky, cholesky_solve */
#include "kernels.h"  /* FprAttitudeApi: the kernel for the native loop */

#define MAX_V 64     /* coordinates */
#define MAX_D 16     /* drones */
#define HEADER 3

/* A float64 view (any strides) of obj of shape (rows, cols) (cols 0: a vector of `rows`); 0 on a wrong type or
 * shape. Vectors are read as AT(v, 0, j) (_dense.h's row vectors). */
static int shaped_view(PyObject *obj, npy_intp rows, npy_intp cols, View *v)
{
    if (!view(obj, cols ? 2 : 1, v)) return 0;
    if (cols ? (v->rows != rows || v->cols != cols) : v->cols != rows) {
        PyErr_Format(PyExc_ValueError, "post: expected an array of shape (%zd, %zd)", (Py_ssize_t)rows,
                     (Py_ssize_t)cols);
        Py_CLEAR(v->array);
        return 0;
    }
    return 1;
}


static PyObject *new_array(int rows, int cols, double **data)
{
    npy_intp dims[2] = {rows, cols};
    PyObject *out = PyArray_SimpleNew(cols ? 2 : 1, dims, NPY_DOUBLE);
    if (out != NULL) *data = (double *)PyArray_DATA((PyArrayObject *)out);
    return out;
}

/* The attitude model on plain row-major arrays (the kernel of `post`, also the native loop's through the module's
 * capsule, kernels.h): m_p (n x n, upper triangle read), nle_p (n), jacobians (n_d x 6 x n). Returns 1 with
 * m_inv_a (n_a x n), j_tau (3 n_d x n), j_f (n_d x n), a_tau (n_a x 3 n_d), c (n); 0 when M_p is not positive
 * definite (or not finite); -1 when the constants do not fit their header. */
static int post_kernel(const double *m_p, const double *nle, const double *jac, const double *k, long k_len,
                       double *mi, double *jt, double *jf, double *at, double *cc)
{
    if (k_len < HEADER) return -1;
    const int n = (int)k[0], nd = (int)k[1], na = (int)k[2], nt = 3 * nd;
    if (n < 1 || n > MAX_V || nd < 1 || nd > MAX_D || na < 1 || na > n || k_len != HEADER + na + 2 * n * n)
        return -1;
    const double *idx = k + HEADER, *t = idx + na, *t_inv = t + n * n;
    for (int a = 0; a < na; a++)
        if (!(idx[a] >= 0 && idx[a] < n)) return -1;
    /* Cholesky M_p = R^T R (R upper, row-major), M_p's upper triangle read */
    double r[MAX_V * MAX_V];
    if (!cholesky(m_p, n, n, r)) return 0;  /* not positive definite, or not finite: the Python path decides */
    /* c = T^T nle_p */
    for (int i = 0; i < n; i++) {
        double s = 0.0;
        for (int j = 0; j < n; j++) s += t[j * n + i] * nle[j];
        cc[i] = s;
    }
    /* each drone's rows of J T: thrust (row 2), torques (rows 3-5) */
    for (int d = 0; d < nd; d++)
        for (int row = 2; row < 6; row++) {
            double *out = row == 2 ? jf + d * n : jt + (3 * d + row - 3) * n;
            const double *jrow = jac + (d * 6 + row) * n;
            for (int i = 0; i < n; i++) {
                double s = 0.0;
                for (int j = 0; j < n; j++) s += jrow[j] * t[j * n + i];
                out[i] = s;
            }
        }
    /* the attitude rows of M^-1 = T^-1 M_p^-1 T^-T: x = M_p^-1 (T^-1)[a]^T, then row a of M^-1 = T^-1 x */
    for (int a = 0; a < na; a++) {
        double x[MAX_V];
        const double *rhs = t_inv + (int)idx[a] * n;
        for (int i = 0; i < n; i++) x[i] = rhs[i];
        cholesky_solve(r, n, x);
        for (int i = 0; i < n; i++) {
            double s = 0.0;
            for (int j = 0; j < n; j++) s += t_inv[i * n + j] * x[j];
            mi[a * n + i] = s;
        }
        /* a_tau = m_inv_a j_tau^T */
        for (int b = 0; b < nt; b++) {
            double s = 0.0;
            for (int i = 0; i < n; i++) s += mi[a * n + i] * jt[b * n + i];
            at[a * nt + b] = s;
        }
    }
    return 1;
}

static PyObject *post(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *o_m, *o_c, *o_j, *o_k;
    if (!PyArg_UnpackTuple(args, "post", 4, 4, &o_m, &o_c, &o_j, &o_k)) return NULL;
    npy_intp k_len = 0;
    const double *k = constants_of(o_k, &k_len);
    if (k == NULL || !PyTuple_Check(o_j)) {
        PyErr_SetString(PyExc_TypeError, "post: constants must be contiguous float64, jacobians a tuple");
        return NULL;
    }
    if (k_len < HEADER) goto bad_constants;
    const int n = (int)k[0], nd = (int)k[1], na = (int)k[2], nt = 3 * nd;
    if (n < 1 || n > MAX_V || nd < 1 || nd > MAX_D || na < 1 || na > n || k_len != HEADER + na + 2 * n * n
        || PyTuple_GET_SIZE(o_j) != nd)
        goto bad_constants;

    View mv = {0}, cv = {0}, jv[MAX_D] = {{0}};
    PyObject *result = NULL, *o_mi = NULL, *o_jt = NULL, *o_jf = NULL, *o_at = NULL, *o_cc = NULL;
    if (!shaped_view(o_m, n, n, &mv) || !shaped_view(o_c, n, 0, &cv)) goto done;
    for (int d = 0; d < nd; d++)
        if (!shaped_view(PyTuple_GET_ITEM(o_j, d), 6, n, &jv[d])) goto done;
    double mp[MAX_V * MAX_V], nle[MAX_V], jac[MAX_D * 6 * MAX_V];
    for (int i = 0; i < n; i++) {
        nle[i] = AT(cv, 0, i);
        for (int j = 0; j < n; j++) mp[i * n + j] = j >= i ? AT(mv, i, j) : 0.0;
    }
    for (int d = 0; d < nd; d++)
        for (int row = 0; row < 6; row++)
            for (int j = 0; j < n; j++) jac[(d * 6 + row) * n + j] = AT(jv[d], row, j);
    double *mi, *jt, *jf, *at, *cc;
    if ((o_mi = new_array(na, n, &mi)) == NULL || (o_jt = new_array(nt, n, &jt)) == NULL
        || (o_jf = new_array(nd, n, &jf)) == NULL || (o_at = new_array(na, nt, &at)) == NULL
        || (o_cc = new_array(n, 0, &cc)) == NULL)
        goto done;
    const int found = post_kernel(mp, nle, jac, k, (long)k_len, mi, jt, jf, at, cc);
    if (found < 0) {
        PyErr_SetString(PyExc_ValueError, "post: the constants vector does not fit its header or the jacobians");
        goto done;
    }
    if (found == 0) {
        result = Py_None;
        Py_INCREF(result);
        goto done;
    }
    result = PyTuple_Pack(5, o_mi, o_jt, o_jf, o_at, o_cc);
done:
    Py_XDECREF(o_mi);
    Py_XDECREF(o_jt);
    Py_XDECREF(o_jf);
    Py_XDECREF(o_at);
    Py_XDECREF(o_cc);
    Py_XDECREF(mv.array);
    Py_XDECREF(cv.array);
    for (int d = 0; d < nd; d++) Py_XDECREF(jv[d].array);
    return result;

bad_constants:
    PyErr_SetString(PyExc_ValueError, "post: the constants vector does not fit its header or the jacobians");
    return NULL;
}

static const FprAttitudeApi attitude_api = {FPR_KERNELS_VERSION, post_kernel};

static PyMethodDef methods[] = {
    {"post", post, METH_VARARGS, "The attitude model from Pinocchio's outputs (see the module's C source)."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "fpr._native._attitude",
                                    "Robot.attitude_model's numpy part in C (fpr.model.robot).",
                                    -1, methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__attitude(void)
{
    import_array();
    PyObject *mod = PyModule_Create(&module);
    if (mod == NULL) return NULL;
    PyModule_AddIntConstant(mod, "MAX_COORDINATES", MAX_V);
    PyModule_AddIntConstant(mod, "MAX_DRONES", MAX_D);
    PyObject *capsule = PyCapsule_New((void *)&attitude_api, "fpr._native._attitude._C_API", NULL);
    if (capsule == NULL || PyModule_AddObject(mod, "_C_API", capsule) < 0) {
        Py_XDECREF(capsule);
        Py_DECREF(mod);
        return NULL;
    }
    return mod;
}
