// fpr._native._pinocchio's type Measure (module.cpp registers it): the closed loop's measurement (measure.cpp).
//
// Measure(model, data, minimal, nqp, closed_q, source, sign, eulers, angles, T_inv, angular): the measurement on
//   the closed chain's model and data; eulers: (joint, A 4x4, B 4x4, (x, y, z qp indices or -1), (psi, theta, phi
//   qp indices), (their thesis indices)) tuples; angles: (joint, P 4x4, other, qp index)
//   measure(qc, vc, reference) -> (q, v), or None when the velocity's normal equations are not positive definite
#define PY_SSIZE_T_CLEAN
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#define PY_ARRAY_UNIQUE_SYMBOL fpr_native_ARRAY_API
#define NO_IMPORT_ARRAY
#include "native.hpp"

#include <numpy/arrayobject.h>

#include "arrays.hpp"

#include <algorithm>
#include <exception>
#include <string>
#include <vector>

namespace
{
  using namespace fpr_native;
  using namespace fpr_native::arrays;

  // ------------------------------------------------------------------ Measure
  struct MeasureObject
  {
    PyObject_HEAD Measure * measure;
    PyObject * keep;
  };

  void measure_dealloc(PyObject * self)
  {
    auto * p = reinterpret_cast<MeasureObject *>(self);
    measure_delete(p->measure);
    Py_XDECREF(p->keep);
    Py_TYPE(self)->tp_free(self);
  }

  bool homogeneous(PyObject * obj, double * out, const char * what)
  {
    PyArrayObject * a = input(obj, 16, what);
    if (a == nullptr)
      return false;
    std::copy(data(a), data(a) + 16, out);
    Py_DECREF(a);
    return true;
  }

  bool euler_reads(PyObject * sequence, std::vector<EulerRead> & out)
  {
    PyObject * fast = PySequence_Fast(sequence, "eulers: expected a sequence of tuples");
    if (fast == nullptr)
      return false;
    bool ok = true;
    for (Py_ssize_t k = 0; ok && k < PySequence_Fast_GET_SIZE(fast); ++k)
    {
      EulerRead e;
      PyObject *a, *b;
      ok = PyArg_ParseTuple(PySequence_Fast_GET_ITEM(fast, k), "iOO(iii)(iii)(iii)", &e.joint, &a, &b,
                            &e.translation[0], &e.translation[1], &e.translation[2], &e.euler[0], &e.euler[1],
                            &e.euler[2], &e.reference[0], &e.reference[1], &e.reference[2])
           && homogeneous(a, e.A, "eulers: A") && homogeneous(b, e.B, "eulers: B");
      if (ok)
        out.push_back(e);
    }
    Py_DECREF(fast);
    return ok;
  }

  bool angle_reads(PyObject * sequence, std::vector<AngleRead> & out)
  {
    PyObject * fast = PySequence_Fast(sequence, "angles: expected a sequence of tuples");
    if (fast == nullptr)
      return false;
    bool ok = true;
    for (Py_ssize_t k = 0; ok && k < PySequence_Fast_GET_SIZE(fast); ++k)
    {
      AngleRead a;
      PyObject * p;
      ok = PyArg_ParseTuple(PySequence_Fast_GET_ITEM(fast, k), "iOii", &a.joint, &p, &a.other, &a.index)
           && homogeneous(p, a.P, "angles: P");
      if (ok)
        out.push_back(a);
    }
    Py_DECREF(fast);
    return ok;
  }

  bool double_list(PyObject * sequence, std::vector<double> & out, const char * what)
  {
    PyArrayObject * a = input(sequence, -1, what);
    if (a == nullptr)
      return false;
    out.assign(data(a), data(a) + PyArray_SIZE(a));
    Py_DECREF(a);
    return true;
  }

  int measure_init(PyObject * self, PyObject * args, PyObject * kwargs)
  {
    auto * p = reinterpret_cast<MeasureObject *>(self);
    static const char * names[] = {"model",  "data",   "minimal", "nqp",   "closed_q", "source", "sign",
                                   "eulers", "angles", "T_inv",   "angular", nullptr};
    PyObject *model, *data_obj, *minimal_obj, *closed_obj, *source_obj, *sign_obj, *eulers_obj, *angles_obj,
      *t_obj, *angular_obj;
    int nqp = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OOOiOOOOOOO", const_cast<char **>(names), &model, &data_obj,
                                     &minimal_obj, &nqp, &closed_obj, &source_obj, &sign_obj, &eulers_obj,
                                     &angles_obj, &t_obj, &angular_obj))
      return -1;
    Minimal * minimal = minimal_from(minimal_obj, "minimal");
    if (minimal == nullptr)
      return -1;
    try
    {
      Objects objects;
      std::string error;
      if (!extract(model, data_obj, Py_None, Py_None, Py_None, objects, error))
      {
        PyErr_SetString(PyExc_TypeError, error.c_str());
        return -1;
      }
      std::vector<int> closed_q, source, angular;
      std::vector<double> sign;
      std::vector<EulerRead> eulers;
      std::vector<AngleRead> angles;
      if (!int_list(closed_obj, closed_q, "closed_q: expected a sequence of indices")
          || !int_list(source_obj, source, "source: expected a sequence of indices")
          || !double_list(sign_obj, sign, "sign") || !euler_reads(eulers_obj, eulers)
          || !angle_reads(angles_obj, angles) || !int_list(angular_obj, angular, "angular: expected indices"))
        return -1;
      PyArrayObject * T = input(t_obj, -1, "T_inv");
      if (T == nullptr)
        return -1;
      Measure * measure = nullptr;
      if (PyArray_NDIM(T) != 2 || PyArray_DIM(T, 1) != nqp)
        error = "T_inv must be (n, nqp)";
      else
        measure = measure_new(objects, minimal, nqp, closed_q, source, sign, eulers, angles, data(T),
                              (int)PyArray_DIM(T, 0), angular, error);
      Py_DECREF(T);
      if (measure == nullptr)
      {
        PyErr_SetString(PyExc_ValueError, error.c_str());
        return -1;
      }
      measure_delete(p->measure);
      p->measure = measure;
      Py_XDECREF(p->keep);
      p->keep = PyTuple_Pack(3, model, data_obj, minimal_obj);
      return p->keep == nullptr ? -1 : 0;
    }
    catch (const std::exception & e)
    {
      PyErr_SetString(PyExc_RuntimeError, e.what());
      return -1;
    }
  }

  PyObject * measure_py(PyObject * self, PyObject * const * args, Py_ssize_t nargs)
  {
    Measure * m = reinterpret_cast<MeasureObject *>(self)->measure;
    if (m == nullptr)
    {
      PyErr_SetString(PyExc_RuntimeError, "Measure: not initialised");
      return nullptr;
    }
    if (!check_arguments("measure", nargs, 3, 3))
      return nullptr;
    const int n = measure_n(m);
    PyArrayObject *qc = input(args[0], measure_nq(m), "qc"), *vc = qc ? input(args[1], measure_nv(m), "vc") : nullptr,
                  *ref = vc ? input(args[2], n, "reference") : nullptr;
    PyObject * result = nullptr;
    if (ref != nullptr)
    {
      npy_intp dims[1] = {n};
      PyArrayObject *q = output(1, dims), *v = output(1, dims);
      if (q != nullptr && v != nullptr)
      {
        try
        {
          result = measure(m, data(qc), data(vc), data(ref), data(q), data(v)) ? Py_BuildValue("OO", q, v)
                                                                                : Py_NewRef(Py_None);
        }
        catch (const std::exception & e)
        {
          PyErr_SetString(PyExc_RuntimeError, e.what());
        }
      }
      Py_XDECREF(q);
      Py_XDECREF(v);
    }
    Py_XDECREF(qc);
    Py_XDECREF(vc);
    Py_XDECREF(ref);
    return result;
  }

  PyMethodDef measure_methods[] = {
    {"measure", reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(measure_py)), METH_FASTCALL,
     "(q, v) in thesis coordinates at (qc, vc), angles within pi of the reference; None: the Python path decides."},
    {nullptr, nullptr, 0, nullptr}};

  PyType_Slot measure_slots[] = {
    {Py_tp_doc, const_cast<char *>("The closed loop's measurement (fpr/_native/cpp/module.cpp).")},
    {Py_tp_new, reinterpret_cast<void *>(PyType_GenericNew)},
    {Py_tp_init, reinterpret_cast<void *>(measure_init)},
    {Py_tp_dealloc, reinterpret_cast<void *>(measure_dealloc)},
    {Py_tp_methods, measure_methods},
    {0, nullptr}};

  PyType_Spec measure_spec = {"fpr._native._pinocchio.Measure", sizeof(MeasureObject), 0, Py_TPFLAGS_DEFAULT,
                              measure_slots};

  PyObject * measure_type = nullptr; // borrowed: the module holds it

} // namespace

namespace fpr_native
{
  Measure * measure_from(PyObject * obj, const char * what)
  {
    if (measure_type == nullptr || !PyObject_TypeCheck(obj, reinterpret_cast<PyTypeObject *>(measure_type)))
    {
      PyErr_Format(PyExc_TypeError, "%s: expected a fpr._native._pinocchio.Measure", what);
      return nullptr;
    }
    Measure * m = reinterpret_cast<MeasureObject *>(obj)->measure;
    if (m == nullptr)
      PyErr_SetString(PyExc_RuntimeError, "Measure: not initialised");
    return m;
  }

  bool measure_register(PyObject * module)
  {
    PyObject * type = PyType_FromSpec(&measure_spec);
    if (type == nullptr || PyModule_AddObject(module, "Measure", type) < 0)
    {
      Py_XDECREF(type);
      return false;
    }
    measure_type = type;
    return true;
  }
} // namespace fpr_native
