// The plant's RKMK4 steps on Pinocchio's constraint dynamics and Lie-group integration: the method of
// fpr/sim/plant.py (Plant._python_steps, rkmk4_step) with the same calls, made from C++ instead of Python.
#include "native.hpp"

#include <pinocchio/multibody.hpp>
#include <pinocchio/constraints.hpp>
#include <pinocchio/algorithm/proximal.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/kinematics.hpp>

#include <Eigen/LU>

#include <cmath>
#include <utility>

// pinocchio::constraintDynamics as its header declares it, without the header: the header also defines it, as
// an inline template, which the compiler then instantiates for this file's call (most of a minute of compile
// time) although libpinocchio_default holds that very instantiation (declared `extern template` there) and
// the call links to it. The declaration must be the header's, parameter for parameter, so that the call
// names the library's symbol: a mismatch fails at load time (an undefined symbol), never silently.
namespace pinocchio
{
  template<
    typename Scalar,
    int Options,
    template<typename, int> class JointCollectionTpl,
    typename ConfigVectorType,
    typename TangentVectorType1,
    typename TangentVectorType2,
    class ConstraintModelAllocator,
    class ConstraintDataAllocator>
  const typename DataTpl<Scalar, Options, JointCollectionTpl>::TangentVectorType & constraintDynamics(
    const ModelTpl<Scalar, Options, JointCollectionTpl> & model,
    DataTpl<Scalar, Options, JointCollectionTpl> & data,
    const Eigen::MatrixBase<ConfigVectorType> & q,
    const Eigen::MatrixBase<TangentVectorType1> & v,
    const Eigen::MatrixBase<TangentVectorType2> & tau,
    const std::vector<RigidConstraintModelTpl<Scalar, Options>, ConstraintModelAllocator> & contact_models,
    std::vector<RigidConstraintDataTpl<Scalar, Options>, ConstraintDataAllocator> & contact_datas,
    ProximalSettingsTpl<Scalar> & settings);
} // namespace pinocchio

namespace fpr_native
{
  namespace pin = pinocchio;
  typedef Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> RowMatrix;

  class Plant
  {
  public:
    Plant(const Objects & objects, const double * force_map_t, int nw, const std::vector<int> & frames)
    : model(*static_cast<const pin::Model *>(objects.model))
    , data(*static_cast<pin::Data *>(objects.data))
    , constraints(*static_cast<const pin::RigidConstraintModelVector *>(objects.constraint_models))
    , datas(*static_cast<pin::RigidConstraintDataVector *>(objects.constraint_datas))
    , settings(*static_cast<pin::ProximalSettings *>(objects.settings))
    , force_map(Eigen::Map<const RowMatrix>(force_map_t, nw, model.nv))
    , frames(frames)
    , dexp(Eigen::MatrixXd::Zero(model.nv, model.nv))
    , frame_jacobian(6, model.nv)
    {
      // dexp^-1 is block diagonal, one block per joint (each joint's integrate reads its own velocity only)
      for (std::size_t j = 1; j < model.nvs.size(); ++j)
        if (model.nvs[j] > 0)
          blocks.emplace_back(model.idx_vs[j], model.nvs[j]);
      for (const auto & block : blocks)
        lus.emplace_back(block.second);
      for (int k = 0; k < 3; ++k)
        forces[k].resize(model.nv);
      for (int k = 0; k < 4; ++k)
      {
        kv[k].resize(model.nv);
        kq[k].resize(model.nv);
      }
    }

    const pin::Model & model;
    pin::Data & data;
    const pin::RigidConstraintModelVector & constraints;
    pin::RigidConstraintDataVector & datas;
    pin::ProximalSettings & settings;
    RowMatrix force_map; // nw x nv
    std::vector<int> frames;
    std::vector<std::pair<int, int>> blocks; // (idx_v, nv) of each joint
    std::vector<Eigen::PartialPivLU<Eigen::MatrixXd>> lus;
    Eigen::MatrixXd dexp;
    Eigen::Matrix<double, 6, Eigen::Dynamic> frame_jacobian;
    Eigen::VectorXd forces[3], kv[4], kq[4], tau;

    // the generalised force at configuration q: the rotors' (`rotors`) and the wind's J^T F at each frame
    const Eigen::VectorXd & force(const Eigen::VectorXd & q, const Eigen::VectorXd & rotors, const double * wind)
    {
      if (wind == nullptr)
        return rotors;
      tau = rotors;
      pin::computeJointJacobians(model, data, q);
      for (std::size_t f = 0; f < frames.size(); ++f)
      {
        frame_jacobian.setZero();
        pin::getFrameJacobian(
          model, data, (pin::FrameIndex)frames[f], pin::LOCAL_WORLD_ALIGNED, frame_jacobian);
        tau.noalias() +=
          frame_jacobian.topRows<3>().transpose() * Eigen::Map<const Eigen::Vector3d>(wind + 3 * f);
      }
      return tau;
    }

    // x = dexp^-1_theta(v) = dIntegrate(q, theta, ARG1)^-1 v, block by block; false on a singular block
    bool dexp_inverse(const Eigen::VectorXd & q, const Eigen::VectorXd & theta, const Eigen::VectorXd & v,
                      Eigen::VectorXd & x)
    {
      pin::dIntegrate(model, q, theta, dexp, pin::ARG1);
      for (std::size_t b = 0; b < blocks.size(); ++b)
      {
        const int iv = blocks[b].first, n = blocks[b].second;
        if (n == 1)
        {
          const double d = dexp(iv, iv);
          if (d == 0.0)
            return false;
          x[iv] = v[iv] / d;
          continue;
        }
        auto & lu = lus[b];
        lu.compute(dexp.block(iv, iv, n, n));
        if ((lu.matrixLU().diagonal().array() == 0.0).any())
          return false;
        x.segment(iv, n) = lu.solve(v.segment(iv, n));
      }
      return true;
    }

    const Eigen::VectorXd & dynamics(const Eigen::VectorXd & q, const Eigen::VectorXd & v,
                                     const Eigen::VectorXd & tau_in)
    {
      return pin::constraintDynamics(model, data, q, v, tau_in, constraints, datas, settings);
    }
  };

  Plant * plant_new(const Objects & objects, const double * force_map_t, int nw, const std::vector<int> & frames,
                    std::string & error)
  {
    const auto & model = *static_cast<const pin::Model *>(objects.model);
    if (objects.constraint_models == nullptr || objects.settings == nullptr)
    {
      error = "the plant needs its constraints, their datas and the proximal settings";
      return nullptr;
    }
    for (int f : frames)
      if (f < 0 || f >= (int)model.nframes)
      {
        error = "a frame index out of the model's frames";
        return nullptr;
      }
    return new Plant(objects, force_map_t, nw, frames);
  }

  void plant_delete(Plant * plant)
  {
    delete plant;
  }

  int plant_nq(const Plant * plant)
  {
    return plant->model.nq;
  }

  int plant_nv(const Plant * plant)
  {
    return plant->model.nv;
  }

  int plant_frames(const Plant * plant)
  {
    return (int)plant->frames.size();
  }

  int plant_nw(const Plant * plant)
  {
    return (int)plant->force_map.rows();
  }

  StepStatus plant_steps(Plant * p, double * q_io, double * v_io, double * w_io, const double * w_cmd,
                         const double * decay, double dt, long steps, const double * wind, long & done)
  {
    const int nq = p->model.nq, nv = p->model.nv, nw = (int)p->force_map.rows();
    Eigen::Map<Eigen::VectorXd> q_out(q_io, nq), v_out(v_io, nv), w_out(w_io, nw);
    Eigen::Map<const Eigen::VectorXd> command(w_cmd, nw);
    Eigen::VectorXd q = q_out, v = v_out, w = w_out, speeds[3], q_stage(nq), v_stage(nv), theta(nv), q_next(nq),
                    v_next(nv);
    const double half = 0.5 * dt, weights[4] = {dt / 6.0, dt / 3.0, dt / 3.0, dt / 6.0};
    static const int force_of[4] = {0, 1, 1, 2};
    for (done = 0; done < steps; ++done)
    {
      for (int s = 0; s < 3; ++s)
      {
        speeds[s] = command + (w - command) * decay[s];
        p->forces[s].noalias() = p->force_map.transpose() * speeds[s].cwiseProduct(speeds[s]);
      }
      p->kv[0] = p->dynamics(q, v, p->force(q, p->forces[0], wind));
      p->kq[0] = v;
      for (int stage = 1; stage < 4; ++stage)
      {
        const double h = stage == 3 ? dt : half;
        v_stage = v + h * p->kv[stage - 1];
        theta = h * p->kq[stage - 1];
        pin::integrate(p->model, q, theta, q_stage);
        p->kv[stage] = p->dynamics(q_stage, v_stage, p->force(q_stage, p->forces[force_of[stage]], wind));
        if (!p->dexp_inverse(q, theta, v_stage, p->kq[stage]))
          return STEPS_SINGULAR;
      }
      theta = weights[0] * p->kq[0] + weights[1] * p->kq[1] + weights[2] * p->kq[2] + weights[3] * p->kq[3];
      v_next = v + (weights[0] * p->kv[0] + weights[1] * p->kv[1] + weights[2] * p->kv[2] + weights[3] * p->kv[3]);
      pin::integrate(p->model, q, theta, q_next);
      if (!std::isfinite(q_next.sum() + v_next.sum()))
        return STEPS_NOT_FINITE;
      q = q_next;
      v = v_next;
      w = speeds[2];
      q_out = q;
      v_out = v;
      w_out = w;
    }
    return STEPS_DONE;
  }

  void plant_dynamics(Plant * plant, const double * q, const double * v, const double * tau, double * a)
  {
    const int nq = plant->model.nq, nv = plant->model.nv;
    const Eigen::VectorXd qv = Eigen::Map<const Eigen::VectorXd>(q, nq), vv = Eigen::Map<const Eigen::VectorXd>(v, nv),
                          tv = Eigen::Map<const Eigen::VectorXd>(tau, nv);
    Eigen::Map<Eigen::VectorXd>(a, nv) = plant->dynamics(qv, vv, tv);
  }

  bool plant_points(Plant * p, const double * q, double * positions, double & closure_error)
  {
    for (const auto & cm : p->constraints)
      if (cm.type != pin::CONTACT_3D)
        return false;
    const Eigen::VectorXd qv = Eigen::Map<const Eigen::VectorXd>(q, p->model.nq);
    pin::forwardKinematics(p->model, p->data, qv);
    for (std::size_t f = 0; f < p->frames.size(); ++f)
    {
      const auto & frame = p->model.frames[(pin::FrameIndex)p->frames[f]];
      Eigen::Map<Eigen::Vector3d>(positions + 3 * f) =
        p->data.oMi[frame.parentJoint].act(frame.placement.translation());
    }
    double worst = 0.0;
    for (const auto & cm : p->constraints)
    {
      const Eigen::Vector3d a = p->data.oMi[cm.joint1_id].act(cm.joint1_placement.translation()),
                            b = p->data.oMi[cm.joint2_id].act(cm.joint2_placement.translation());
      const double e = (a - b).norm();
      if (e > worst || std::isnan(e))
        worst = e;
    }
    closure_error = worst;
    return true;
  }

} // namespace fpr_native
