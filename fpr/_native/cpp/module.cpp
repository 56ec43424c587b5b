// fpr._native._pinocchio: the closed loop's calls of Pinocchio's C++ library, as Python types.
//
// Plant(model, data, constraints, constraint_datas, settings, force_map_t, frames): the plant on a closed-chain
//   model (plant.cpp), `data` and `constraint_datas` its own (initialised by pin.initConstraintDynamics)
//   steps(q, v, w, w_command, w_max, decay, dt, steps, wind=None) -> (q, v, w, done, status)
//   dynamics(q, v, tau) -> a
//   points(q) -> (positions (frames, 3), closure error), or None when a closure is not a 3D point closure
// Minimal(model, data, T, frames, constant_rows, freeflyer_rows, hinges): the minimal model's terms
//   (minimal.cpp), `data` its own
//   frame_terms(q, v) -> (M, nle, (J per frame))
//   velocity(q, vc) -> v, or None when K^T K is not positive definite
// Measure(...): the measurement (measure_module.cpp, which says its arguments)
// Loop(...): the closed loop's ticks natively (loop.cpp, which says its arguments)
//
// The CPython API with METH_FASTCALL: the tick calls these a few times per inner-loop tick, where every
// microsecond of call overhead counts; pinocchio's objects are found once, at construction (bridge.cpp).
#define PY_SSIZE_T_CLEAN
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#define PY_ARRAY_UNIQUE_SYMBOL fpr_native_ARRAY_API
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

  // ------------------------------------------------------------------ Plant
  struct PlantObject
  {
    PyObject_HEAD Plant * plant;
    PyObject * keep; // the Python objects whose C++ objects the plant uses (kept alive)
  };

  void plant_dealloc(PyObject * self)
  {
    auto * p = reinterpret_cast<PlantObject *>(self);
    plant_delete(p->plant);
    Py_XDECREF(p->keep);
    Py_TYPE(self)->tp_free(self);
  }

  int plant_init(PyObject * self, PyObject * args, PyObject * kwargs)
  {
    auto * p = reinterpret_cast<PlantObject *>(self);
    static const char * names[] = {"model",    "data",        "constraints", "constraint_datas",
                                   "settings", "force_map_t", "frames",      nullptr};
    PyObject *model, *data_obj, *constraints, *datas, *settings, *map, *frames_obj;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OOOOOOO", const_cast<char **>(names), &model, &data_obj,
                                     &constraints, &datas, &settings, &map, &frames_obj))
      return -1;
    try
    {
      Objects objects;
      std::string error;
      if (!extract(model, data_obj, constraints, datas, settings, objects, error))
      {
        PyErr_SetString(PyExc_TypeError, error.c_str());
        return -1;
      }
      std::vector<int> frames;
      if (!int_list(frames_obj, frames, "frames: expected a sequence of frame indices"))
        return -1;
      PyArrayObject * g = input(map, -1, "force_map_t");
      if (g == nullptr)
        return -1;
      if (PyArray_NDIM(g) != 2)
      {
        Py_DECREF(g);
        PyErr_SetString(PyExc_ValueError, "force_map_t: expected a 2D array (rotor speeds, nv)");
        return -1;
      }
      Plant * plant = nullptr;
      if (PyArray_DIM(g, 1) != model_nv(objects))
        error = "force_map_t: expected the model's nv columns";
      else
        plant = plant_new(objects, data(g), (int)PyArray_DIM(g, 0), frames, error);
      Py_DECREF(g);
      if (plant == nullptr)
      {
        PyErr_SetString(PyExc_ValueError, error.c_str());
        return -1;
      }
      plant_delete(p->plant);
      p->plant = plant;
      Py_XDECREF(p->keep);
      p->keep = PyTuple_Pack(5, model, data_obj, constraints, datas, settings);
      return p->keep == nullptr ? -1 : 0;
    }
    catch (const std::exception & e)
    {
      PyErr_SetString(PyExc_RuntimeError, e.what());
      return -1;
    }
  }

  Plant * plant_of(PyObject * self)
  {
    Plant * plant = reinterpret_cast<PlantObject *>(self)->plant;
    if (plant == nullptr)
      PyErr_SetString(PyExc_RuntimeError, "Plant: not initialised");
    return plant;
  }

  PyObject * plant_steps_py(PyObject * self, PyObject * const * args, Py_ssize_t nargs)
  {
    Plant * plant = plant_of(self);
    if (plant == nullptr || !check_arguments("steps", nargs, 8, 9))
      return nullptr;
    const double w_max = PyFloat_AsDouble(args[4]), dt = PyFloat_AsDouble(args[6]);
    const long steps = PyLong_AsLong(args[7]);
    if (PyErr_Occurred())
      return nullptr;
    if (!(dt > 0) || steps < 0)
    {
      PyErr_SetString(PyExc_ValueError, "steps: dt must be > 0 and steps >= 0");
      return nullptr;
    }
    const int nq = plant_nq(plant), nv = plant_nv(plant), frames = plant_frames(plant);
    PyArrayObject *q = nullptr, *v = nullptr, *w = nullptr, *wc = nullptr, *decay = nullptr, *wind = nullptr;
    PyObject * result = nullptr;
    npy_intp nw = 0;
    long done = 0;
    StepStatus status = STEPS_DONE;
    if ((q = input(args[0], nq, "q")) == nullptr || (v = input(args[1], nv, "v")) == nullptr
        || (w = input(args[2], plant_nw(plant), "w")) == nullptr)
      goto end;
    nw = PyArray_SIZE(w);
    if ((wc = input(args[3], nw, "w_command")) == nullptr || (decay = input(args[5], 3, "decay")) == nullptr)
      goto end;
    if (!PyArray_SAMESHAPE(w, wc))
    {
      PyErr_SetString(PyExc_ValueError, "steps: w_command must have w's shape");
      goto end;
    }
    if (nargs == 9 && args[8] != Py_None && (wind = input(args[8], 3 * (npy_intp)frames, "wind")) == nullptr)
      goto end;
    {
      npy_intp q_dims[1] = {nq}, v_dims[1] = {nv};
      PyArrayObject *q_out = output(1, q_dims, data(q)), *v_out = output(1, v_dims, data(v)),
                    *w_out = output(PyArray_NDIM(w), PyArray_DIMS(w), data(w)),
                    *command = output(PyArray_NDIM(w), PyArray_DIMS(w), data(wc));
      if (q_out != nullptr && v_out != nullptr && w_out != nullptr && command != nullptr)
      {
        double * c = data(command);
        for (npy_intp r = 0; r < nw; ++r) // saturated to [0, w_max] as Plant.saturate (NaN stays NaN)
        {
          if (c[r] < 0.0)
            c[r] = 0.0;
          if (c[r] > w_max)
            c[r] = w_max;
        }
        try
        {
          status = plant_steps(plant, data(q_out), data(v_out), data(w_out), c, data(decay), dt, steps,
                               wind == nullptr ? nullptr : data(wind), done);
          result = Py_BuildValue("OOOli", q_out, v_out, w_out, done, (int)status);
        }
        catch (const std::exception & e)
        {
          PyErr_SetString(PyExc_RuntimeError, e.what());
        }
      }
      Py_XDECREF(q_out);
      Py_XDECREF(v_out);
      Py_XDECREF(w_out);
      Py_XDECREF(command);
    }
  end:
    Py_XDECREF(q);
    Py_XDECREF(v);
    Py_XDECREF(w);
    Py_XDECREF(wc);
    Py_XDECREF(decay);
    Py_XDECREF(wind);
    return result;
  }

  PyObject * plant_dynamics_py(PyObject * self, PyObject * const * args, Py_ssize_t nargs)
  {
    Plant * plant = plant_of(self);
    if (plant == nullptr || !check_arguments("dynamics", nargs, 3, 3))
      return nullptr;
    const int nq = plant_nq(plant), nv = plant_nv(plant);
    PyArrayObject *q = input(args[0], nq, "q"), *v = q ? input(args[1], nv, "v") : nullptr,
                  *tau = v ? input(args[2], nv, "tau") : nullptr, *a = nullptr;
    if (tau != nullptr)
    {
      npy_intp dims[1] = {nv};
      if ((a = output(1, dims)) != nullptr)
      {
        try
        {
          plant_dynamics(plant, data(q), data(v), data(tau), data(a));
        }
        catch (const std::exception & e)
        {
          PyErr_SetString(PyExc_RuntimeError, e.what());
          Py_CLEAR(a);
        }
      }
    }
    Py_XDECREF(q);
    Py_XDECREF(v);
    Py_XDECREF(tau);
    return reinterpret_cast<PyObject *>(a);
  }

  PyObject * plant_points_py(PyObject * self, PyObject * const * args, Py_ssize_t nargs)
  {
    Plant * plant = plant_of(self);
    if (plant == nullptr || !check_arguments("points", nargs, 1, 1))
      return nullptr;
    PyArrayObject * q = input(args[0], plant_nq(plant), "q");
    if (q == nullptr)
      return nullptr;
    npy_intp dims[2] = {plant_frames(plant), 3};
    PyArrayObject * positions = output(2, dims);
    PyObject * result = nullptr;
    if (positions != nullptr)
    {
      double closure = 0.0;
      try
      {
        if (plant_points(plant, data(q), data(positions), closure))
          result = Py_BuildValue("Od", positions, closure);
        else
          result = Py_NewRef(Py_None);
      }
      catch (const std::exception & e)
      {
        PyErr_SetString(PyExc_RuntimeError, e.what());
      }
    }
    Py_XDECREF(positions);
    Py_DECREF(q);
    return result;
  }

  PyMethodDef plant_methods[] = {
    {"steps", reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(plant_steps_py)), METH_FASTCALL,
     "RKMK4 steps: (q, v, w, w_command, w_max, decay, dt, steps, wind=None) -> (q, v, w, done, status)."},
    {"dynamics", reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(plant_dynamics_py)), METH_FASTCALL,
     "pinocchio::constraintDynamics at (q, v) under tau."},
    {"points", reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(plant_points_py)), METH_FASTCALL,
     "(frame positions, closure error) at q, or None when a closure is not a 3D point closure."},
    {nullptr, nullptr, 0, nullptr}};

  PyType_Slot plant_slots[] = {
    {Py_tp_doc,
     const_cast<char *>("The plant's steps on Pinocchio's constraint dynamics (fpr/_native/cpp/module.cpp).")},
    {Py_tp_new, reinterpret_cast<void *>(PyType_GenericNew)},
    {Py_tp_init, reinterpret_cast<void *>(plant_init)},
    {Py_tp_dealloc, reinterpret_cast<void *>(plant_dealloc)},
    {Py_tp_methods, plant_methods},
    {0, nullptr}};

  PyType_Spec plant_spec = {"fpr._native._pinocchio.Plant", sizeof(PlantObject), 0, Py_TPFLAGS_DEFAULT,
                            plant_slots};

  // ------------------------------------------------------------------ Minimal
  struct MinimalObject
  {
    PyObject_HEAD Minimal * minimal;
    PyObject * keep;
  };

  void minimal_dealloc(PyObject * self)
  {
    auto * p = reinterpret_cast<MinimalObject *>(self);
    minimal_delete(p->minimal);
    Py_XDECREF(p->keep);
    Py_TYPE(self)->tp_free(self);
  }

  int minimal_init(PyObject * self, PyObject * args, PyObject * kwargs)
  {
    auto * p = reinterpret_cast<MinimalObject *>(self);
    static const char * names[] = {"model", "data", "T", "frames", "constant_rows", "freeflyer_rows", "hinges",
                                   nullptr};
    PyObject *model, *data_obj, *t_obj, *frames_obj, *rows_obj, *ff_obj, *hinges_obj;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OOOOOOO", const_cast<char **>(names), &model, &data_obj, &t_obj,
                                     &frames_obj, &rows_obj, &ff_obj, &hinges_obj))
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
      std::vector<int> frames, freeflyer_rows, hinges;
      if (!int_list(frames_obj, frames, "frames: expected a sequence of frame indices")
          || !int_list(ff_obj, freeflyer_rows, "freeflyer_rows: expected a sequence of rows")
          || !int_list(hinges_obj, hinges, "hinges: expected a sequence of joint indices"))
        return -1;
      PyArrayObject *T = input(t_obj, -1, "T"), *rows = T ? input(rows_obj, -1, "constant_rows") : nullptr;
      Minimal * minimal = nullptr;
      if (rows != nullptr)
      {
        if (PyArray_NDIM(T) != 2 || PyArray_NDIM(rows) != 2 || PyArray_DIM(rows, 1) != PyArray_DIM(T, 1)
            || PyArray_DIM(T, 0) != model_nq(objects))
          error = "T must be (the model's nq, n) and constant_rows (rows, n)";
        else
          minimal = minimal_new(objects, data(T), (int)PyArray_DIM(T, 1), frames, data(rows),
                                (int)PyArray_DIM(rows, 0), freeflyer_rows, hinges, error);
        if (minimal == nullptr)
          PyErr_SetString(PyExc_ValueError, error.c_str());
      }
      Py_XDECREF(T);
      Py_XDECREF(rows);
      if (minimal == nullptr)
        return -1;
      minimal_delete(p->minimal);
      p->minimal = minimal;
      Py_XDECREF(p->keep);
      p->keep = PyTuple_Pack(2, model, data_obj);
      if (p->keep == nullptr)
        return -1;
      return 0;
    }
    catch (const std::exception & e)
    {
      PyErr_SetString(PyExc_RuntimeError, e.what());
      return -1;
    }
  }

  Minimal * minimal_of(PyObject * self)
  {
    Minimal * minimal = reinterpret_cast<MinimalObject *>(self)->minimal;
    if (minimal == nullptr)
      PyErr_SetString(PyExc_RuntimeError, "Minimal: not initialised");
    return minimal;
  }

  PyObject * minimal_frame_terms_py(PyObject * self, PyObject * const * args, Py_ssize_t nargs)
  {
    Minimal * minimal = minimal_of(self);
    if (minimal == nullptr || !check_arguments("frame_terms", nargs, 2, 2))
      return nullptr;
    const int n = minimal_n(minimal), nv = minimal_nv(minimal), count = minimal_frames(minimal);
    PyArrayObject *q = input(args[0], n, "q"), *v = q ? input(args[1], n, "v") : nullptr;
    PyObject * result = nullptr;
    if (v != nullptr)
    {
      npy_intp m_dims[2] = {nv, nv}, j_dims[3] = {count, 6, nv};
      PyArrayObject *m = output(2, m_dims), *nle = output(1, m_dims), *jac = output(3, j_dims);
      PyObject * jacobians = PyTuple_New(count);
      if (m != nullptr && nle != nullptr && jac != nullptr && jacobians != nullptr)
      {
        try
        {
          minimal_frame_terms(minimal, data(q), data(v), data(m), data(nle), data(jac));
          bool ok = true;
          for (int f = 0; f < count && ok; ++f)
          {
            PyObject * item = PySequence_GetItem(reinterpret_cast<PyObject *>(jac), f);
            ok = item != nullptr;
            if (ok)
              PyTuple_SET_ITEM(jacobians, f, item);
          }
          if (ok)
            result = Py_BuildValue("OOO", m, nle, jacobians);
        }
        catch (const std::exception & e)
        {
          PyErr_SetString(PyExc_RuntimeError, e.what());
        }
      }
      Py_XDECREF(m);
      Py_XDECREF(nle);
      Py_XDECREF(jac);
      Py_XDECREF(jacobians);
    }
    Py_XDECREF(q);
    Py_XDECREF(v);
    return result;
  }

  PyObject * minimal_velocity_py(PyObject * self, PyObject * const * args, Py_ssize_t nargs)
  {
    Minimal * minimal = minimal_of(self);
    if (minimal == nullptr || !check_arguments("velocity", nargs, 2, 2))
      return nullptr;
    const int n = minimal_n(minimal);
    PyArrayObject *q = input(args[0], n, "q"), *vc = q ? input(args[1], minimal_rows(minimal), "vc") : nullptr;
    PyObject * result = nullptr;
    if (vc != nullptr)
    {
      npy_intp dims[1] = {n};
      PyArrayObject * v = output(1, dims);
      if (v != nullptr)
      {
        try
        {
          result = minimal_velocity(minimal, data(q), data(vc), data(v)) ? Py_NewRef(reinterpret_cast<PyObject *>(v))
                                                                         : Py_NewRef(Py_None);
        }
        catch (const std::exception & e)
        {
          PyErr_SetString(PyExc_RuntimeError, e.what());
        }
        Py_DECREF(v);
      }
    }
    Py_XDECREF(q);
    Py_XDECREF(vc);
    return result;
  }

  PyMethodDef minimal_methods[] = {
    {"frame_terms", reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(minimal_frame_terms_py)),
     METH_FASTCALL, "(M, nle, frame Jacobians (LOCAL)) at (T q, T v)."},
    {"velocity", reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(minimal_velocity_py)), METH_FASTCALL,
     "Least-squares v of K(q) v = vc, or None when K^T K is not positive definite."},
    {nullptr, nullptr, 0, nullptr}};

  PyType_Slot minimal_slots[] = {
    {Py_tp_doc,
     const_cast<char *>("The minimal model's terms by Pinocchio's algorithms (fpr/_native/cpp/module.cpp).")},
    {Py_tp_new, reinterpret_cast<void *>(PyType_GenericNew)},
    {Py_tp_init, reinterpret_cast<void *>(minimal_init)},
    {Py_tp_dealloc, reinterpret_cast<void *>(minimal_dealloc)},
    {Py_tp_methods, minimal_methods},
    {0, nullptr}};

  PyType_Spec minimal_spec = {"fpr._native._pinocchio.Minimal", sizeof(MinimalObject), 0, Py_TPFLAGS_DEFAULT,
                              minimal_slots};

  PyObject * plant_type = nullptr;   // the module's types (borrowed: the module holds them)
  PyObject * minimal_type = nullptr;

  bool is_instance(PyObject * obj, PyObject * type, const char * what, const char * kind)
  {
    if (type != nullptr && PyObject_TypeCheck(obj, reinterpret_cast<PyTypeObject *>(type)))
      return true;
    PyErr_Format(PyExc_TypeError, "%s: expected a fpr._native._pinocchio.%s", what, kind);
    return false;
  }

  PyModuleDef module_def = {PyModuleDef_HEAD_INIT, "fpr._native._pinocchio",
                            "The closed loop's calls of Pinocchio's C++ library (fpr/_native/cpp).", -1, nullptr,
                            nullptr, nullptr, nullptr, nullptr};

} // namespace

namespace fpr_native
{
  Plant * plant_from(PyObject * obj, const char * what)
  {
    return is_instance(obj, plant_type, what, "Plant") ? plant_of(obj) : nullptr;
  }

  Minimal * minimal_from(PyObject * obj, const char * what)
  {
    return is_instance(obj, minimal_type, what, "Minimal") ? minimal_of(obj) : nullptr;
  }
} // namespace fpr_native

PyMODINIT_FUNC PyInit__pinocchio(void)
{
  import_array();
  PyObject * module = PyModule_Create(&module_def);
  if (module == nullptr)
    return nullptr;
  PyObject * plant = PyType_FromSpec(&plant_spec);
  PyObject * minimal = plant ? PyType_FromSpec(&minimal_spec) : nullptr;
  plant_type = plant;
  minimal_type = minimal;
  if (minimal == nullptr || PyModule_AddObject(module, "Plant", plant) < 0)
  {
    Py_XDECREF(plant);
    Py_XDECREF(minimal);
    Py_DECREF(module);
    return nullptr;
  }
  if (PyModule_AddObject(module, "Minimal", minimal) < 0)
  {
    Py_DECREF(minimal);
    Py_DECREF(module);
    return nullptr;
  }
  if (!fpr_native::measure_register(module) || !fpr_native::loop_register(module))
  {
    Py_DECREF(module);
    return nullptr;
  }
  if (PyModule_AddStringConstant(module, "PINOCCHIO_VERSION", fpr_native::pinocchio_version()) < 0)
  {
    Py_DECREF(module);
    return nullptr;
  }
  return module;
}
