/* Small dense helpers shared by the compiled parts of the closed loop's tick (controllers/_alloc.c,
 * fpr/model/_attitude.c, fpr/model/_multibody.c, fpr/sim/_watch.c): the constants vectors the Python side builds,
 * float64 views of numpy arrays of any strides, and a Cholesky factor and solve (the same loops, so the same
 * bits, wherever they run). Included after Python.h and numpy's arrayobject.h, not linked: each extension gets
 * its own static copy. */
#ifndef FPR_DENSE_H
#define FPR_DENSE_H

#include <math.h>

typedef struct {
    PyArrayObject *array;
    const char *data;
    npy_intp rows, cols, s0, s1;
} View;

/* The data of a constants vector (float64, aligned, native byte order, C-contiguous: as the Python side builds
 * them) and its length into *len; NULL, with no error set, when obj is not one. */
static inline const double *constants_of(PyObject *obj, npy_intp *len)
{
    if (!PyArray_Check(obj) || PyArray_TYPE((PyArrayObject *)obj) != NPY_DOUBLE
        || !PyArray_ISCARRAY_RO((PyArrayObject *)obj))
        return NULL;
    *len = PyArray_SIZE((PyArrayObject *)obj);
    return (const double *)PyArray_DATA((PyArrayObject *)obj);
}

/* A float64 view of obj with `ndim` dimensions (1: a row vector of `cols`); 0 on a wrong type or shape. */
static inline int view(PyObject *obj, int ndim, View *v)
{
    v->array = (PyArrayObject *)PyArray_FROM_OTF(obj, NPY_DOUBLE, NPY_ARRAY_ALIGNED);
    if (v->array == NULL) return 0;
    if (PyArray_NDIM(v->array) != ndim) {
        PyErr_Format(PyExc_ValueError, "expected a %d-d array", ndim);
        Py_CLEAR(v->array);
        return 0;
    }
    v->data = PyArray_BYTES(v->array);
    if (ndim == 2) {
        v->rows = PyArray_DIM(v->array, 0);
        v->cols = PyArray_DIM(v->array, 1);
        v->s0 = PyArray_STRIDE(v->array, 0);
        v->s1 = PyArray_STRIDE(v->array, 1);
    } else {
        v->rows = 1;
        v->cols = PyArray_DIM(v->array, 0);
        v->s0 = 0;
        v->s1 = PyArray_STRIDE(v->array, 0);
    }
    return 1;
}

#define AT(v, i, j) (*(const double *)((v).data + (i) * (v).s0 + (j) * (v).s1))

/* Cholesky A = R^T R of the k x k matrix a (leading dimension lda), its upper triangle read as LAPACK's posv;
 * R's upper triangle into r (leading dimension k). 0 when not positive definite. */
static inline int cholesky(const double *a, int lda, int k, double *r)
{
    for (int j = 0; j < k; j++) {
        double d = a[j * lda + j];
        for (int p = 0; p < j; p++) d -= r[p * k + j] * r[p * k + j];
        if (!(d > 0.0)) return 0;
        double rjj = sqrt(d);
        r[j * k + j] = rjj;
        for (int i = j + 1; i < k; i++) {
            double s = a[j * lda + i];
            for (int p = 0; p < j; p++) s -= r[p * k + j] * r[p * k + i];
            r[j * k + i] = s / rjj;
        }
    }
    return 1;
}

/* x (in place) := (R^T R)^-1 x, R from cholesky (k x k). */
static inline void cholesky_solve(const double *r, int k, double *x)
{
    for (int i = 0; i < k; i++) {
        double s = x[i];
        for (int p = 0; p < i; p++) s -= r[p * k + i] * x[p];
        x[i] = s / r[i * k + i];
    }
    for (int i = k - 1; i >= 0; i--) {
        double s = x[i];
        for (int p = i + 1; p < k; p++) s -= r[i * k + p] * x[p];
        x[i] = s / r[i * k + i];
    }
}

#endif
