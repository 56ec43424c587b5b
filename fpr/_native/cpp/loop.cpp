// The closed loop's plain ticks natively (fpr._native's part "loop"): fpr/sim/closed_loop.py's simulate and
// controllers/ctc.py's CascadedController.update between two outer-loop updates, tick after tick without the
// interpreter: the plant's points and closure error, the measurement (measure.cpp), the watch's screen, the inner
// loop's float part, the attitude model (minimal.cpp and attitude.c) with the observer's estimate, the allocation,
// the rotor speeds, the observer's sum of applied forces, the log's row, and the plant's steps (plant.cpp). The
// C kernels are the C parts' own (alloc.c, attitude.c, watch.c), called through their capsules (kernels.h).
//
// Loop(plant, measure, attitude, point, alloc_constants, alloc_state, inner_constants, attitude_constants,
//      screen_constants, outer_constants, ticks, motion, thrust_vectors, rate, acceleration, chain, logs, dt, steps,
//      w_max, decay, wind, observer, force_limits, authority=None)
//   plant, measure, attitude: the native Plant, Measure and the controller model's Minimal (module.cpp); point: the
//   Minimal of the controller's point-drone model on the chain (its T the chain map), or None; the constants vectors
//   of the allocation, the inner loop, the attitude model and the watch's screen (as the Python side gives them to
//   alloc.c's tick and inner, attitude.c's post, watch.c's may_be_lost) and of the outer loop (outer.cpp; None:
//   the outer-loop updates are the Python side's); alloc_state: the allocator's int8 active bounds (updated in
//   place); ticks (n_t), the plan's s_d and its derivatives 0..4 (n_t, 5, n_s), its thrust vectors (n_t, n_d, 2),
//   attitude rates and accelerations (n_t, n_d); chain: the chain's indices in q; logs: the simulation log's
//   preallocated arrays (q, v, speed, closure_error, drone_height, attitude_desired, speed_command, thrust, torque,
//   saturated (bool), disturbance), row k written at tick k; dt, steps (per tick), w_max, the motor lag's decay
//   (3), wind (3 n_d) or None; observer: whether the controller has its observer (bandwidth > 0); force_limits:
//   whether a new force whose allocation has a rotor at a bound goes to the force limiter (the Python side's);
//   authority: the drones' authority sets' constants (controllers/authority.py), or None: a new force that leaves
//   one goes to the Python side's AuthoritySet.hold.
// run(k, stop, qc, vc, w, reference, integral, estimate, start, observer_integral, last_mass, last_velocity,
//     last_nle, force, applied, ticks, time, last_outer, limited, outer_threshold, report_at, tick)
//   -> (k, time, ticks, last_outer, limited, closed_form, active_set)
//   ticks k, k + 1, ... before `stop`, each done whole or not at all; it returns at the first tick it does not do
//   (a progress report due, the screen firing, a kernel declining, the plant's steps failing, an outer-loop
//   update it cannot do, whose allocation has a rotor at a bound with force_limits or whose force leaves an
//   authority set) with that tick's index: the
//   Python side does that tick with its own code on the same state. The arrays (the plant's state, the
//   measurement's reference, the controller's integral, observer state (None without one), held force (n_d, 2) and
//   applied forces' sum) are updated in place; the scalars come back: the plant's time, the applied forces' count,
//   the last outer update's time, the limiter's flag, and the allocation's routes taken.
#define PY_SSIZE_T_CLEAN
#include "native.hpp"

#include "../kernels.h"

#include <cmath>
#include <cstring>
#include <exception>
#include <vector>

namespace
{
  using namespace fpr_native;

  // A C-contiguous buffer of float64 ('d'), int8 ('b') or bool ('?') of `size` items (any size when < 0), or
  // false with an exception naming `what`.
  bool get_buffer(PyObject * obj, Py_buffer & view, char format, Py_ssize_t size, bool writable, const char * what)
  {
    if (PyObject_GetBuffer(obj, &view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0)) < 0)
      return false;
    const char * f = view.format == nullptr ? "B" : view.format;
    if (f[0] == '<' || f[0] == '=' || f[0] == '@')
      ++f;
    const Py_ssize_t itemsize = format == 'd' ? 8 : 1;
    if (f[0] != format || f[1] != 0 || view.itemsize != itemsize || (size >= 0 && view.len != size * itemsize))
    {
      PyErr_Format(PyExc_ValueError, "Loop: %s must be a C-contiguous array of %zd '%c' items", what, size, format);
      PyBuffer_Release(&view);
      return false;
    }
    return true;
  }

  double * doubles(Py_buffer & view)
  {
    return static_cast<double *>(view.buf);
  }

  template<typename Api>
  const Api * capsule(const char * name)
  {
    const Api * api = static_cast<const Api *>(PyCapsule_Import(name, 0));
    if (api != nullptr && api->version != FPR_KERNELS_VERSION)
    {
      PyErr_Format(PyExc_ImportError, "%s: kernels of another version (rebuild: pip install -e .)", name);
      return nullptr;
    }
    return api;
  }

  enum Log
  {
    LOG_Q,
    LOG_V,
    LOG_SPEED,
    LOG_CLOSURE,
    LOG_HEIGHT,
    LOG_ATTITUDE,
    LOG_COMMAND,
    LOG_THRUST,
    LOG_TORQUE,
    LOG_SATURATED,
    LOG_DISTURBANCE,
    LOGS
  };

  enum Constants
  {
    K_ALLOC,
    K_INNER,
    K_ATTITUDE,
    K_SCREEN,
    K_OUTER,
    K_TICKS,
    K_MOTION,
    K_THRUST,
    K_RATE,
    K_ACCELERATION,
    K_DECAY,
    K_WIND,
    K_STATE,
    K_AUTHORITY,
    BUFFERS
  };

  struct LoopObject
  {
    PyObject_HEAD PyObject * keep; // the Python objects whose C++ objects or buffers the loop uses
    Plant * plant;
    Measure * measure;
    Minimal * attitude;
    Outer * outer;
    const FprAllocApi * alloc;
    const FprAttitudeApi * attitude_api;
    const FprWatchApi * watch;
    Py_buffer buffers[BUFFERS];
    Py_buffer logs[LOGS];
    bool held[BUFFERS];
    bool logs_held[LOGS];
    bool wind, observer, force_limits, authority;
    int n, nd, na, ns, nqc, nvc, nw, steps;
    long n_t;
    double dt, w_max;
    std::vector<int> * chain;
    std::vector<double> * scratch;
    std::vector<double> * work; // the outer update's working copy of the controller's state
  };

  void loop_release(LoopObject * p)
  {
    for (int b = 0; b < BUFFERS; ++b)
      if (p->held[b])
        PyBuffer_Release(&p->buffers[b]);
    for (int b = 0; b < LOGS; ++b)
      if (p->logs_held[b])
        PyBuffer_Release(&p->logs[b]);
    std::memset(p->held, 0, sizeof(p->held));
    std::memset(p->logs_held, 0, sizeof(p->logs_held));
    delete p->chain;
    delete p->scratch;
    delete p->work;
    outer_delete(p->outer);
    p->chain = nullptr;
    p->scratch = nullptr;
    p->work = nullptr;
    p->outer = nullptr;
    Py_CLEAR(p->keep);
    p->plant = nullptr;
  }

  void loop_dealloc(PyObject * self)
  {
    loop_release(reinterpret_cast<LoopObject *>(self));
    Py_TYPE(self)->tp_free(self);
  }

  int loop_init(PyObject * self, PyObject * args, PyObject * kwargs)
  {
    auto * p = reinterpret_cast<LoopObject *>(self);
    loop_release(p);
    static const char * names[] = {"plant", "measure", "attitude", "point", "alloc_constants", "alloc_state",
                                   "inner_constants", "attitude_constants", "screen_constants", "outer_constants",
                                   "ticks", "motion", "thrust_vectors", "rate", "acceleration", "chain", "logs", "dt",
                                   "steps", "w_max", "decay", "wind", "observer", "force_limits", "authority",
                                   nullptr};
    PyObject *o_plant, *o_measure, *o_attitude, *o_point, *o_alloc, *o_state, *o_inner, *o_att, *o_screen, *o_outer,
      *o_ticks, *o_motion, *o_thrust, *o_rate, *o_acc, *o_chain, *o_logs, *o_decay, *o_wind, *o_authority = Py_None;
    double dt = 0.0, w_max = 0.0;
    int steps = 0, observer = 0, force_limits = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OOOOOOOOOOOOOOOOOdidOOpp|O", const_cast<char **>(names), &o_plant,
                                     &o_measure, &o_attitude, &o_point, &o_alloc, &o_state, &o_inner, &o_att,
                                     &o_screen, &o_outer, &o_ticks, &o_motion, &o_thrust, &o_rate, &o_acc, &o_chain,
                                     &o_logs, &dt, &steps, &w_max, &o_decay, &o_wind, &observer, &force_limits,
                                     &o_authority))
      return -1;
    p->plant = plant_from(o_plant, "Loop: plant");
    p->measure = p->plant ? measure_from(o_measure, "Loop: measure") : nullptr;
    p->attitude = p->measure ? minimal_from(o_attitude, "Loop: attitude") : nullptr;
    if (p->attitude == nullptr)
      return -1;
    Minimal * point = nullptr;
    if (o_point != Py_None && (point = minimal_from(o_point, "Loop: point")) == nullptr)
      return -1;
    p->alloc = capsule<FprAllocApi>("fpr._native._alloc._C_API");
    p->attitude_api = p->alloc ? capsule<FprAttitudeApi>("fpr._native._attitude._C_API") : nullptr;
    p->watch = p->attitude_api ? capsule<FprWatchApi>("fpr._native._watch._C_API") : nullptr;
    if (p->watch == nullptr)
      return -1;
    if (!(dt > 0.0) || steps < 1 || !PyTuple_Check(o_logs) || PyTuple_GET_SIZE(o_logs) != LOGS)
    {
      PyErr_SetString(PyExc_ValueError, "Loop: dt > 0, steps >= 1 and a tuple of the 11 log arrays");
      return -1;
    }
    PyObject * const constants[4] = {o_alloc, o_inner, o_att, o_screen};
    for (int b = 0; b < 4; ++b)
      if (!(p->held[b] = get_buffer(constants[b], p->buffers[b], 'd', -1, false, "a constants vector")))
        return -1;
    const double *ka = doubles(p->buffers[K_ALLOC]), *kt = doubles(p->buffers[K_ATTITUDE]);
    if (p->buffers[K_ALLOC].len < 16 || p->buffers[K_ATTITUDE].len < 24)
    {
      PyErr_SetString(PyExc_ValueError, "Loop: the constants vectors are too short");
      return -1;
    }
    p->nd = (int)ka[0];
    p->na = (int)ka[1];
    p->n = (int)kt[0];
    p->nw = 4 * p->nd;
    p->nqc = plant_nq(p->plant);
    p->nvc = plant_nv(p->plant);
    p->chain = new std::vector<int>();
    p->scratch = new std::vector<double>();
    p->work = new std::vector<double>();
    PyObject * chain_fast = PySequence_Fast(o_chain, "Loop: chain must be a sequence of indices");
    if (chain_fast == nullptr)
      return -1;
    for (Py_ssize_t i = 0; i < PySequence_Fast_GET_SIZE(chain_fast); ++i)
    {
      const long c = PyLong_AsLong(PySequence_Fast_GET_ITEM(chain_fast, i));
      if (c == -1 && PyErr_Occurred())
        break;
      p->chain->push_back((int)c);
    }
    Py_DECREF(chain_fast);
    if (PyErr_Occurred())
      return -1;
    p->ns = (int)p->chain->size();
    bool fits = (int)kt[1] == p->nd && (int)kt[2] == p->na && plant_nw(p->plant) == p->nw && p->nw <= 64
                && measure_n(p->measure) == p->n && measure_nq(p->measure) == p->nqc
                && measure_nv(p->measure) == p->nvc && minimal_n(p->attitude) == p->n
                && minimal_frames(p->attitude) == p->nd && plant_frames(p->plant) == p->nd && p->ns > 0
                && (long)p->buffers[K_ATTITUDE].len / 8 == 3 + p->na + 2 * p->n * p->n;
    for (int c : *p->chain)
      fits = fits && c >= 0 && c < p->n;
    if (!fits)
    {
      PyErr_SetString(PyExc_ValueError, "Loop: the plant, the measurement, the model and the constants do not fit");
      return -1;
    }
    if (o_outer != Py_None)
    {
      if (point == nullptr)
      {
        PyErr_SetString(PyExc_ValueError, "Loop: the outer loop's constants need the point model");
        return -1;
      }
      if (!(p->held[K_OUTER] = get_buffer(o_outer, p->buffers[K_OUTER], 'd', -1, false, "outer_constants")))
        return -1;
      std::string error;
      p->outer = outer_new(point, doubles(p->buffers[K_OUTER]), (long)(p->buffers[K_OUTER].len / 8), p->n, error);
      if (p->outer == nullptr)
      {
        PyErr_SetString(PyExc_ValueError, ("Loop: " + error).c_str());
        return -1;
      }
      if (outer_observer(p->outer) != (observer != 0))
      {
        PyErr_SetString(PyExc_ValueError, "Loop: the outer loop's observer and `observer` disagree");
        return -1;
      }
    }
    if (!(p->held[K_TICKS] = get_buffer(o_ticks, p->buffers[K_TICKS], 'd', -1, false, "ticks")))
      return -1;
    p->n_t = (long)(p->buffers[K_TICKS].len / 8);
    const long n_t = p->n_t;
    struct Wanted
    {
      int index;
      PyObject * obj;
      Py_ssize_t size;
      const char * what;
    } wanted[] = {{K_MOTION, o_motion, n_t * 5 * p->ns, "motion"},
                  {K_THRUST, o_thrust, n_t * 2 * p->nd, "thrust_vectors"},
                  {K_RATE, o_rate, n_t * p->nd, "rate"},
                  {K_ACCELERATION, o_acc, n_t * p->nd, "acceleration"},
                  {K_DECAY, o_decay, 3, "decay"}};
    for (const auto & w : wanted)
      if (!(p->held[w.index] = get_buffer(w.obj, p->buffers[w.index], 'd', w.size, false, w.what)))
        return -1;
    p->wind = o_wind != Py_None;
    if (p->wind && !(p->held[K_WIND] = get_buffer(o_wind, p->buffers[K_WIND], 'd', 3 * p->nd, false, "wind")))
      return -1;
    if (!(p->held[K_STATE] = get_buffer(o_state, p->buffers[K_STATE], 'b', p->nw, true, "alloc_state")))
      return -1;
    const Py_ssize_t widths[LOGS] = {p->n, p->n, p->nw, 1, p->nd, p->nd, p->nw, p->nd, 3 * p->nd, p->nw, p->ns};
    for (int b = 0; b < LOGS; ++b)
      if (!(p->logs_held[b] = get_buffer(PyTuple_GET_ITEM(o_logs, b), p->logs[b], b == LOG_SATURATED ? '?' : 'd',
                                         n_t * widths[b], true, "a log array")))
        return -1;
    p->dt = dt;
    p->steps = steps;
    p->w_max = w_max;
    p->observer = observer != 0;
    p->force_limits = force_limits != 0;
    p->authority = o_authority != Py_None;
    if (p->authority)
    {
      if (!(p->held[K_AUTHORITY] = get_buffer(o_authority, p->buffers[K_AUTHORITY], 'd', -1, false, "authority")))
        return -1;
      if (!authority_fits(doubles(p->buffers[K_AUTHORITY]), (long)(p->buffers[K_AUTHORITY].len / 8), p->nd, p->n))
      {
        PyErr_SetString(PyExc_ValueError, "Loop: the authority set's constants do not fit the drones");
        return -1;
      }
    }
    p->keep = PyTuple_Pack(4, o_plant, o_measure, o_attitude, o_point);
    return p->keep == nullptr ? -1 : 0;
  }

  // The state one tick reads and writes: the plant's, the measurement's reference, the controller's
  struct Tick
  {
    double * qc;
    double * vc;
    double * w;
    double * reference;
    OuterState controller;
    double time;
    long routes[2];
  };

  // The working copy of the controller's state in `work` (the outer update writes it; the tick commits it)
  OuterState working_copy(LoopObject * p, const OuterState & from)
  {
    const int n = p->n, ns = p->ns, nd = p->nd;
    std::vector<double> & w = *p->work;
    w.resize(ns + 6 * n + n * n + 2 * nd);
    OuterState to = from;
    double * at = w.data();
    auto take = [&](double *& field, const double * source, int size) {
      field = at;
      at += size;
      if (source != nullptr)
        std::memcpy(field, source, sizeof(double) * size);
    };
    take(to.integral, from.integral, ns);
    take(to.force, from.force, 2 * nd);
    take(to.applied, from.applied, n);
    if (p->observer)
    {
      take(to.estimate, from.estimate, n);
      take(to.start, from.start, n);
      take(to.observer_integral, from.observer_integral, n);
      take(to.last_mass, from.last_mass, n * n);
      take(to.last_velocity, from.last_velocity, n);
      take(to.last_nle, from.last_nle, n);
    }
    return to;
  }

  void commit(LoopObject * p, const OuterState & from, OuterState & to)
  {
    const int n = p->n, ns = p->ns, nd = p->nd;
    std::memcpy(to.integral, from.integral, sizeof(double) * ns);
    std::memcpy(to.force, from.force, sizeof(double) * 2 * nd);
    std::memcpy(to.applied, from.applied, sizeof(double) * n);
    if (p->observer)
    {
      std::memcpy(to.estimate, from.estimate, sizeof(double) * n);
      std::memcpy(to.observer_integral, from.observer_integral, sizeof(double) * n);
      std::memcpy(to.last_mass, from.last_mass, sizeof(double) * n * n);
      std::memcpy(to.last_velocity, from.last_velocity, sizeof(double) * n);
      std::memcpy(to.last_nle, from.last_nle, sizeof(double) * n);
    }
    to.ticks = from.ticks;
    to.last_outer = from.last_outer;
    to.limited = from.limited;
  }

  bool one_tick(LoopObject * p, long k, double t, bool outer_due, Tick & s)
  {
    const int n = p->n, nd = p->nd, na = p->na, ns = p->ns, nqc = p->nqc, nvc = p->nvc, nw = p->nw, nt = 3 * nd;
    std::vector<double> & b = *p->scratch;
    // the scratch, in pieces
    const std::size_t sizes[] = {(std::size_t)n,       (std::size_t)n,        3 * (std::size_t)nd, (std::size_t)nd,
                                 (std::size_t)na,      (std::size_t)nd,       (std::size_t)(n * n), (std::size_t)n,
                                 (std::size_t)(6 * nd * n), (std::size_t)(na * n), (std::size_t)(nt * n),
                                 (std::size_t)(nd * n), (std::size_t)(na * nt), (std::size_t)n, (std::size_t)n,
                                 (std::size_t)nw,      (std::size_t)nd,       (std::size_t)nt,     (std::size_t)nw,
                                 (std::size_t)nqc,     (std::size_t)nvc,      (std::size_t)nw,     (std::size_t)nw};
    std::size_t total = 0;
    for (std::size_t size : sizes)
      total += size;
    if (b.size() != total)
      b.assign(total, 0.0);
    double * piece[sizeof(sizes) / sizeof(sizes[0])];
    double * at = b.data();
    for (std::size_t i = 0; i < sizeof(sizes) / sizeof(sizes[0]); ++i)
    {
      piece[i] = at;
      at += sizes[i];
    }
    double *q = piece[0], *v = piece[1], *positions = piece[2], *thrust_d = piece[3], *u_a = piece[4],
           *roll = piece[5], *m = piece[6], *nle = piece[7], *jac = piece[8], *mi = piece[9], *jt = piece[10],
           *jf = piece[11], *a_tau = piece[12], *own = piece[13], *c = piece[14], *z = piece[15],
           *thrust = piece[16], *tau = piece[17], *speeds = piece[18], *q_next = piece[19], *v_next = piece[20],
           *w_next = piece[21], *command = piece[22];
    double closure = 0.0;
    if (!fpr_native::measure(p->measure, s.qc, s.vc, s.reference, q, v))
      return false;
    if (!plant_points(p->plant, s.qc, positions, closure))
      return false;
    const double * motion = doubles(p->buffers[K_MOTION]) + k * 5 * ns;
    if (p->watch->screen(s.qc, nqc, s.vc, nvc, q, v, n, positions, nd, closure, motion, ns,
                         doubles(p->buffers[K_SCREEN]), (long)(p->buffers[K_SCREEN].len / 8))
        != 0)
      return false; // may be lost (or constants that do not fit): the Python check decides
    minimal_frame_terms(p->attitude, q, v, m, nle, jac);
    if (p->attitude_api->post(m, nle, jac, doubles(p->buffers[K_ATTITUDE]), (long)(p->buffers[K_ATTITUDE].len / 8),
                              mi, jt, jf, a_tau, own)
        != 1)
      return false;
    OuterState next = s.controller; // the controller's state after this tick (a working copy when it updates)
    const double * rate = doubles(p->buffers[K_RATE]) + k * nd;
    if (outer_due)
    {
      next = working_copy(p, s.controller);
      const double * t_map = doubles(p->buffers[K_ATTITUDE]) + 3 + na; // the controller model's T
      if (!outer_update(p->outer, t, q, v, m, t_map, own, motion, doubles(p->buffers[K_THRUST]) + k * 2 * nd, rate,
                        next))
        return false;
      if (p->authority && !authority_inside(doubles(p->buffers[K_AUTHORITY]), next.force, q))
        return false; // a drone without the authority to turn: the forces chosen together (controllers/authority.py)
    }
    const double * estimate = p->observer ? next.estimate : nullptr;
    double pitch = 0.0;
    if (p->alloc->inner(q, v, n, next.force, rate, doubles(p->buffers[K_ACCELERATION]) + k * nd,
                        doubles(p->buffers[K_INNER]), (long)(p->buffers[K_INNER].len / 8), thrust_d, u_a, roll,
                        &pitch)
        != 1)
      return false;
    for (int i = 0; i < n; ++i) // the estimated force, as a known wind (CascadedController.update)
      c[i] = estimate == nullptr ? own[i] : own[i] - estimate[i];
    signed char state[64];
    std::memcpy(state, p->buffers[K_STATE].buf, nw);
    unsigned long long bits = 0;
    int route = 0, iterations = 0;
    if (p->alloc->tick(mi, jf, a_tau, c, n, thrust_d, u_a, doubles(p->buffers[K_ALLOC]),
                       (long)(p->buffers[K_ALLOC].len / 8), state, z, thrust, tau, &bits, &route, &iterations)
        != 1)
      return false;
    if (outer_due && p->force_limits && bits != 0)
      return false; // a new force the rotors cannot follow: the force limiter's (controllers/saturation.py)
    for (int i = 0; i < nw; ++i)
    {
      const double zi = z[i];
      speeds[i] = std::sqrt(zi >= 0.0 || std::isnan(zi) ? zi : 0.0); // np.sqrt(np.maximum(z, 0.0))
      const double cmd = speeds[i];
      command[i] = cmd < 0.0 ? 0.0 : cmd; // Plant.saturate (NaN stays NaN)
      if (command[i] > p->w_max)
        command[i] = p->w_max;
    }
    std::memcpy(q_next, s.qc, sizeof(double) * nqc);
    std::memcpy(v_next, s.vc, sizeof(double) * nvc);
    std::memcpy(w_next, s.w, sizeof(double) * nw);
    long done = 0;
    if (plant_steps(p->plant, q_next, v_next, w_next, command, doubles(p->buffers[K_DECAY]), p->dt, p->steps,
                    p->wind ? doubles(p->buffers[K_WIND]) : nullptr, done)
        != STEPS_DONE)
      return false; // the Python side steps again and reports the divergence
    // the tick is done: its log row, the sums, the state
    auto row = [&](int log, int width) { return doubles(p->logs[log]) + k * width; };
    std::memcpy(row(LOG_Q, n), q, sizeof(double) * n);
    std::memcpy(row(LOG_V, n), v, sizeof(double) * n);
    std::memcpy(row(LOG_SPEED, nw), s.w, sizeof(double) * nw);
    row(LOG_CLOSURE, 1)[0] = closure;
    for (int d = 0; d < nd; ++d)
      row(LOG_HEIGHT, nd)[d] = positions[3 * d + 2];
    std::memcpy(row(LOG_ATTITUDE, nd), roll, sizeof(double) * nd);
    std::memcpy(row(LOG_COMMAND, nw), speeds, sizeof(double) * nw);
    std::memcpy(row(LOG_THRUST, nd), thrust, sizeof(double) * nd);
    std::memcpy(row(LOG_TORQUE, nt), tau, sizeof(double) * nt);
    bool * saturated = static_cast<bool *>(p->logs[LOG_SATURATED].buf) + k * nw;
    for (int i = 0; i < nw; ++i)
      saturated[i] = (bits >> i & 1ULL) != 0;
    double * disturbance = row(LOG_DISTURBANCE, ns);
    for (int i = 0; i < ns; ++i)
      disturbance[i] = estimate == nullptr ? 0.0 : estimate[(*p->chain)[i]];
    if (p->observer) // the inputs' generalised force until the next tick, and the known wind's (none here)
    {
      for (int i = 0; i < n; ++i)
      {
        double from_thrust = 0.0, from_torque = 0.0;
        for (int d = 0; d < nd; ++d)
          from_thrust += jf[d * n + i] * thrust[d];
        for (int r = 0; r < nt; ++r)
          from_torque += jt[r * n + i] * tau[r];
        const double known = estimate == nullptr ? own[i] - c[i] : own[i] - c[i] - estimate[i];
        next.applied[i] += from_thrust + from_torque + known;
      }
      ++next.ticks;
    }
    if (outer_due)
      commit(p, next, s.controller);
    else
      s.controller.ticks = next.ticks;
    std::memcpy(p->buffers[K_STATE].buf, state, nw);
    ++s.routes[route];
    std::memcpy(s.reference, q, sizeof(double) * n);
    std::memcpy(s.qc, q_next, sizeof(double) * nqc);
    std::memcpy(s.vc, v_next, sizeof(double) * nvc);
    std::memcpy(s.w, w_next, sizeof(double) * nw);
    for (long i = 0; i < done; ++i)
      s.time += p->dt;
    return true;
  }

  PyObject * loop_run(PyObject * self, PyObject * args)
  {
    auto * p = reinterpret_cast<LoopObject *>(self);
    if (p->plant == nullptr)
    {
      PyErr_SetString(PyExc_RuntimeError, "Loop: not initialised");
      return nullptr;
    }
    enum
    {
      QC,
      VC,
      W,
      REFERENCE,
      INTEGRAL,
      ESTIMATE,
      START,
      OBSERVER_INTEGRAL,
      LAST_MASS,
      LAST_VELOCITY,
      LAST_NLE,
      FORCE,
      APPLIED,
      ARRAYS
    };
    long k = 0, stop = 0, ticks_count = 0;
    int limited = 0;
    PyObject * objects[ARRAYS];
    double time = 0.0, last_outer = 0.0, threshold = 0.0, report_at = 0.0, tick = 0.0;
    if (!PyArg_ParseTuple(args, "llOOOOOOOOOOOOOlddpddd", &k, &stop, &objects[QC], &objects[VC], &objects[W],
                          &objects[REFERENCE], &objects[INTEGRAL], &objects[ESTIMATE], &objects[START],
                          &objects[OBSERVER_INTEGRAL], &objects[LAST_MASS], &objects[LAST_VELOCITY],
                          &objects[LAST_NLE], &objects[FORCE], &objects[APPLIED], &ticks_count, &time, &last_outer,
                          &limited, &threshold, &report_at, &tick))
      return nullptr;
    const int n = p->n;
    const Py_ssize_t sizes[ARRAYS] = {p->nqc, p->nvc, p->nw, n, p->ns, n, n, n, n * n, n, n, 2 * p->nd, n};
    const char * what[ARRAYS] = {"qc",        "vc",           "w",            "reference", "integral",
                                 "estimate",  "start",        "observer_integral", "last_mass", "last_velocity",
                                 "last_nle",  "force",        "applied"};
    Py_buffer views[ARRAYS];
    bool held[ARRAYS] = {false};
    PyObject * result = nullptr;
    bool ok = true;
    for (int i = 0; i < ARRAYS && ok; ++i)
    {
      const bool observer_part = i >= ESTIMATE && i <= LAST_NLE;
      if (observer_part && !p->observer)
        continue; // None without an observer
      ok = held[i] = get_buffer(objects[i], views[i], 'd', sizes[i], true, what[i]);
    }
    if (ok)
    {
      auto at = [&](int i) { return held[i] ? doubles(views[i]) : nullptr; };
      Tick s = {at(QC), at(VC), at(W), at(REFERENCE),
                OuterState{at(INTEGRAL), at(ESTIMATE), at(START), at(OBSERVER_INTEGRAL), at(LAST_MASS),
                           at(LAST_VELOCITY), at(LAST_NLE), at(FORCE), at(APPLIED), ticks_count, last_outer,
                           limited != 0},
                time, {0, 0}};
      const double * ticks = doubles(p->buffers[K_TICKS]);
      if (stop > p->n_t)
        stop = p->n_t;
      for (; k < stop; ++k)
      {
        const double t = ticks[k];
        const bool outer_due = t - s.controller.last_outer >= threshold;
        if ((outer_due && p->outer == nullptr) || t + tick >= report_at)
          break; // an outer-loop update the Python side does, or a progress report
        bool done = false;
        try
        {
          done = one_tick(p, k, t, outer_due, s);
        }
        catch (const std::exception &)
        {
          done = false; // the Python side does the tick (and raises what its path raises)
        }
        if (!done)
          break;
      }
      result = Py_BuildValue("ldldNll", k, s.time, s.controller.ticks, s.controller.last_outer,
                             PyBool_FromLong(s.controller.limited), s.routes[0], s.routes[1]);
    }
    for (int i = 0; i < ARRAYS; ++i)
      if (held[i])
        PyBuffer_Release(&views[i]);
    return result;
  }

  PyMethodDef loop_methods[] = {
    {"run", loop_run, METH_VARARGS,
     "run(k, stop, qc, vc, w, reference, integral, estimate, start, observer_integral, last_mass, last_velocity, "
     "last_nle, force, applied, ticks, time, last_outer, limited, outer_threshold, report_at, tick) -> (k, time, "
     "ticks, last_outer, limited, closed_form, active_set): the ticks from k on (fpr/_native/cpp/loop.cpp)."},
    {nullptr, nullptr, 0, nullptr}};

  PyType_Slot loop_slots[] = {
    {Py_tp_doc, const_cast<char *>("The closed loop's plain ticks natively (fpr/_native/cpp/loop.cpp).")},
    {Py_tp_new, reinterpret_cast<void *>(PyType_GenericNew)},
    {Py_tp_init, reinterpret_cast<void *>(loop_init)},
    {Py_tp_dealloc, reinterpret_cast<void *>(loop_dealloc)},
    {Py_tp_methods, loop_methods},
    {0, nullptr}};

  PyType_Spec loop_spec = {"fpr._native._pinocchio.Loop", sizeof(LoopObject), 0, Py_TPFLAGS_DEFAULT, loop_slots};

} // namespace

namespace fpr_native
{
  bool loop_register(PyObject * module)
  {
    PyObject * type = PyType_FromSpec(&loop_spec);
    if (type == nullptr || PyModule_AddObject(module, "Loop", type) < 0)
    {
      Py_XDECREF(type);
      return false;
    }
    return true;
  }
} // namespace fpr_native
