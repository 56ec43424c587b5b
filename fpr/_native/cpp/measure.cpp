// The measurement of the closed-loop tick (fpr/model/constrained.py, ClosedChainModel.to_minimal with a
// reference): Pinocchio's forward kinematics of the closed chain, the robot kind's reads of its placements, the
// thesis coordinates unwrapped to the reference, and the velocity's least squares (minimal.cpp).
#include "native.hpp"

#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/kinematics.hpp>

#include <cmath>

namespace fpr_native
{
  namespace pin = pinocchio;
  typedef Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> RowMatrix;

  namespace
  {
    pin::SE3 placement(const double * h)
    {
      const Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>> m(h);
      return pin::SE3(m.topLeftCorner<3, 3>(), m.topRightCorner<3, 1>());
    }

    // Python's float x % m for m > 0 (the sign of m, fmod's value otherwise)
    double python_mod(double x, double m)
    {
      double r = std::fmod(x, m);
      if (r != 0.0)
      {
        if ((m < 0) != (r < 0))
          r += m;
      }
      else
        r = std::copysign(0.0, m);
      return r;
    }

    const double PI = 3.14159265358979323846, TWO_PI = 2 * PI;

    // the wrapped difference (a - r + pi) % 2 pi - pi, as fpr.model.constrained.euler_zyx computes it
    double wrapped(double a, double r)
    {
      return python_mod(a - r + PI, TWO_PI) - PI;
    }
  } // namespace

  class Measure
  {
  public:
    const pin::Model & model;
    pin::Data & data;
    Minimal * minimal;
    int nqp;
    std::vector<int> closed_q, source;
    std::vector<double> sign;
    std::vector<EulerRead> eulers;
    std::vector<pin::SE3> A, B;
    std::vector<AngleRead> angles;
    std::vector<pin::SE3> P;
    RowMatrix T_inv;
    std::vector<int> angular;
    Eigen::VectorXd qp, q_model;
  };

  Measure * measure_new(const Objects & objects, Minimal * minimal, int nqp, const std::vector<int> & closed_q,
                        const std::vector<int> & source, const std::vector<double> & sign,
                        const std::vector<EulerRead> & eulers, const std::vector<AngleRead> & angles,
                        const double * T_inv, int n, const std::vector<int> & angular, std::string & error)
  {
    const auto & model = *static_cast<const pin::Model *>(objects.model);
    const int nj = model.njoints;
    if (minimal_rows(minimal) != model.nv)
    {
      error = "the velocity's constant rows must be the closed chain's nv";
      return nullptr;
    }
    if (n != minimal_n(minimal))
    {
      error = "T_inv must have the minimal model's thesis coordinates as rows";
      return nullptr;
    }
    if (closed_q.size() != source.size() || source.size() != sign.size())
    {
      error = "one source and one sign per shared joint";
      return nullptr;
    }
    for (std::size_t k = 0; k < closed_q.size(); ++k)
      if (closed_q[k] < 0 || closed_q[k] >= model.nq || source[k] < 0 || source[k] >= nqp)
      {
        error = "a shared joint's index out of range";
        return nullptr;
      }
    auto qp_index = [nqp](int i) { return i >= 0 && i < nqp; };
    for (const auto & e : eulers)
    {
      bool ok = e.joint >= 0 && e.joint < nj;
      for (int d = 0; d < 3; ++d)
        ok = ok && (e.translation[d] == -1 || qp_index(e.translation[d])) && qp_index(e.euler[d])
             && e.reference[d] >= 0 && e.reference[d] < n;
      if (!ok)
      {
        error = "an Euler read's joint or index out of range";
        return nullptr;
      }
    }
    for (const auto & a : angles)
      if (a.joint < 0 || a.joint >= nj || a.other < 0 || a.other >= nj || !qp_index(a.index))
      {
        error = "an angle read's joint or index out of range";
        return nullptr;
      }
    for (int i : angular)
      if (i < 0 || i >= n)
      {
        error = "an angular coordinate out of range";
        return nullptr;
      }
    auto * m = new Measure{model,  *static_cast<pin::Data *>(objects.data), minimal, nqp, closed_q, source, sign,
                           eulers, {}, {}, angles, {}, Eigen::Map<const RowMatrix>(T_inv, n, nqp), angular,
                           Eigen::VectorXd::Zero(nqp), Eigen::VectorXd::Zero(model.nq)};
    for (const auto & e : eulers)
    {
      m->A.push_back(placement(e.A));
      m->B.push_back(placement(e.B));
    }
    for (const auto & a : angles)
      m->P.push_back(placement(a.P));
    return m;
  }

  void measure_delete(Measure * measure)
  {
    delete measure;
  }

  int measure_nq(const Measure * measure)
  {
    return measure->model.nq;
  }

  int measure_nv(const Measure * measure)
  {
    return measure->model.nv;
  }

  int measure_n(const Measure * measure)
  {
    return (int)measure->T_inv.rows();
  }

  bool measure(Measure * m, const double * qc, const double * vc, const double * reference, double * q, double * v)
  {
    m->q_model = Eigen::Map<const Eigen::VectorXd>(qc, m->model.nq);
    pin::forwardKinematics(m->model, m->data, m->q_model);
    const auto & omi = m->data.oMi;
    m->qp.setZero();
    for (std::size_t k = 0; k < m->closed_q.size(); ++k)
      m->qp[m->source[k]] = m->sign[k] * qc[m->closed_q[k]];
    for (std::size_t k = 0; k < m->eulers.size(); ++k)
    {
      const EulerRead & e = m->eulers[k];
      const pin::SE3 M = m->A[k] * omi[(pin::JointIndex)e.joint] * m->B[k];
      const Eigen::Vector3d rpy = pin::rpy::matrixToRpy(M.rotation());
      const double phi = rpy[0], theta = rpy[1], psi = rpy[2];
      const double r0 = reference[e.reference[0]], r1 = reference[e.reference[1]], r2 = reference[e.reference[2]];
      const double a0 = wrapped(psi, r0), a1 = wrapped(theta, r1), a2 = wrapped(phi, r2);
      const double b0 = wrapped(psi + PI, r0), b1 = wrapped(PI - theta, r1), b2 = wrapped(phi + PI, r2);
      const double first = a0 * a0 + a1 * a1 + a2 * a2, second = b0 * b0 + b1 * b1 + b2 * b2;
      const double euler[3] = {second < first ? psi + PI : psi, second < first ? PI - theta : theta,
                               second < first ? phi + PI : phi};
      for (int d = 0; d < 3; ++d)
      {
        if (e.translation[d] >= 0)
          m->qp[e.translation[d]] = M.translation()[d];
        m->qp[e.euler[d]] = euler[d];
      }
    }
    for (std::size_t k = 0; k < m->angles.size(); ++k)
    {
      const AngleRead & a = m->angles[k];
      const Eigen::Matrix3d rel =
        (omi[(pin::JointIndex)a.joint] * m->P[k]).rotation().transpose() * omi[(pin::JointIndex)a.other].rotation();
      m->qp[a.index] = std::atan2(rel(2, 1), rel(1, 1));
    }
    Eigen::Map<Eigen::VectorXd> out(q, m->T_inv.rows());
    out.noalias() = m->T_inv * m->qp;
    for (int i : m->angular)
      out[i] = reference[i] + wrapped(out[i], reference[i]);
    return minimal_velocity(m->minimal, q, vc, v);
  }

} // namespace fpr_native
