// The controller's outer-loop update for the native loop (loop.cpp): controllers/ctc.py's CascadedController.update
// when the outer loop is due -- the chain error's integral, the full model's M(q), the momentum observer
// (controllers/observer.py), the momentum feedback's errors, the point-drone model's M_s, c_s and J_h by Pinocchio
// (minimal.cpp) and the robot kind's solve J_h^T F = b (the kind's `compiled_outer_constants` says which) -- the
// same operations in the same order as the Python path, on plain arrays.
//
// The constants vector (CascadedController._outer_constants): n, n_s, n_d, the solve (0: J_h^T F = b by LU; 1: the
// two-link chain's tension regularised towards the plan near its Type-2 singularity, prototype_thrust.py's
// regularised_force), K_p, K_d, K_i, the integral's bound, the observer's bandwidth (0: none), momentum feedback
// (0/1), the regularisation angle, the link length (solve 1), the force axes' two world rows; then the chain's
// indices (n_s), the other coordinates' (n - n_s), the rolls' places among those (n_d), the hinge joints (n_d).
#include "native.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace fpr_native
{
  namespace
  {
    const int HEADER = 15;

    // x := A^-1 x for `columns` right-hand sides (x: n x columns, row-major), A (n x n, row-major) overwritten by
    // its LU factors with partial pivoting (LAPACK's dgesv's choice of pivots); false when A is singular.
    bool lu_solve(double * a, int n, double * x, int columns)
    {
      for (int k = 0; k < n; ++k)
      {
        int pivot = k;
        for (int i = k + 1; i < n; ++i)
          if (std::fabs(a[i * n + k]) > std::fabs(a[pivot * n + k]))
            pivot = i;
        if (a[pivot * n + k] == 0.0)
          return false;
        if (pivot != k)
        {
          for (int j = 0; j < n; ++j)
            std::swap(a[k * n + j], a[pivot * n + j]);
          for (int j = 0; j < columns; ++j)
            std::swap(x[k * columns + j], x[pivot * columns + j]);
        }
        for (int i = k + 1; i < n; ++i)
        {
          const double l = a[i * n + k] / a[k * n + k];
          a[i * n + k] = l;
          for (int j = k + 1; j < n; ++j)
            a[i * n + j] -= l * a[k * n + j];
          for (int j = 0; j < columns; ++j)
            x[i * columns + j] -= l * x[k * columns + j];
        }
      }
      for (int k = n - 1; k >= 0; --k)
        for (int j = 0; j < columns; ++j)
        {
          double s = x[k * columns + j];
          for (int i = k + 1; i < n; ++i)
            s -= a[k * n + i] * x[i * columns + j];
          x[k * columns + j] = s / a[k * n + k];
        }
      return true;
    }

    // np.remainder(x, y) for y > 0: the floored modulo, as numpy computes it (fmod, then moved into [0, y))
    double remainder_floored(double x, double y)
    {
      double m = std::fmod(x, y);
      if (m != 0.0)
      {
        if ((y < 0.0) != (m < 0.0))
          m += y;
      }
      else
        m = std::copysign(0.0, y);
      return m;
    }

    // np.minimum(np.maximum(x, low), high): NaN stays NaN
    double clip(double x, double low, double high)
    {
      if (x < low)
        x = low;
      if (x > high)
        x = high;
      return x;
    }
  } // namespace

  struct Outer
  {
    Minimal * point;
    std::vector<double> k;
    int n, ns, nd, method, axes[2];
    double kp, kd, ki, limit, bandwidth, band, length;
    bool momentum;
    std::vector<int> chain, others, other_rolls, hinges;
    std::vector<double> mass, point_mass, point_nle, jacobians, ms, cs, jh, gain, scratch;
  };

  // The authority set's constants (AuthoritySet.compiled_constants): a header of AUTHORITY_HEAD numbers, then
  // AUTHORITY_DRONE per drone (its mass, offset, roll inertia, the rotors' a and b, the index of its roll in q, or
  // -1: the turn counted from upright).
  const int AUTHORITY_HEAD = 6, AUTHORITY_DRONE = 12;

  bool authority_fits(const double * constants, long length, int n_d, int n)
  {
    if (length < AUTHORITY_HEAD || constants[0] != n_d || length != AUTHORITY_HEAD + AUTHORITY_DRONE * n_d)
      return false;
    for (int i = 0; i < n_d; ++i)
    {
      const double roll = constants[AUTHORITY_HEAD + AUTHORITY_DRONE * i + 11];
      if (!(roll >= -1.0 && roll < n && roll == std::floor(roll)))
        return false;
    }
    return true;
  }

  bool authority_inside(const double * k, const double * force, const double * q)
  {
    const int n_d = (int)k[0];
    const double lower = k[1], upper = k[2], gravity = k[3], kp = k[4], max_tilt = k[5];
    for (int i = 0; i < n_d; ++i)
    {
      const double *drone = k + AUTHORITY_HEAD + AUTHORITY_DRONE * i, *a = drone + 3, *b = drone + 7;
      const double fy = force[2 * i], fz = force[2 * i + 1];
      if (!std::isfinite(fy) || !std::isfinite(fz))
        return false;
      // torque_limit(|F_i|): the least room over the rotors, negative when tau = 0 does not fit
      const double thrust = std::sqrt(fy * fy + fz * fz);
      double out = INFINITY;
      bool within = true;
      for (int j = 0; j < 4; ++j)
      {
        const double z = a[j] * thrust;
        within = within && z >= lower && z <= upper;
        if (b[j] != 0.0)
          out = std::min(out, std::min(z - lower, upper - z) / std::fabs(b[j]));
      }
      const double limit = within ? out : -std::fabs(out);
      // torque_needed: holding the tilt at rest, and turning there from the drone's roll at the chain loop's rate
      const double tilt = std::atan2(-fy, fz);
      const int roll = (int)drone[11];
      const double turn = roll < 0 ? tilt : remainder_floored(tilt - q[roll] + M_PI, 2 * M_PI) - M_PI;
      const double needed = drone[0] * gravity * drone[1] * std::fabs(std::sin(tilt)) + drone[2] * kp * std::fabs(turn);
      if (!(limit - needed >= 0.0) || !(max_tilt - std::fabs(tilt) >= 0.0))
        return false;
    }
    return true;
  }

  Outer * outer_new(Minimal * point, const double * constants, long length, int n, std::string & error)
  {
    if (length < HEADER || (int)constants[0] != n)
    {
      error = "the outer loop's constants do not fit their header or the model";
      return nullptr;
    }
    const int ns = (int)constants[1], nd = (int)constants[2];
    if (ns < 1 || ns > n || nd < 1 || length != HEADER + n + 2 * nd || minimal_n(point) != ns
        || 2 * nd < ns)
    {
      error = "the outer loop's constants do not fit the point model";
      return nullptr;
    }
    auto * o = new Outer();
    o->point = point;
    o->k.assign(constants, constants + length);
    o->n = n;
    o->ns = ns;
    o->nd = nd;
    o->method = (int)constants[3];
    o->kp = constants[4];
    o->kd = constants[5];
    o->ki = constants[6];
    o->limit = constants[7];
    o->bandwidth = constants[8];
    o->momentum = constants[9] != 0.0;
    o->band = constants[10];
    o->length = constants[11];
    o->axes[0] = (int)constants[13];
    o->axes[1] = (int)constants[14];
    const double * idx = constants + HEADER;
    for (int i = 0; i < ns; ++i)
      o->chain.push_back((int)idx[i]);
    for (int i = ns; i < n; ++i)
      o->others.push_back((int)idx[i]);
    for (int i = 0; i < nd; ++i)
      o->other_rolls.push_back((int)idx[n + i]);
    for (int i = 0; i < nd; ++i)
      o->hinges.push_back((int)idx[n + nd + i]);
    bool ok = (int)constants[12] == 2 && (o->method == 0 || (o->method == 1 && nd == 1 && ns == 2))
              && (o->method != 0 || 2 * nd == ns);
    for (int c : o->chain)
      ok = ok && c >= 0 && c < n;
    for (int c : o->others)
      ok = ok && c >= 0 && c < n;
    for (int c : o->other_rolls)
      ok = ok && c >= 0 && c < n - ns;
    for (int h : o->hinges)
      ok = ok && h >= 1 && h < minimal_joints(point);
    for (int a : o->axes)
      ok = ok && a >= 0 && a < 3;
    if (!ok)
    {
      delete o;
      error = "the outer loop's constants: an index out of range, or a solve that does not fit the chain";
      return nullptr;
    }
    const int nv = minimal_nv(point);
    o->mass.resize(n * n);
    o->point_mass.resize(nv * nv);
    o->point_nle.resize(nv);
    o->jacobians.resize(6 * nv * nd);
    o->ms.resize(ns * ns);
    o->cs.resize(ns);
    o->jh.resize(2 * nd * ns);
    o->gain.resize(ns * n);
    o->scratch.resize(4 * n * n + 8 * n);
    return o;
  }

  void outer_delete(Outer * outer)
  {
    delete outer;
  }

  bool outer_observer(const Outer * outer)
  {
    return outer->bandwidth > 0.0;
  }

  bool outer_update(Outer * o, double t, const double * q, const double * v, const double * m_p, const double * t_map,
                    const double * own, const double * motion, const double * planned_force, const double * rate,
                    OuterState & s)
  {
    const int n = o->n, ns = o->ns, nd = o->nd, no = n - ns;
    // the integral of the chain error, held while the force is limited
    if (std::isfinite(s.last_outer) && !s.limited)
      for (int i = 0; i < ns; ++i)
      {
        const double error = q[o->chain[i]] - motion[i];
        s.integral[i] = clip(s.integral[i] + error * (t - s.last_outer), -o->limit, o->limit);
      }
    s.limited = false;
    // M(q) = T^T M_p T of the controller's model (Robot.mass_matrix)
    double * mass = o->mass.data();
    if (o->bandwidth > 0.0 || o->momentum)
    {
      double * left = o->scratch.data(); // T^T M_p
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j)
        {
          double sum = 0.0;
          for (int p = 0; p < n; ++p)
            sum += t_map[p * n + i] * m_p[p * n + j];
          left[i * n + j] = sum;
        }
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j)
        {
          double sum = 0.0;
          for (int p = 0; p < n; ++p)
            sum += left[i * n + p] * t_map[p * n + j];
          mass[i * n + j] = sum;
        }
    }
    // the momentum observer's update (MomentumObserver.update), the inputs' mean force since the last one
    if (o->bandwidth > 0.0)
    {
      const double dt = std::isfinite(s.last_outer) ? t - s.last_outer : 0.0;
      for (int i = 0; i < n; ++i)
      {
        const double applied = s.ticks ? s.applied[i] / (double)s.ticks : 0.0;
        double momentum = 0.0, drift = 0.0;
        for (int j = 0; j < n; ++j)
        {
          momentum += mass[i * n + j] * v[j];
          drift += (mass[i * n + j] - s.last_mass[i * n + j]) * (0.5 * (v[j] + s.last_velocity[j]));
        }
        drift -= 0.5 * dt * (own[i] + s.last_nle[i]);
        s.observer_integral[i] = s.observer_integral[i] + drift + dt * (applied + s.estimate[i]);
        o->scratch[3 * n * n + i] = momentum;
      }
      for (int i = 0; i < n; ++i)
        s.estimate[i] = o->bandwidth * (o->scratch[3 * n * n + i] - s.start[i] - s.observer_integral[i]);
      std::copy(mass, mass + n * n, s.last_mass);
      std::copy(v, v + n, s.last_velocity);
      std::copy(own, own + n, s.last_nle);
      std::fill(s.applied, s.applied + n, 0.0);
      s.ticks = 0;
    }
    // the chain's errors, of the state its momentum stands for with momentum feedback (CascadedController.outer)
    double * error = o->scratch.data() + n * n;
    double * rate_error = error + n;
    double * position = rate_error + n;
    double * rate_o = position + n;
    double * u = rate_o + n;
    double * b = u + n;
    double * mss = b + n;
    for (int i = 0; i < ns; ++i)
    {
      error[i] = q[o->chain[i]] - motion[i];
      rate_error[i] = v[o->chain[i]] - motion[ns + i];
    }
    if (o->momentum)
    {
      double * gain = o->gain.data(); // M_ss^-1 M_so (ns x no)
      for (int i = 0; i < ns; ++i)
      {
        for (int j = 0; j < ns; ++j)
          mss[i * ns + j] = mass[o->chain[i] * n + o->chain[j]];
        for (int j = 0; j < no; ++j)
          gain[i * no + j] = mass[o->chain[i] * n + o->others[j]];
      }
      if (!lu_solve(mss, ns, gain, no))
        return false;
      for (int j = 0; j < no; ++j)
      {
        position[j] = q[o->others[j]];
        rate_o[j] = v[o->others[j]];
      }
      for (int d = 0; d < nd; ++d) // the rolls' references: the planned thrust vectors' attitudes (2.20)
      {
        const int r = o->other_rolls[d];
        const double planned = std::atan2(-planned_force[2 * d], planned_force[2 * d + 1]);
        position[r] = remainder_floored(position[r] - planned + M_PI, 2 * M_PI) - M_PI;
        rate_o[r] -= rate[d];
      }
      for (int i = 0; i < ns; ++i)
      {
        double p = 0.0, r = 0.0;
        for (int j = 0; j < no; ++j)
        {
          p += gain[i * no + j] * position[j];
          r += gain[i * no + j] * rate_o[j];
        }
        error[i] += p;
        rate_error[i] += r;
      }
    }
    for (int i = 0; i < ns; ++i)
      u[i] = motion[2 * ns + i] - o->kp * error[i] - o->kd * rate_error[i] - o->ki * s.integral[i];
    // the point-drone model: M_s = T^T M T, c_s = T^T nle, J_h (the force axes' rows of each hinge) T
    const int nv = minimal_nv(o->point);
    const double * chain_map = minimal_map(o->point);
    double * s_q = position; // the chain's s and s' (the scratch of position and rate, done with)
    double * s_v = rate_o;
    for (int i = 0; i < ns; ++i)
    {
      s_q[i] = q[o->chain[i]];
      s_v[i] = v[o->chain[i]];
    }
    minimal_joint_terms(o->point, s_q, s_v, o->point_mass.data(), o->point_nle.data(), o->hinges,
                        o->jacobians.data());
    double * left = o->scratch.data(); // T^T M (ns x nv)
    for (int i = 0; i < ns; ++i)
      for (int j = 0; j < nv; ++j)
      {
        double sum = 0.0;
        for (int p = 0; p < nv; ++p)
          sum += chain_map[p * ns + i] * o->point_mass[p * nv + j];
        left[i * nv + j] = sum;
      }
    for (int i = 0; i < ns; ++i)
    {
      for (int j = 0; j < ns; ++j)
      {
        double sum = 0.0;
        for (int p = 0; p < nv; ++p)
          sum += left[i * nv + p] * chain_map[p * ns + j];
        o->ms[i * ns + j] = sum;
      }
      double sum = 0.0;
      for (int p = 0; p < nv; ++p)
        sum += chain_map[p * ns + i] * o->point_nle[p];
      o->cs[i] = sum;
    }
    for (int d = 0; d < nd; ++d)
      for (int a = 0; a < 2; ++a)
        for (int j = 0; j < ns; ++j)
        {
          const double * row = o->jacobians.data() + (6 * d + o->axes[a]) * nv;
          double sum = 0.0;
          for (int p = 0; p < nv; ++p)
            sum += row[p] * chain_map[p * ns + j];
          o->jh[(2 * d + a) * ns + j] = sum;
        }
    for (int i = 0; i < ns; ++i)
    {
      double sum = 0.0;
      for (int j = 0; j < ns; ++j)
        sum += o->ms[i * ns + j] * u[j];
      b[i] = sum + o->cs[i];
      if (o->bandwidth > 0.0)
        b[i] -= s.estimate[o->chain[i]];
    }
    // the robot kind's solve J_h^T F = b
    if (o->method == 0)
    {
      double * jt = mss; // J_h^T (ns x ns)
      for (int i = 0; i < ns; ++i)
        for (int j = 0; j < ns; ++j)
          jt[i * ns + j] = o->jh[j * ns + i];
      if (!lu_solve(jt, ns, b, 1))
        return false;
      std::copy(b, b + ns, s.force);
    }
    else // the two-link chain's tension regularised towards the planned one (prototype_thrust.regularised_force)
    {
      const double length = o->length, q12 = s_q[0] + s_q[1];
      const double along0 = std::cos(q12), along1 = std::sin(q12);
      const double g = b[0] - b[1] * (1.0 + std::cos(s_q[1])), f_p = b[1] / length;
      const double lever = length * std::sin(s_q[1]);
      const double width = length * std::sin(o->band);
      double eps2 = width * width;
      eps2 *= std::max(0.0, 1.0 - lever * lever / (100.0 * eps2));
      const double f_r = (lever * g + eps2 * (planned_force[0] * along0 + planned_force[1] * along1))
                         / (lever * lever + eps2);
      s.force[0] = f_r * along0 - f_p * along1;
      s.force[1] = f_r * along1 + f_p * along0;
    }
    for (int i = 0; i < 2 * nd; ++i)
      if (!std::isfinite(s.force[i]))
        return false;
    s.last_outer = t;
    return true;
  }

} // namespace fpr_native
