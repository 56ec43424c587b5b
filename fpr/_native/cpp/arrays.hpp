// Small helpers of the Python bindings (module.cpp, measure_module.cpp): numpy arrays in and out, argument
// checks. Included after numpy/arrayobject.h, whose API the including file sets up (PY_ARRAY_UNIQUE_SYMBOL).
#pragma once

#include <algorithm>
#include <vector>

namespace fpr_native
{
  namespace arrays
  {
  // A float64 C-contiguous array of obj with `size` entries (a new reference: obj itself when it is one), or
  // nullptr with a ValueError naming `what`.
  inline PyArrayObject * input(PyObject * obj, npy_intp size, const char * what)
  {
    PyArrayObject * a = reinterpret_cast<PyArrayObject *>(
      PyArray_FROMANY(obj, NPY_DOUBLE, 0, 0, NPY_ARRAY_IN_ARRAY));
    if (a != nullptr && size >= 0 && PyArray_SIZE(a) != size)
    {
      PyErr_Format(PyExc_ValueError, "%s: expected %zd values, got %zd", what, (Py_ssize_t)size,
                   (Py_ssize_t)PyArray_SIZE(a));
      Py_CLEAR(a);
    }
    return a;
  }

  // A new float64 array of the given shape (a copy of `from` when given), or nullptr.
  inline PyArrayObject * output(int ndim, const npy_intp * dims, const double * from = nullptr)
  {
    PyArrayObject * a = reinterpret_cast<PyArrayObject *>(PyArray_SimpleNew(ndim, dims, NPY_DOUBLE));
    if (a != nullptr && from != nullptr)
      std::copy(from, from + PyArray_SIZE(a), static_cast<double *>(PyArray_DATA(a)));
    return a;
  }

  inline double * data(PyArrayObject * a)
  {
    return static_cast<double *>(PyArray_DATA(a));
  }

  // A list of ints from a sequence, or false with an exception set.
  inline bool int_list(PyObject * sequence, std::vector<int> & out, const char * what)
  {
    PyObject * fast = PySequence_Fast(sequence, what);
    if (fast == nullptr)
      return false;
    const Py_ssize_t n = PySequence_Fast_GET_SIZE(fast);
    for (Py_ssize_t k = 0; k < n; ++k)
    {
      const long value = PyLong_AsLong(PySequence_Fast_GET_ITEM(fast, k));
      if (value == -1 && PyErr_Occurred())
      {
        Py_DECREF(fast);
        return false;
      }
      out.push_back((int)value);
    }
    Py_DECREF(fast);
    return true;
  }

  inline bool check_arguments(const char * name, Py_ssize_t nargs, Py_ssize_t least, Py_ssize_t most)
  {
    if (nargs < least || nargs > most)
    {
      PyErr_Format(PyExc_TypeError, "%s takes %zd to %zd arguments (%zd given)", name, least, most, nargs);
      return false;
    }
    return true;
  }
  } // namespace arrays
} // namespace fpr_native
