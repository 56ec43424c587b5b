// The minimal model's terms the closed loop reads at every tick, by Pinocchio's algorithms: the attitude
// model's M_p, nonlinear effects and the drones' frame Jacobians (fpr/model/robot.py, Robot.attitude_model),
// and the measured velocity's least squares (fpr/model/constrained.py, ClosedChainModel.to_minimal).
#include "native.hpp"

#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/rnea.hpp>

#include <Eigen/Cholesky>

namespace fpr_native
{
  namespace pin = pinocchio;
  typedef Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> RowMatrix;

  class Minimal
  {
  public:
    Minimal(const Objects & objects, const double * T, int n, const std::vector<int> & frames,
            const double * constant_rows, int rows, const std::vector<int> & freeflyer_rows,
            const std::vector<int> & hinges)
    : model(*static_cast<const pin::Model *>(objects.model))
    , data(*static_cast<pin::Data *>(objects.data))
    , T(Eigen::Map<const RowMatrix>(T, model.nq, n))
    , frames(frames)
    , K(Eigen::Map<const RowMatrix>(constant_rows, rows, n))
    , freeflyer_rows(freeflyer_rows)
    , hinges(hinges)
    , jacobian(6, model.nv)
    , normal(n)
    {
    }

    const pin::Model & model;
    pin::Data & data;
    RowMatrix T;
    std::vector<int> frames;
    RowMatrix K;
    std::vector<int> freeflyer_rows, hinges;
    Eigen::Matrix<double, 6, Eigen::Dynamic> jacobian;
    Eigen::LLT<Eigen::MatrixXd> normal;
  };

  Minimal * minimal_new(const Objects & objects, const double * T, int n, const std::vector<int> & frames,
                        const double * constant_rows, int rows, const std::vector<int> & freeflyer_rows,
                        const std::vector<int> & hinges, std::string & error)
  {
    const auto & model = *static_cast<const pin::Model *>(objects.model);
    if (model.nq != model.nv)
    {
      error = "the minimal model must have nq == nv (T maps thesis coordinates to its configuration)";
      return nullptr;
    }
    for (int f : frames)
      if (f < 0 || f >= (int)model.nframes)
      {
        error = "a frame index out of the model's frames";
        return nullptr;
      }
    if (freeflyer_rows.size() != hinges.size())
    {
      error = "one free-flyer row per hinge";
      return nullptr;
    }
    for (std::size_t k = 0; k < hinges.size(); ++k)
      if (hinges[k] < 1 || hinges[k] >= (int)model.njoints || freeflyer_rows[k] < 0 || freeflyer_rows[k] + 6 > rows)
      {
        error = "a hinge joint or a free-flyer row out of range";
        return nullptr;
      }
    return new Minimal(objects, T, n, frames, constant_rows, rows, freeflyer_rows, hinges);
  }

  void minimal_delete(Minimal * minimal)
  {
    delete minimal;
  }

  int minimal_n(const Minimal * minimal)
  {
    return (int)minimal->T.cols();
  }

  int minimal_nv(const Minimal * minimal)
  {
    return minimal->model.nv;
  }

  int minimal_rows(const Minimal * minimal)
  {
    return (int)minimal->K.rows();
  }

  int minimal_frames(const Minimal * minimal)
  {
    return (int)minimal->frames.size();
  }

  // M(q_model) (both triangles, row-major into m) and the nonlinear effects at q_model = T q, v_model = T v, then the
  // joints' Jacobians at q_model (computeJointJacobians), for the callers to read; returns nv.
  static int mass_bias_jacobians(Minimal * p, const double * q, const double * v, double * m, double * nle)
  {
    const int n = (int)p->T.cols(), nv = p->model.nv;
    const Eigen::VectorXd qp = p->T * Eigen::Map<const Eigen::VectorXd>(q, n),
                          vp = p->T * Eigen::Map<const Eigen::VectorXd>(v, n);
    pin::crba(p->model, p->data, Eigen::Ref<const Eigen::VectorXd>(qp), pin::Convention::LOCAL);
    p->data.M.triangularView<Eigen::StrictlyLower>() = p->data.M.transpose().triangularView<Eigen::StrictlyLower>();
    Eigen::Map<RowMatrix>(m, nv, nv) = p->data.M;
    Eigen::Map<Eigen::VectorXd>(nle, nv) = pin::nonLinearEffects(p->model, p->data, qp, vp);
    pin::computeJointJacobians(p->model, p->data, qp);
    return nv;
  }

  void minimal_frame_terms(Minimal * p, const double * q, const double * v, double * m, double * nle,
                           double * jacobians)
  {
    const int nv = mass_bias_jacobians(p, q, v, m, nle);
    pin::updateFramePlacements(p->model, p->data);
    for (std::size_t f = 0; f < p->frames.size(); ++f)
    {
      p->jacobian.setZero();
      pin::getFrameJacobian(p->model, p->data, (pin::FrameIndex)p->frames[f], pin::LOCAL, p->jacobian);
      Eigen::Map<RowMatrix>(jacobians + 6 * nv * f, 6, nv) = p->jacobian;
    }
  }

  void minimal_joint_terms(Minimal * p, const double * q, const double * v, double * m, double * nle,
                           const std::vector<int> & joints, double * jacobians)
  {
    const int nv = mass_bias_jacobians(p, q, v, m, nle);
    for (std::size_t k = 0; k < joints.size(); ++k)
    {
      p->jacobian.setZero();
      pin::getJointJacobian(p->model, p->data, (pin::JointIndex)joints[k], pin::LOCAL_WORLD_ALIGNED, p->jacobian);
      Eigen::Map<RowMatrix>(jacobians + 6 * nv * k, 6, nv) = p->jacobian;
    }
  }

  const double * minimal_map(const Minimal * p)
  {
    return p->T.data();
  }

  int minimal_joints(const Minimal * p)
  {
    return (int)p->model.njoints;
  }

  bool minimal_velocity(Minimal * p, const double * q, const double * vc, double * v)
  {
    const int n = (int)p->T.cols(), rows = (int)p->K.rows();
    const Eigen::VectorXd qp = p->T * Eigen::Map<const Eigen::VectorXd>(q, n);
    pin::computeJointJacobians(p->model, p->data, qp);
    for (std::size_t k = 0; k < p->hinges.size(); ++k)
    {
      p->jacobian.setZero();
      pin::getJointJacobian(p->model, p->data, (pin::JointIndex)p->hinges[k], pin::LOCAL, p->jacobian);
      p->K.middleRows(p->freeflyer_rows[k], 6).noalias() = p->jacobian * p->T;
    }
    p->normal.compute(p->K.transpose() * p->K);
    if (p->normal.info() != Eigen::Success)
      return false;
    Eigen::Map<Eigen::VectorXd>(v, n) =
      p->normal.solve(p->K.transpose() * Eigen::Map<const Eigen::VectorXd>(vc, rows));
    return true;
  }

} // namespace fpr_native
