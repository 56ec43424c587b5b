// The interface between the Python module (module.cpp) and the translation units that call Pinocchio's C++
// library (bridge.cpp, plant.cpp, minimal.cpp). Plain pointers and sizes only: module.cpp includes no Pinocchio
// or Eigen header, so that each heavy translation unit compiles on its own, in parallel.
#pragma once

#include <Python.h>

#include <string>
#include <vector>

namespace fpr_native
{

  // The C++ objects behind pinocchio's Python objects (boost::python::extract, bridge.cpp): no copy is made.
  // The compiled parts own no Pinocchio object (the Python side makes their data and constraint datas): they
  // neither construct nor destroy one, which spares their translation units the instantiation of those types.
  struct Objects
  {
    void * model = nullptr;             // pinocchio::Model (const)
    void * data = nullptr;              // pinocchio::Data, the compiled part's own scratch
    void * constraint_models = nullptr; // pinocchio::RigidConstraintModelVector (const), or nullptr
    void * constraint_datas = nullptr;  // pinocchio::RigidConstraintDataVector, initialised (initConstraintDynamics)
    void * settings = nullptr;          // pinocchio::ProximalSettings, or nullptr
  };

  // The version of Pinocchio's headers this module was compiled against (PINOCCHIO_VERSION).
  const char * pinocchio_version();

  // Fills `out` from the Python objects `model` (a pin.Model), `data` (a pin.Data of it), `constraints` and
  // `constraint_datas` (a pin.StdVec_RigidConstraintModel and its StdVec_RigidConstraintData, or None both) and
  // `settings` (a pin.ProximalSettings or None). Returns false with `error` set when an object is not of its
  // type or the sizes do not match (pinocchio must be imported: its bindings register the types).
  bool extract(PyObject * model, PyObject * data, PyObject * constraints, PyObject * constraint_datas,
               PyObject * settings, Objects & out, std::string & error);

  // The model's nq and nv (bridge.cpp).
  int model_nq(const Objects & objects);
  int model_nv(const Objects & objects);

  // ------------------------------------------------------------------ the plant (plant.cpp)
  class Plant;

  // The plant's stepper on the closed chain (`objects` with its constraints). `force_map_t` (nw x nv, row-major)
  // maps the squared rotor speeds to the generalised force; `frames` are the drones' centre frames: the wind
  // pushes them, and plant_points returns their world positions.
  Plant * plant_new(const Objects & objects, const double * force_map_t, int nw, const std::vector<int> & frames,
                    std::string & error);
  void plant_delete(Plant * plant);
  int plant_nq(const Plant * plant);
  int plant_nv(const Plant * plant);
  int plant_frames(const Plant * plant);
  int plant_nw(const Plant * plant); // rotor speeds: the force map's rows

  // Status of plant_steps.
  enum StepStatus
  {
    STEPS_DONE = 0,          // every step taken
    STEPS_NOT_FINITE = 1,    // the state turned non-finite: q, v, w hold the last finite state
    STEPS_SINGULAR = 2,      // dexp^-1 met a singular block (a turn of about 2 pi within one step)
  };

  // `steps` RKMK4 steps of length dt (fpr/sim/plant.py, Plant._python_steps): q (nq), v (nv), w (nw) are read
  // and overwritten with the state after the last step taken; w_cmd (nw) is the command, already saturated;
  // decay (3) the motor lag's decay at 0, dt/2, dt; wind (3 per frame, world axes) or nullptr. `done` is the
  // number of steps taken.
  StepStatus plant_steps(Plant * plant, double * q, double * v, double * w, const double * w_cmd,
                         const double * decay, double dt, long steps, const double * wind, long & done);

  // Constrained acceleration at (q, v) under tau (pinocchio::constraintDynamics), into a (nv).
  void plant_dynamics(Plant * plant, const double * q, const double * v, const double * tau, double * a);

  // World positions of the plant's frames (3 per frame) and the largest distance between the two points of
  // a 3D loop closure (NaN when one is), from one forward kinematics pass at q. False when a closure is not a
  // point closure (CONTACT_3D).
  bool plant_points(Plant * plant, const double * q, double * positions, double & closure_error);

  // ------------------------------------------------------------------ the minimal model (minimal.cpp)
  class Minimal;

  // The minimal model's terms at thesis coordinates: q_model = T q (T: nq_model x n, row-major). `frames`:
  // the drones' frames whose LOCAL Jacobians frame_terms() returns. For velocity(): the closed chain's rows
  // (rows x n, row-major; the free flyers' rows left zero) and, per drone, the closed chain's velocity row of
  // its free flyer and the minimal model's hinge joint whose LOCAL Jacobian fills those six rows.
  Minimal * minimal_new(const Objects & objects, const double * T, int n, const std::vector<int> & frames,
                        const double * constant_rows, int rows, const std::vector<int> & freeflyer_rows,
                        const std::vector<int> & hinges, std::string & error);
  void minimal_delete(Minimal * minimal);
  int minimal_n(const Minimal * minimal);
  int minimal_nv(const Minimal * minimal);
  int minimal_rows(const Minimal * minimal);
  int minimal_frames(const Minimal * minimal);

  // M_p (nv x nv, upper triangle as pinocchio::crba fills it, the lower left as crba leaves it), the
  // nonlinear effects (nv) and the frames' LOCAL Jacobians (6 x nv each, row-major) at (T q, T v).
  void minimal_frame_terms(Minimal * minimal, const double * q, const double * v, double * m, double * nle,
                           double * jacobians);

  // M_p (nv x nv, symmetric), the nonlinear effects (nv) and the LOCAL_WORLD_ALIGNED Jacobians of `joints` (6 x nv
  // each, row-major) at (T q, T v): the controller's point-drone model (controllers/ctc.py, _point_dynamics).
  void minimal_joint_terms(Minimal * minimal, const double * q, const double * v, double * m, double * nle,
                           const std::vector<int> & joints, double * jacobians);
  // T (nq_model x n, row-major) and the model's number of joints.
  const double * minimal_map(const Minimal * minimal);
  int minimal_joints(const Minimal * minimal);

  // The least-squares v of K(q) v = vc (K: the constant rows and the hinges' LOCAL Jacobians times T) by the
  // normal equations and a Cholesky factorisation; false when K^T K is not positive definite.
  bool minimal_velocity(Minimal * minimal, const double * q, const double * vc, double * v);

  // ------------------------------------------------------------------ the measurement (measure.cpp)
  class Measure;

  // How the robot kind's reader takes a minimal coordinate off the closed chain's joint placements
  // (fpr/model/constrained.py, ClosedChainModel.to_minimal; the readers of fpr/robots/):
  struct EulerRead // M = A oMi[joint] B: its translation and Z-Y-X Euler angles into qp
  {
    int joint;
    double A[16], B[16];  // homogeneous, row-major
    int translation[3];   // qp indices of x, y, z, or -1 (not read)
    int euler[3];         // qp indices of psi, theta, phi
    int reference[3];     // thesis indices of psi, theta, phi: the solution nearer the reference is taken
  };
  struct AngleRead // the angle about x from (oMi[joint] P) to oMi[other]: atan2(R[2,1], R[1,1]) of the relative R
  {
    int joint, other, index; // index: into qp
    double P[16];
  };

  // The measurement on the closed chain's model (`objects`: its model and data, the Python side's, which the
  // forward kinematics leaves as the Python path would): qp gets the shared joints (qp[source[k]] = sign[k]
  // qc[closed_q[k]]) and the reads, q = T_inv qp with every angle (thesis indices `angular`) within pi of the
  // reference, v by minimal_velocity on `minimal`.
  Measure * measure_new(const Objects & objects, Minimal * minimal, int nqp, const std::vector<int> & closed_q,
                        const std::vector<int> & source, const std::vector<double> & sign,
                        const std::vector<EulerRead> & eulers, const std::vector<AngleRead> & angles,
                        const double * T_inv, int n, const std::vector<int> & angular, std::string & error);
  void measure_delete(Measure * measure);
  int measure_nq(const Measure * measure);
  int measure_nv(const Measure * measure);
  int measure_n(const Measure * measure);

  // (q, v) in thesis coordinates at the closed chain's (qc, vc), the angles unwrapped to `reference` (n); false
  // when the velocity's normal equations are not positive definite (q is then set, v not).
  bool measure(Measure * measure, const double * qc, const double * vc, const double * reference, double * q,
               double * v);

  // ------------------------------------------------------------------ the outer loop (outer.cpp)
  struct Outer;

  // The controller's state the outer-loop update reads and writes (CascadedController's: the integral (n_s), the
  // observer's estimate, p(0), integral and last (M, q', nle) (n, n, n, n x n, n, n; unused without an observer),
  // the held force (n_d x 2), the applied forces' sum (n) and count, the last update's time, the limiter's flag).
  struct OuterState
  {
    double * integral;
    double * estimate;
    double * start;
    double * observer_integral;
    double * last_mass;
    double * last_velocity;
    double * last_nle;
    double * force;
    double * applied;
    long ticks;
    double last_outer;
    bool limited;
  };

  // The outer update's constants (outer.cpp says them) on the point-drone model `point` (its T: the chain map);
  // nullptr with `error` set when they do not fit.
  // Whether every drone's force (force: n_d x 2, the held force's layout) lies in its authority set, the drones at
  // their rolls in q (thesis coordinates) (controllers/authority.py, AuthoritySet.inside with no tolerance, the same
  // operations in the same order), from the set's constants (AuthoritySet.compiled_constants, `length` numbers).
  // False for a force that is not finite.
  bool authority_inside(const double * constants, const double * force, const double * q);
  // Whether `length` numbers are an authority set's constants for n_d drones whose rolls are among n coordinates
  // (or -1: the turn counted from upright).
  bool authority_fits(const double * constants, long length, int n_d, int n);

  Outer * outer_new(Minimal * point, const double * constants, long length, int n, std::string & error);
  void outer_delete(Outer * outer);
  bool outer_observer(const Outer * outer);

  // One outer-loop update at time t with the measured (q, v) (n), the controller model's M_p (n x n, symmetric)
  // and its T (n x n), its nonlinear effects T^T nle (n), the plan's s_d and its two derivatives (3 x n_s), its
  // thrust vectors (n_d x 2) and attitude rates (n_d): the state `s` updated (its force the new F); false (s then
  // partly written) when a solve is singular or F is not finite.
  bool outer_update(Outer * outer, double t, const double * q, const double * v, const double * m_p,
                    const double * t_map, const double * own, const double * motion, const double * planned_force,
                    const double * rate, OuterState & s);

  // ------------------------------------------------------------------ the Python objects (module.cpp)
  // The C++ object behind a fpr._native._pinocchio Plant, Minimal (module.cpp) or Measure (measure_module.cpp), or
  // nullptr with a TypeError set (`what` names the argument) when obj is not one or not initialised.
  Plant * plant_from(PyObject * obj, const char * what);
  Minimal * minimal_from(PyObject * obj, const char * what);
  Measure * measure_from(PyObject * obj, const char * what);

  // ------------------------------------------------------------------ the native closed loop (loop.cpp)
  // Adds the type Loop to the module; false with an exception set on failure.
  bool loop_register(PyObject * module);
  // Adds the type Measure to the module (measure_module.cpp); false with an exception set on failure.
  bool measure_register(PyObject * module);

} // namespace fpr_native
