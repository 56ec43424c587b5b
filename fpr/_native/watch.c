/* The watch's screen (fpr/sim/watch.py, Watch._may_be_lost_python) in C: the same comparisons on
 * the same numbers, without the interpreter's cost of a few dozen float operations at every inner-loop tick.
 *
 * may_be_lost(qc, vc, q, v, positions, closure_error, planned, constants) -> bool
 *   qc, vc: the plant's state; q, v: the measured state; positions: the drones' centres (n_d, 3) [m];
 *   closure_error [m]; planned: the planned chain coordinates (n_s,).
 *   constants (Watch._screen_constants, one contiguous float64 vector): floor, closure bound, speed^2,
 *   rate^2, the lowest tilt cosine (NaN: no tilt screen), the tracking bound -- each already moved towards
 *   the safe side as the Python screen moves it --, n_f, n_s, then per free flyer (iq, iv, ax, ay, az), then
 *   the chain's indices in q (n_s).
 *   True when any entry of qc, vc, q, v is not finite, or a bound is crossed: the full check then decides.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <math.h>

#include "dense.h"  /* constants_of */
#include "kernels.h"  /* FprWatchApi: the kernel for the native loop */

#define HEADER 8

/* A contiguous float64 vector (or matrix) of obj, or NULL (an exception set) */
static PyArrayObject *vector(PyObject *obj)
{
    return (PyArrayObject *)PyArray_FROM_OTF(obj, NPY_DOUBLE, NPY_ARRAY_IN_ARRAY);
}

static int all_finite(const double *d, long n)
{
    for (long i = 0; i < n; i++)
        if (!isfinite(d[i])) return 0;
    return 1;
}

/* The screen on plain arrays (the kernel of `may_be_lost`, also the native loop's through the module's capsule,
 * kernels.h): 1 when the robot may be lost, 0 when not, -1 when the constants do not fit the state. */
static int screen_kernel(const double *qc, long nqc, const double *vc, long nvc, const double *q, const double *v,
                         long nq, const double *pos, long nd, double closure_error, const double *planned, long ns_in,
                         const double *k, long k_len)
{
    if (k_len < HEADER) return -1;
    const double floor = k[0], closure = k[1], speed = k[2], rate = k[3], lowest = k[4], bound = k[5];
    const int nf = (int)k[6], ns = (int)k[7];
    if (k_len != HEADER + 5 * nf + ns || ns_in != ns) return -1;
    const double *flyers = k + HEADER, *chain = flyers + 5 * nf;
    for (int f = 0; f < nf; f++) {
        const long iq = (long)flyers[5 * f], iv = (long)flyers[5 * f + 1];
        if (iq < 0 || iq + 7 > nqc || iv < 0 || iv + 6 > nvc) return -1;
    }
    for (int i = 0; i < ns; i++)
        if (!(chain[i] >= 0 && chain[i] < nq)) return -1;
    if (!all_finite(qc, nqc) || !all_finite(vc, nvc) || !all_finite(q, nq) || !all_finite(v, nq)) return 1;
    for (int f = 0; f < nf; f++)
        if (qc[(long)flyers[5 * f] + 2] < floor) return 1;  /* hinge heights */
    for (long d = 0; d < nd; d++)
        if (pos[3 * d + 2] < floor) return 1;  /* centres of mass */
    if (!(closure_error <= closure)) return 1;
    for (int f = 0; f < nf; f++) {
        const double *w = vc + (long)flyers[5 * f + 1];
        if (w[0] * w[0] + w[1] * w[1] + w[2] * w[2] > speed || w[3] * w[3] + w[4] * w[4] + w[5] * w[5] > rate)
            return 1;
    }
    if (!isnan(lowest))
        for (int f = 0; f < nf; f++) {
            const double *o = qc + (long)flyers[5 * f] + 3, ax = flyers[5 * f + 2], ay = flyers[5 * f + 3],
                         az = flyers[5 * f + 4];
            const double x = o[0], y = o[1], z = o[2], w = o[3];
            const double norm2 = x * x + y * y + z * z + w * w;
            const double cosine = (2 * (x * z - w * y) * ax + 2 * (y * z + w * x) * ay) / norm2
                                   + (1 - 2 * (x * x + y * y) / norm2) * az;
            if (!(cosine >= lowest)) return 1;  /* NaN (a zero quaternion) too: the full check decides */
        }
    for (int i = 0; i < ns; i++)
        if (fabs(q[(long)chain[i]] - planned[i]) > bound) return 1;
    return 0;
}

static PyObject *may_be_lost(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *o[8];
    double closure_error;
    if (!PyArg_ParseTuple(args, "OOOOOdOO", &o[0], &o[1], &o[2], &o[3], &o[4], &closure_error, &o[5], &o[6]))
        return NULL;
    npy_intp k_len = 0;
    const double *k = constants_of(o[6], &k_len);
    if (k == NULL || k_len < HEADER) {
        PyErr_SetString(PyExc_TypeError, "may_be_lost: constants must be a contiguous float64 vector");
        return NULL;
    }
    PyArrayObject *a[6] = {NULL};
    int answer = -1;
    for (int i = 0; i < 6; i++)
        if ((a[i] = vector(o[i])) == NULL) goto done;
    if (PyArray_NDIM(a[4]) != 2 || PyArray_DIM(a[4], 1) != 3 || PyArray_SIZE(a[3]) != PyArray_SIZE(a[2])) {
        PyErr_SetString(PyExc_ValueError, "may_be_lost: the constants do not fit the state");
        goto done;
    }
#define D(i) ((const double *)PyArray_DATA(a[i]))
    answer = screen_kernel(D(0), (long)PyArray_SIZE(a[0]), D(1), (long)PyArray_SIZE(a[1]), D(2), D(3),
                           (long)PyArray_SIZE(a[2]), D(4), (long)PyArray_DIM(a[4], 0), closure_error, D(5),
                           (long)PyArray_SIZE(a[5]), k, (long)k_len);
#undef D
    if (answer < 0) PyErr_SetString(PyExc_ValueError, "may_be_lost: the constants do not fit the state");
done:
    for (int i = 0; i < 6; i++) Py_XDECREF(a[i]);
    if (answer < 0) return NULL;
    return PyBool_FromLong(answer);
}

static const FprWatchApi watch_api = {FPR_KERNELS_VERSION, screen_kernel};

static PyMethodDef methods[] = {
    {"may_be_lost", may_be_lost, METH_VARARGS, "The watch's screen (see the module's C source): a bool."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "fpr._native._watch",
                                    "The closed loop's watch screen in C (fpr.sim.watch).",
                                    -1, methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__watch(void)
{
    import_array();
    PyObject *mod = PyModule_Create(&module);
    if (mod == NULL) return NULL;
    PyObject *capsule = PyCapsule_New((void *)&watch_api, "fpr._native._watch._C_API", NULL);
    if (capsule == NULL || PyModule_AddObject(mod, "_C_API", capsule) < 0) {
        Py_XDECREF(capsule);
        Py_DECREF(mod);
        return NULL;
    }
    return mod;
}
