/* Jet products of fpr/model/jets.py in C: the Leibniz sums of products of time-derivative jets, and
 * the recurrence of a jet's linear solve, one loop over every sample instead of numpy's per-order, per-term
 * passes over small matrices (numpy spends about 40 ns per 4 x 4 matrix-vector product of a batch; the
 * planner's complex-step batches hold thousands).
 *
 * product(a, b, out, S, Sa, Sb, n, m, k)
 *   a: (Ka+1, Sa, n, m), b: (Kb+1, Sb, m, k), out: (K+1, S, n, k), all C-contiguous, all float64 or all
 *   complex128. Batch index s of out reads a's s % Sa and b's s % Sb (numpy's broadcasting when a batch shape is
 *   a suffix of out's). out[p] = sum_q C(p, q) a[q] @ b[p - q], q over max(0, p - Kb)..min(p, Ka).
 *   (Elementwise products stay with numpy: its SIMD loops beat a scalar C loop.)
 * solve(inv, a, b, out, S, Si, Sa, Sb, n, k)
 *   inv: (Si, n, n) the inverse of the value of A, a: (Ka+1, Sa, n, n) A's jet, b: (Kb+1, Sb, n, k),
 *   out: (K+1, S, n, k): x[p] = inv @ (b[p] - sum_{q=1..p} C(p, q) a[q] @ x[p - q]) (b[p] = 0 beyond Kb), the
 *   jet of A^-1 b.
 * gauss_jordan(a, b, out, S, n, k) -> bool
 *   a: (S, n, n), b: (S, n, k) or None (the identity: k = n), out: (S, n, k), float64: out[s] = a[s]^-1 b[s] by
 *   Gauss-Jordan elimination with partial pivoting (LAPACK's getrf pivots the same way; the results agree to
 *   round-off). False, out unfinished, when a pivot is exactly 0 (a singular matrix): the caller then asks
 *   numpy, which raises as it does.
 * product and solve return None; all raise ValueError on arrays that do not match (the Python side checks
 * first: jets.py).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <math.h>

#define MAX_K 16      /* derivative orders, as jets._MAXK */
#define MAX_DIM 32    /* n, m, k of a matrix */

static double binomial[MAX_K + 1][MAX_K + 1];

typedef struct {
    PyArrayObject *array;
    char *data;
    npy_intp size;
} Operand;

/* obj as an operand of `cplx` type (0 float64, 1 complex128), C-contiguous and aligned; 0 with an error. */
static int operand(PyObject *obj, int cplx, Operand *o)
{
    int type = cplx ? NPY_CDOUBLE : NPY_DOUBLE;
    if (!PyArray_Check(obj) || PyArray_TYPE((PyArrayObject *)obj) != type
        || !PyArray_ISCARRAY((PyArrayObject *)obj)) {
        PyErr_SetString(PyExc_ValueError, "_jets: operands must be C-contiguous arrays of one type "
                                          "(float64 or complex128)");
        return 0;
    }
    o->array = (PyArrayObject *)obj;
    o->data = PyArray_BYTES(o->array);
    o->size = PyArray_SIZE(o->array);
    return 1;
}

/* The number of orders of an operand of `block` elements per sample and S samples: size / (S block), or -1
 * when that does not divide or exceeds MAX_K + 1. */
static int orders(const Operand *o, npy_intp samples, npy_intp block)
{
    npy_intp per = samples * block;
    if (per <= 0 || o->size % per) return -1;
    npy_intp count = o->size / per;
    return (count >= 1 && count <= MAX_K + 1) ? (int)count : -1;
}

static int dims_ok(npy_intp n, npy_intp m, npy_intp k)
{
    return n >= 1 && m >= 1 && k >= 1 && n <= MAX_DIM && m <= MAX_DIM && k <= MAX_DIM;
}

/* o = x @ y (assign) or o += c x @ y, for x (n, m) and y (m, k) row-major: real, or complex (interleaved re, im). */
static inline void block_real(const double *x, const double *y, double *o, int n, int m, int k, double c,
                              int assign)
{
    for (int i = 0; i < n; i++)
        for (int j = 0; j < k; j++) {
            double acc = 0.0;
            for (int l = 0; l < m; l++) acc += x[i * m + l] * y[l * k + j];
            if (assign) o[i * k + j] = acc;
            else o[i * k + j] += c * acc;
        }
}

static inline void block_complex(const double *x, const double *y, double *o, int n, int m, int k, double c,
                                 int assign)
{
    for (int i = 0; i < n; i++)
        for (int j = 0; j < k; j++) {
            double re = 0.0, im = 0.0;
            for (int l = 0; l < m; l++) {
                const double *u = x + 2 * (i * m + l), *v = y + 2 * (l * k + j);
                re += u[0] * v[0] - u[1] * v[1];
                im += u[0] * v[1] + u[1] * v[0];
            }
            double *w = o + 2 * (i * k + j);
            if (assign) { w[0] = re; w[1] = im; }
            else { w[0] += c * re; w[1] += c * im; }
        }
}

/* The kernels below count in numbers: w = 1 (real) or 2 (complex) doubles each. */
static void product(const double *a, const double *b, double *out, npy_intp S, npy_intp Sa, npy_intp Sb, int ka,
                    int kb, int K, int n, int m, int k, int w)
{
    npy_intp ba = (npy_intp)n * m * w, bb = (npy_intp)m * k * w, bo = (npy_intp)n * k * w;
    for (int p = 0; p <= K; p++) {
        int q0 = p - kb > 0 ? p - kb : 0, q1 = p < ka ? p : ka;
        for (npy_intp s = 0; s < S; s++) {
            npy_intp ia = Sa == S ? s : s % Sa, ib = Sb == S ? s : s % Sb;
            double *o = out + ((npy_intp)p * S + s) * bo;
            for (npy_intp r = 0; r < bo; r++) o[r] = 0.0;
            for (int q = q0; q <= q1; q++) {
                const double *x = a + ((npy_intp)q * Sa + ia) * ba, *y = b + ((npy_intp)(p - q) * Sb + ib) * bb;
                if (w == 2) block_complex(x, y, o, n, m, k, binomial[p][q], 0);
                else block_real(x, y, o, n, m, k, binomial[p][q], 0);
            }
        }
    }
}

static void solve(const double *inv, const double *a, const double *b, double *out, npy_intp S, npy_intp Si,
                  npy_intp Sa, npy_intp Sb, int ka, int kb, int K, int n, int k, int w)
{
    double r[2 * MAX_DIM * MAX_DIM];
    npy_intp bo = (npy_intp)n * k * w, bm = (npy_intp)n * n * w;
    for (npy_intp s = 0; s < S; s++) {
        npy_intp ig = s % Si, ia = s % Sa, ib = s % Sb;
        for (int p = 0; p <= K; p++) {
            const double *y = p <= kb ? b + ((npy_intp)p * Sb + ib) * bo : NULL;
            for (npy_intp e = 0; e < bo; e++) r[e] = y ? y[e] : 0.0;
            for (int q = 1; q <= p && q <= ka; q++) {
                const double *x = a + ((npy_intp)q * Sa + ia) * bm, *z = out + ((npy_intp)(p - q) * S + s) * bo;
                if (w == 2) block_complex(x, z, r, n, n, k, -binomial[p][q], 0);
                else block_real(x, z, r, n, n, k, -binomial[p][q], 0);
            }
            double *o = out + ((npy_intp)p * S + s) * bo;
            if (w == 2) block_complex(inv + ig * bm, r, o, n, n, k, 1.0, 1);
            else block_real(inv + ig * bm, r, o, n, n, k, 1.0, 1);
        }
    }
}

/* ------------------------------------------------------------------ inverse and solve */
/* out[s] = a[s]^-1 b[s] (b NULL: the identity, out (S, n, n); else b and out (S, n, k)) by Gauss-Jordan elimination
 * with partial pivoting; 0, out unfinished, at an exactly zero pivot. */
static int gauss_jordan(const double *a, const double *b, double *out, npy_intp S, int n, int k)
{
    double w[MAX_DIM * 2 * MAX_DIM];
    int cols = n + k;
    for (npy_intp s = 0; s < S; s++) {
        const double *x = a + s * n * n, *y = b ? b + s * n * k : NULL;
        for (int i = 0; i < n; i++) {
            for (int j = 0; j < n; j++) w[i * cols + j] = x[i * n + j];
            for (int j = 0; j < k; j++) w[i * cols + n + j] = y ? y[i * k + j] : (i == j ? 1.0 : 0.0);
        }
        for (int c = 0; c < n; c++) {
            int pivot = c;
            for (int i = c + 1; i < n; i++)
                if (fabs(w[i * cols + c]) > fabs(w[pivot * cols + c])) pivot = i;
            if (w[pivot * cols + c] == 0.0) return 0;
            if (pivot != c)
                for (int j = 0; j < cols; j++) {
                    double t = w[c * cols + j];
                    w[c * cols + j] = w[pivot * cols + j];
                    w[pivot * cols + j] = t;
                }
            double d = w[c * cols + c];
            for (int j = 0; j < cols; j++) w[c * cols + j] /= d;
            for (int i = 0; i < n; i++) {
                if (i == c) continue;
                double f = w[i * cols + c];
                if (f == 0.0) continue;
                for (int j = 0; j < cols; j++) w[i * cols + j] -= f * w[c * cols + j];
            }
        }
        double *o = out + s * n * k;
        for (int i = 0; i < n; i++)
            for (int j = 0; j < k; j++) o[i * k + j] = w[i * cols + n + j];
    }
    return 1;
}

/* ------------------------------------------------------------------ Python */
static int batch_ok(npy_intp S, npy_intp part)
{
    return part >= 1 && S >= 1 && S % part == 0;
}

static PyObject *py_product(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *oa, *ob, *oo;
    Py_ssize_t S, Sa, Sb, n, m, k;
    if (!PyArg_ParseTuple(args, "OOOnnnnnn", &oa, &ob, &oo, &S, &Sa, &Sb, &n, &m, &k)) return NULL;
    if (!PyArray_Check(oo)) {
        PyErr_SetString(PyExc_ValueError, "product: out must be an array");
        return NULL;
    }
    int cplx = PyArray_TYPE((PyArrayObject *)oo) == NPY_CDOUBLE;
    Operand a, b, o;
    if (!operand(oa, cplx, &a) || !operand(ob, cplx, &b) || !operand(oo, cplx, &o)) return NULL;
    if (!dims_ok(n, m, k) || !batch_ok(S, Sa) || !batch_ok(S, Sb)) {
        PyErr_SetString(PyExc_ValueError, "product: sizes out of range");
        return NULL;
    }
    int ka = orders(&a, Sa, n * m) - 1, kb = orders(&b, Sb, m * k) - 1, K = orders(&o, S, n * k) - 1;
    if (ka < 0 || kb < 0 || K < 0 || K > ka + kb) {
        PyErr_SetString(PyExc_ValueError, "product: operand sizes do not match the batch and block sizes");
        return NULL;
    }
    Py_BEGIN_ALLOW_THREADS
    product((const double *)a.data, (const double *)b.data, (double *)o.data, S, Sa, Sb, ka, kb, K, (int)n,
            (int)m, (int)k, cplx ? 2 : 1);
    Py_END_ALLOW_THREADS
    Py_RETURN_NONE;
}

static PyObject *py_solve(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *oi, *oa, *ob, *oo;
    Py_ssize_t S, Si, Sa, Sb, n, k;
    if (!PyArg_ParseTuple(args, "OOOOnnnnnn", &oi, &oa, &ob, &oo, &S, &Si, &Sa, &Sb, &n, &k)) return NULL;
    if (!PyArray_Check(oo)) {
        PyErr_SetString(PyExc_ValueError, "solve: out must be an array");
        return NULL;
    }
    int cplx = PyArray_TYPE((PyArrayObject *)oo) == NPY_CDOUBLE;
    Operand g, a, b, o;
    if (!operand(oi, cplx, &g) || !operand(oa, cplx, &a) || !operand(ob, cplx, &b)
        || !operand(oo, cplx, &o))
        return NULL;
    if (!dims_ok(n, n, k) || !batch_ok(S, Si) || !batch_ok(S, Sa) || !batch_ok(S, Sb) || g.size != Si * n * n) {
        PyErr_SetString(PyExc_ValueError, "solve: sizes out of range");
        return NULL;
    }
    int ka = orders(&a, Sa, n * n) - 1, kb = orders(&b, Sb, n * k) - 1, K = orders(&o, S, n * k) - 1;
    if (ka < 0 || kb < 0 || K < 0) {
        PyErr_SetString(PyExc_ValueError, "solve: operand sizes do not match the batch and block sizes");
        return NULL;
    }
    Py_BEGIN_ALLOW_THREADS
    solve((const double *)g.data, (const double *)a.data, (const double *)b.data, (double *)o.data, S, Si, Sa, Sb,
          ka, kb, K, (int)n, (int)k, cplx ? 2 : 1);
    Py_END_ALLOW_THREADS
    Py_RETURN_NONE;
}

static PyObject *py_gauss_jordan(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *oa, *ob, *oo;
    Py_ssize_t S, n, k;
    if (!PyArg_ParseTuple(args, "OOOnnn", &oa, &ob, &oo, &S, &n, &k)) return NULL;
    Operand a, b = {NULL, NULL, 0}, o;
    if (!operand(oa, 0, &a) || (ob != Py_None && !operand(ob, 0, &b)) || !operand(oo, 0, &o)) return NULL;
    if (ob == Py_None && k != n) {
        PyErr_SetString(PyExc_ValueError, "gauss_jordan: an inverse has k = n");
        return NULL;
    }
    if (n < 1 || n > MAX_DIM || k < 1 || k > MAX_DIM || S < 1 || a.size != S * n * n || o.size != S * n * k
        || (ob != Py_None && b.size != S * n * k)) {
        PyErr_SetString(PyExc_ValueError, "gauss_jordan: sizes do not match");
        return NULL;
    }
    int ok;
    Py_BEGIN_ALLOW_THREADS
    ok = gauss_jordan((const double *)a.data, ob == Py_None ? NULL : (const double *)b.data, (double *)o.data, S,
                      (int)n, (int)k);
    Py_END_ALLOW_THREADS
    return PyBool_FromLong(ok);
}

static PyMethodDef methods[] = {
    {"gauss_jordan", py_gauss_jordan, METH_VARARGS, "A^-1 b (b None: A^-1) of small matrices into out, or False."},
    {"product", py_product, METH_VARARGS, "Leibniz sum of jet products into out (see the C source)."},
    {"solve", py_solve, METH_VARARGS, "The jet of A^-1 b into out (see the C source)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "fpr._native._jets",
                                    "Jet products and solves of fpr/model/jets.py in C.",
                                    -1, methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__jets(void)
{
    import_array();
    for (int p = 0; p <= MAX_K; p++) {
        binomial[p][0] = 1.0;
        for (int q = 1; q <= p; q++) binomial[p][q] = binomial[p][q - 1] * (double)(p - q + 1) / (double)q;
    }
    return PyModule_Create(&module);
}
