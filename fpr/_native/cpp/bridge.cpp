// The C++ objects behind pinocchio's Python objects, found through Boost.Python's converter registry (the one
// pinocchio's bindings register their types in): the compiled parts use the very model the Python side built,
// not a copy or an export of it.
#include "native.hpp"

#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/constrained-dynamics.hpp>

#include <boost/python/extract.hpp>

namespace fpr_native
{

  const char * pinocchio_version()
  {
    return PINOCCHIO_VERSION;
  }

  int model_nq(const Objects & objects)
  {
    return static_cast<const pinocchio::Model *>(objects.model)->nq;
  }

  int model_nv(const Objects & objects)
  {
    return static_cast<const pinocchio::Model *>(objects.model)->nv;
  }

  namespace
  {
    template<typename T>
    T * pointer(PyObject * object, const char * what, std::string & error)
    {
      boost::python::extract<T &> found(object);
      if (!found.check())
      {
        error = what;
        return nullptr;
      }
      return &found();
    }
  } // namespace

  bool extract(PyObject * model, PyObject * data, PyObject * constraints, PyObject * constraint_datas,
               PyObject * settings, Objects & out, std::string & error)
  {
    out = Objects();
    const auto * m = pointer<pinocchio::Model>(model, "model: expected a pinocchio.Model", error);
    auto * d = m ? pointer<pinocchio::Data>(data, "data: expected a pinocchio.Data", error) : nullptr;
    if (d == nullptr)
      return false;
    if ((int)d->oMi.size() != m->njoints || d->nvSubtree.size() != m->nvs.size())
    {
      error = "data: not a pinocchio.Data of this model (model.createData())";
      return false;
    }
    out.model = const_cast<pinocchio::Model *>(m);
    out.data = d;
    if ((constraints == Py_None) != (constraint_datas == Py_None))
    {
      error = "constraints and constraint_datas: give both or neither";
      return false;
    }
    if (constraints != Py_None)
    {
      const auto * cms = pointer<pinocchio::RigidConstraintModelVector>(
        constraints, "constraints: expected a pinocchio.StdVec_RigidConstraintModel", error);
      auto * cds = cms ? pointer<pinocchio::RigidConstraintDataVector>(
                           constraint_datas, "constraint_datas: expected a pinocchio.StdVec_RigidConstraintData",
                           error)
                       : nullptr;
      if (cds == nullptr)
        return false;
      if (cds->size() != cms->size())
      {
        error = "constraint_datas: one per constraint (constraint.createData())";
        return false;
      }
      for (const auto & cm : *cms)
        if (cm.joint1_id >= (pinocchio::JointIndex)m->njoints || cm.joint2_id >= (pinocchio::JointIndex)m->njoints)
        {
          error = "constraints: a constraint on a joint the model does not have";
          return false;
        }
      out.constraint_models = const_cast<pinocchio::RigidConstraintModelVector *>(cms);
      out.constraint_datas = cds;
    }
    if (settings != Py_None)
    {
      out.settings = pointer<pinocchio::ProximalSettings>(settings, "settings: expected a pinocchio.ProximalSettings",
                                                          error);
      if (out.settings == nullptr)
        return false;
    }
    return true;
  }

} // namespace fpr_native
