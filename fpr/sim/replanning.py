"""Events and replanning in the closed loop: gusts pushing the plant, a replanner changing the plan in force.

:func:`fpr.sim.closed_loop.simulate` takes an ``in_flight`` object (:class:`InFlight`) with two hooks:

* ``make_plant(...)``: the plant, a :class:`ForcedPlant` that adds the mission's gusts
  (:mod:`planners.missions.events`) to the rotors' and the wind's forces: on the end-effector (the robot kind's
  task point) through J^T F of that point, or on a drone's centre of mass like the wind;
* ``after_tick(t, q, v, reference)`` after every inner-loop tick: returns a new plan in force (a
  :class:`~planners.trajectory.polynomial.PiecewisePolynomial` that equals the old one up to the splice time) or None.

Triggers (with a :class:`planners.replanning.replanner.Replanner`, ``--replan``):

* **event**: a ``move`` event at its time: the way point moves and the rest of the motion is re-optimised
  from the plan in force's own state at the splice (C4 with it: the planned rotor speeds do not jump);
* **tracking error**: ``|measured - planned|`` of a chain coordinate past ``tracking_bound`` (at most once every
  ``min_interval``), and **the end of a gust**: re-optimised from the plan in force's state at the splice too
  (C4); not while a known gust blows (the error is then the wind's push, which the plan in force already
  flies against: replanning every 0.25 s from the plan's state gave short, violent travels that
  saturated the rotors). A start from the robot's own state was tried (bumpless for the controller:
  measured s, s', the commanded acceleration) and left out: the plan in force would jump at the splice,
  which a C4 piecewise polynomial cannot hold, and on a step gust it did not remove the saturation
  (documentation: guides/replanning);
* **rate** (optional, ``rate`` Hz): from the plan in force's state, like an event;
* **wind**: by default (``known_gusts``) the replanner is *told* each gust event's force and profile at
  the gust's start (a forecast, a wind sensor); with ``estimate_wind`` instead it plans against the wind it
  estimates: by default the controller's external-force observer's estimate (:mod:`controllers.observer`,
  read as forces on the task point and the drones, :meth:`controllers.ctc.CascadedController.estimated_forces`),
  taken once it has stayed above ``estimate_threshold`` for ``observed_delay`` (3 / K_O: the observer's 95 %
  settling), and again whenever it has moved by more than the threshold for as long; without an observer
  (``observer_bandwidth = 0``) a steady force on the task point estimated from the tracking error
  (:class:`fpr.sim.wind_estimate.WindEstimator`), taken after ``estimate_delay``. Either way it replans then
  with the force in the NLP's inverse dynamics (:mod:`planners.problem.disturbance`), and again ``wind_lead``
  before each way point while the wind blows: the rest of the travel and the next one are re-optimised
  against the wind together, so the splice lies in the part already planned in the wind. (Replanning
  once the way point was passed spliced into the offline plan's next travel, planned without the wind:
  from that state the next travel in the wind had no feasible C4 continuation the warm SQP could reach,
  e.g. at 6.3 s on the built-in ``gust`` mission; documentation: guides/replanning.)
  Against a sustained wind (a gust with a ``rise``, the built-in ``gust`` mission) every closed-loop margin
  then holds; against a short gust it does not help (the replans come while the gust still changes: the
  campaigns of random gusts fly them with the controller alone; documentation: guides/replanning).

**What the controller knows** (``feed_forward``, default on): the wind it is told, fed forward in its outer
loop (:class:`controllers.ctc.Reference` ``task_force``, ``drone_forces``), and the wind the plan in force was
made for, in the plan's inputs it tracks (the rolls, roll rates and accelerations of the plan flown in that
wind, :meth:`InFlight.inputs`): with ``known_gusts`` every gust with a ``rise`` as it blows, *with or
without* a replanner (the same forecast); with ``estimate_wind`` and the observer, the observer's own
estimate is what the controller feeds forward (it is not told it twice), and the plan's inputs are those in
the gusts the replanner assumed; without an observer, the assumed gusts are fed forward (ramped on from
their take-up, :meth:`InFlight._taken_up_from`); blind: none. The controller's observer, when it has one,
feeds forward whatever wind it is not told of, with or without a replanner.

**Deadline of the wind replans.** A replan in a known or estimated wind (at the gust's start, ``wind_lead``
before a way point, on a new estimate) is given ``wind_deadline`` (default 0.3 s) when it is longer than the
replanner's deadline: it does not react to a surprise (the gust rises over its ``rise``, the way point is
``wind_lead`` ahead), and the 50 ms default made every wind replan on ``gust`` late (84 ms modelled).
A wind replan that comes out infeasible (the rotors' headroom of :mod:`planners.problem.disturbance` out of the warm
SQP's reach) is solved again at once without the headroom, triggered when the first solve ends (the two
latencies add up): better a plan in the wind at the thesis' w >= 0 than the plan in force, made without it.

Without a replanner the gusts still push and the ``move`` events are ignored: the robot flies the offline
plan, so both runs can be compared.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from fpr.model.errors import ModelArgumentError
from fpr.sim.plant import Plant
from fpr.sim.wind_estimate import WindEstimator
from planners.missions.events import END_EFFECTOR, GustEvent, gust_force, moved_positions
from planners.problem.disturbance import inputs_in_gusts
from planners.replanning.replanner import Replanner, jet


class ForcedPlant(Plant):
    """A :class:`~fpr.sim.plant.Plant` pushed by the gust events of a mission.

    Attributes:
        events: the mission's events (only the gusts act here).
        tip_joint: the closed-chain joint whose origin is the robot kind's task point (the FPR's
            end-effector hinge, the prototype's drone joint), where an ``end_effector`` gust pushes.
    """

    events: tuple = ()
    tip_joint: int = 0
    _tip_force = None

    @classmethod
    def with_events(cls, events, robot, q, v=None, w=None, rotor_constant_scale: float = 1.0) -> ForcedPlant:
        """A plant at the thesis state (q, v) (:meth:`Plant.from_minimal`) pushed by ``events``."""
        plant = cls.from_minimal(robot, q, v, w, rotor_constant_scale=rotor_constant_scale)
        plant.events = tuple(events)
        plant.tip_joint = _task_point_joint(plant, robot, q)
        return plant

    def step(self, w_command, dt: float, wind=None) -> None:
        """:meth:`Plant.step` with the gusts active at the step's start added (held over the step)."""
        tip, drones = gust_force(self.events, self.time, self.robot.n_drones)
        self._tip_force = tip
        if tip is None and drones is None:
            return super().step(w_command, dt, wind)
        forces = np.zeros((self.robot.n_drones, 3)) if wind is None else np.array(self._wind_forces(wind))
        if drones is not None:
            forces = forces + drones
        return super().step(w_command, dt, forces)

    def _compiles_forces(self) -> bool:
        """The compiled steps while no end-effector gust pushes (the drones' gusts are their winds)."""
        return self._tip_force is None and self._rotor_map is not None

    def generalized_force(self, qc, w, wind_forces=None) -> np.ndarray:
        """:meth:`Plant.generalized_force` plus J^T F of an end-effector gust (J: world-aligned, at qc)."""
        tau = super().generalized_force(qc, w, wind_forces)
        if self._tip_force is not None:  # the Jacobians at qc were computed by the call above
            jac = pin.getJointJacobian(
                self.closed.model, self.closed.data, self.tip_joint, pin.LOCAL_WORLD_ALIGNED
            )
            tau = tau + self._tip_force @ jac[:3]
        return tau


def _task_point_joint(plant: Plant, robot, q) -> int:
    """The closed-chain joint whose origin is the robot's task point at q (found by position: any robot)."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, robot.to_pinocchio(q))
    target = data.oMf[robot.model.getFrameId(robot.kind.task_frame)].translation
    model, cdata = plant.closed.model, plant.closed.data
    pin.forwardKinematics(model, cdata, plant.qc)
    distances = [np.linalg.norm(cdata.oMi[j].translation - target) for j in range(1, model.njoints)]
    best = int(np.argmin(distances))
    if distances[best] > 1e-6:
        raise ModelArgumentError(
            "events",
            robot.kind.task_frame,
            f"no joint of the closed chain sits at the task point {robot.kind.task_frame!r} "
            f'(nearest {distances[best]:.3g} m away): give the gust a body = "drone_<i>"',
        )
    return best + 1


@dataclass(frozen=True)
class TriggerSettings:
    """When the closed loop asks for a replan.

    Attributes:
        tracking_bound: largest ``|measured - planned|`` of a chain coordinate before a replan from the robot's
            state [m or rad] (None: no such trigger).
        min_interval: least simulated time between two tracking-error replans [s].
        rate: fixed replanning rate [Hz], or None.
        after_gust: replan (from the plan in force's state) when a gust the replanner was told of ends.
        known_gusts: the replanner is told a gust's force when it starts (a forecast, a wind sensor) and
            replans at once against it (:mod:`planners.problem.disturbance`), and again ``wind_lead`` before each
            way point while it blows, through the travel after it (the default). Only gusts with a
            ``rise``: a step blast is not planned against (the plan cannot follow a step; on the previous
            0.4 s step gust it made the saturation worse, 382 ticks instead of 2).
        estimate_wind: (opt-in; ignored with ``known_gusts``) the replanner is not told the gusts but
            estimates a steady force on the task point from the tracking error
            (:class:`fpr.sim.wind_estimate.WindEstimator`); once the estimate has stayed above
            ``estimate_threshold`` [N] for ``estimate_delay`` [s] it plans against it as a known gust
            (replanning then, and ``wind_lead`` before each way point with the estimate of that moment).
            Both off: blind (a gust is seen only through the tracking error). With the controller's
            observer (:mod:`controllers.observer`) the estimate is its estimate instead (forces on the task point
            and the drones, :meth:`controllers.ctc.CascadedController.estimated_forces`), taken after
            ``observed_delay``, and planned against again when it has moved by more than the threshold.
        wind_lead: in a known or estimated wind, how long before a way point [s] the rest of its travel
            and the next travel are re-optimised (more than the replanner's deadline, so that the splice
            comes before the way point, in the part of the plan already made for the wind).
        wind_deadline: the deadline [s] of a replan in the wind when longer than the replanner's own (module
            docstring); less than ``wind_lead``.
        feed_forward: the controller is told the wind the replanner plans against (module docstring);
            False: it is not (the feedback alone holds the wind).
    """

    tracking_bound: float | None = 0.05
    min_interval: float = 0.25
    rate: float | None = None
    after_gust: bool = True
    known_gusts: bool = True
    estimate_wind: bool = False
    estimate_threshold: float = 1.0
    estimate_delay: float = 1.0
    observed_delay: float = 0.3
    wind_lead: float = 1.0
    wind_deadline: float = 0.3
    feed_forward: bool = True

    def __post_init__(self):
        def number(name, value, least=0.0, strict=True):
            ok = (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
                  and (value > least if strict else value >= least))
            if not ok:
                sign = ">" if strict else ">="
                raise ModelArgumentError(name, value,
                                         f"{name} = {value!r}: give a finite number {sign} {least:g}")

        for name in ("after_gust", "known_gusts", "estimate_wind", "feed_forward"):
            value = getattr(self, name)
            if not isinstance(value, bool):
                raise ModelArgumentError(name, value, f"{name} = {value!r}: give True or False")
        for name in ("tracking_bound", "rate"):
            if getattr(self, name) is not None:
                number(name, getattr(self, name))
        number("min_interval", self.min_interval, strict=False)
        number("estimate_threshold", self.estimate_threshold)
        number("estimate_delay", self.estimate_delay, strict=False)
        number("observed_delay", self.observed_delay, strict=False)
        number("wind_lead", self.wind_lead)
        number("wind_deadline", self.wind_deadline)
        if self.wind_deadline >= self.wind_lead:
            raise ModelArgumentError(
                "wind_deadline", self.wind_deadline,
                f"wind_deadline = {self.wind_deadline!r}: give less than wind_lead = {self.wind_lead!r} [s] "
                "(the splice must come before the way point)",
            )


class InFlight:
    """The closed loop's hooks for events and replanning (module docstring).

    Args:
        mission: the mission (its events).
        replanner: a :class:`planners.replanning.replanner.Replanner`, or None (gusts only; move events ignored).
        triggers: :class:`TriggerSettings`.
        controller: the controller's :class:`controllers.ctc.ControllerSettings` (kept as ``controller`` for
            what a trigger may need of it; the triggers of today do not use it).
        chain: indices of the planning coordinates in q.
        robot: the robot (default the replanner's, else ``mission.load_robot()``): its kind places the moved
            way points (:attr:`moves`).

    Attributes:
        moves: {event index: the moved way point in planning coordinates} of the move events, checked
            (:func:`planners.missions.events.moved_positions`).
    """

    def __init__(
        self, mission, replanner: Replanner | None, triggers: TriggerSettings, controller, chain, robot=None
    ):
        self.mission = mission
        self.robot = robot or (replanner.robot if replanner is not None else mission.load_robot())
        self.moves = replanner.moves if replanner is not None else moved_positions(mission, self.robot)
        self.events = tuple(mission.events)
        self.replanner = replanner
        self.triggers = triggers
        self.controller = controller
        self.chain = np.asarray(chain)
        self._done = set()
        self._known = set()
        self._last_tracking = -math.inf
        self._next_rate = None if not triggers.rate else 1.0 / triggers.rate
        self._way_times = np.cumsum(mission.times)[:-1]  # the interior way points' times [s]
        estimate = triggers.estimate_wind and not triggers.known_gusts and replanner is not None
        #: the estimate comes from the controller's observer (``attach``), or (no observer) from the tracking error
        self.observed = estimate and getattr(controller, "observer_bandwidth", 0.0) > 0
        self.estimator = WindEstimator(self.robot, controller) if estimate and not self.observed else None
        self._controller = None
        self._above_since = None  # when the estimate last rose above the threshold [s]
        self._moved_since = None  # when the observer's estimate last moved from the assumed wind [s]
        self._assumed_forces = None  # the estimate the replanner assumed (task point, drones) [N]
        self._below_since = None  # when it last fell below it [s]
        self._prepared = 0  # interior way points whose next travel is planned for (or passed without wind)
        self._inputs_for = ()  # the known gusts of the last inputs()
        self._taken_up = {}  # (at, force) of an estimate fully on when assumed -> when it was [s]
        self._no_force = (None, None)
        self._n_drones = self.robot.n_drones

    @property
    def replans(self) -> list:
        """The :class:`planners.replanning.replanner.Replan` records so far."""
        return [] if self.replanner is None else self.replanner.replans

    def attach(self, controller) -> None:
        """The closed loop's controller (:class:`controllers.ctc.CascadedController`): its observer's estimate
        is the replanner's wind estimate (``estimate_wind``).
        """
        self._controller = controller

    def make_plant(self, robot, q, v=None, w=None, rotor_constant_scale: float = 1.0) -> ForcedPlant:
        """The plant (:class:`ForcedPlant`)."""
        return ForcedPlant.with_events(self.events, robot, q, v, w, rotor_constant_scale)

    def after_tick(self, t: float, q, v, reference):
        """Replan when a trigger fires at the inner-loop tick t [s]; the new plan in force, or None.

        Args:
            t: the tick's time [s].
            q: the measured configuration (thesis coordinates) [m, rad].
            v: the measured velocity [m/s, rad/s].
            reference: the plan in force's s and its derivatives 0..4 at t, shape (>= 5, n_s).
        """
        if self.replanner is None:
            return None
        rp, before = self.replanner, self.replanner.trajectory
        for i, event in enumerate(self.events):
            if i in self._done:
                continue
            starts = event.at <= t + 1e-9
            if event.kind == "move" and starts:
                self._done.add(i)
                rp.move(i)
                rp.replan(t, f"event: way point {event.way_point} moved to {list(event.to)}")
            elif event.kind == "gust" and self._plans_against(event) and i not in self._known and starts:
                self._known.add(i)  # the gust's force is known from its start (forecast, wind sensor)
                rp.learn(i)
                self._wind_replan(t, f"event: a gust of {list(event.force)} N on {event.body} starts "
                                  "(force known)", through=self._through(t))
            elif (event.kind == "gust" and self.triggers.after_gust and i in self._known
                  and event.at + event.duration <= t + 1e-9):
                self._done.add(i)
                rp.replan(t, "event: the gust is over")
        estimated = self._estimate(t, q, v, reference)
        # a known gust blows, or the estimate has risen (the wind builds up): the error is the wind's
        windy = any(g.active(t) for g in rp.gusts) or self._above_since is not None
        due = int(np.searchsorted(self._way_times - self.triggers.wind_lead, t + 1e-9, side="right"))
        if due > self._prepared:
            self._prepared = due
            if any(g.active(t) for g in rp.gusts):  # the next travel enters the horizon: fly it in the wind
                if rp.assumed is not None and estimated is not None:  # the newest estimate, blending from t on
                    # (the observer's estimate is the wind now, fully on; the tracking error's, blended from t)
                    rp.assume(self._estimated_gust(t, estimated, ramp_from=None if self.observed else t))
                    self._assumed_forces = (np.array(estimated[0], dtype=float), np.array(estimated[1], dtype=float))
                self._wind_replan(t, f"way point {due} ahead in the wind", through=due + 1)
        bound = self.triggers.tracking_bound
        # in a known gust the tracking error is the wind's push, which the plan in force already flies
        # against and a replan from the plan's state cannot remove: no tracking-error replans then
        if bound is not None and not windy and t - self._last_tracking >= self.triggers.min_interval:
            error = np.abs(q[self.chain] - reference[0])
            if error.max() > bound:
                self._last_tracking = t
                worst = int(np.argmax(error))
                rp.replan(t, f"tracking error {error.max():.4f} > {bound:g} (coordinate {worst})")
        if self._next_rate is not None and t >= self._next_rate - 1e-9:
            self._next_rate += 1.0 / self.triggers.rate
            rp.replan(t, "rate")
        return None if rp.trajectory is before else rp.trajectory

    def known_gusts(self) -> tuple:
        """The gusts the controller is told of now (module docstring), fed forward: the known ones, or the
        estimates the replanner assumed when they come from the tracking error (an observer's estimate is
        fed forward by the controller itself).
        """
        if not self.triggers.feed_forward:
            return ()
        if self.triggers.known_gusts:
            return tuple(e for e in self.events if e.kind == "gust" and self._plans_against(e))
        if self.estimator is not None:
            return tuple(g for g in map(self._taken_up_from, self.replanner.gusts) if g is not None)
        return ()

    def planned_gusts(self) -> tuple:
        """The gusts the plan's inputs are flown in (the roll feed-forward): the known ones, or those the
        replanner planned against.
        """
        if self.observed and self.triggers.feed_forward:
            return tuple(self.replanner.gusts)
        return self.known_gusts()

    def _taken_up_from(self, gust):
        """The controller's copy of an assumed estimate: the replanner's first estimate is fully on at once
        (the wind has built up), but until then the feedback held it, so a step in the fed force would count
        it twice for a while (a kick back past the plan: 788 rad/s on ``gust``); it ramps on over its rise
        from the time it was taken up instead. None: not on yet.
        """
        up = self._taken_up.get((gust.at, gust.force))
        if up is None or gust.at >= up:
            return gust
        left = gust.duration - (up - gust.at)
        return dataclasses.replace(gust, at=up, duration=left) if left > 0 else None

    def known_force(self, t: float) -> tuple:
        """The known wind at t [s]: (force on the task point (3,), forces on the drones (n_d, 3)) [N], each
        None when none pushes (:func:`planners.missions.events.gust_force` of :meth:`known_gusts`).
        """
        gusts = self.known_gusts()
        return gust_force(gusts, t, self._n_drones) if gusts else self._no_force

    @property
    def known_changed(self) -> bool:
        """The planned gusts changed since the last :meth:`inputs` (the plan's inputs must be recomputed)."""
        return self.planned_gusts() != self._inputs_for

    def inputs(self, robot, ticks, motion):
        """The plan's inputs (:func:`fpr.model.inverse_dynamics.inverse_dynamics`) at ``ticks`` [s] of
        ``motion`` (its derivatives 0..MOTION_ORDER), flown in the known gusts (their Q_ext with its time
        derivatives, :func:`planners.problem.disturbance.generalized_gust`); no gust known: the plan's own.
        """
        gusts = self.planned_gusts()
        self._inputs_for = gusts
        return inputs_in_gusts(robot, motion, ticks, gusts)

    def passes(self, log) -> list[dict]:
        """For each move event: how close the simulated task point passes to the moved way point [m].

        The task point is the robot kind's (the FPR's end-effector); the time is the tick nearest to when the
        mission reaches the way point. Without replanning (the move ignored) the same distance says by how
        much the robot misses.

        Returns:
            one dict per move event: ``event`` (its index), ``way_point``, ``time_s``, ``distance_m``; none
            when the log stops before the way point's time (the robot was lost).
        """
        ways = np.concatenate([[0.0], np.cumsum(self.mission.times)])
        chain = [log.coordinates.index(c) for c in log.chain]
        out = []
        for i, event in enumerate(self.events):
            if event.kind != "move" or log.t.size == 0 or log.t[-1] < ways[event.way_point] - 1e-9:
                continue
            k = int(np.argmin(np.abs(log.t - ways[event.way_point])))
            target = self.robot.kind.task_points(self.moves[i][None])[0][0]
            where = self.robot.kind.task_points(log.q[k, chain][None])[0][0]
            out.append({"event": i, "way_point": event.way_point, "time_s": float(log.t[k]),
                        "distance_m": float(np.linalg.norm(where - target))})
        return out

    def _wind_replan(self, t: float, trigger: str, through: int | None = None) -> None:
        """A replan in the wind, with the deadline ``max(deadline, wind_deadline)`` (module docstring)."""
        rp = self.replanner
        options = rp.options
        if self.triggers.wind_deadline > options.deadline:
            rp.options = dataclasses.replace(options, deadline=self.triggers.wind_deadline)
        try:
            record = rp.replan(t, trigger, through=through)
            infeasible = not record.used and not record.feasible and not record.solver.startswith("QP failed")
            if infeasible and rp.options.wind_headroom > 0:
                # the headroom out of the warm SQP's reach: the thesis' w >= 0 alone (saturation then
                # likelier, but better than the plan in force, made without the wind)
                rp.options = dataclasses.replace(rp.options, wind_headroom=0.0)
                # triggered when the first solve ends (its latency), so the two latencies add up
                again = f"{trigger} (again, without the rotors' headroom)"
                rp.replan(t + record.latency_s, again, through=through)
        finally:
            rp.options = options

    def _through(self, t: float) -> int | None:
        """``through`` of a replan in the wind at t: the travel after the next way point too when that way
        point is less than ``wind_lead`` ahead (that travel is then not re-planned by a later trigger).
        """
        ahead = int(np.searchsorted(self._way_times, t + 1e-9, side="right"))  # 0-based: way point ahead + 1
        if ahead >= self._way_times.size or self._way_times[ahead] - t > self.triggers.wind_lead + 1e-9:
            return None
        self._prepared = max(self._prepared, ahead + 1)
        return ahead + 2

    def _plans_against(self, gust) -> bool:
        """The replanner is told of ``gust`` (``known_gusts``, and the gust has a rise: not a step)."""
        return self.triggers.known_gusts and gust.rise > 0.0

    def _estimate(self, t: float, q, v, reference):
        """Update the wind estimate and plan against it once it has held long enough; the estimate (forces on
        the task point (3,) and on the drones (n_d, 3) [N]) or None.
        """
        if self.observed:
            if self._controller is None:
                return None
            forces = self._controller.estimated_forces()
        elif self.estimator is not None:
            fed = self.known_force(t)[0]  # what the controller feeds forward: the estimate reads the rest
            forces = (self.estimator.update(t, q[self.chain], v[self.chain], reference, fed),
                      np.zeros((self._n_drones, 3)))
        else:
            return None
        size = _largest(forces)
        delay = self.triggers.observed_delay if self.observed else self.triggers.estimate_delay
        if size < self.triggers.estimate_threshold:
            self._above_since = None
            if self._below_since is None:
                self._below_since = t
            dropped = t - self._below_since >= delay - 1e-9
            if self.replanner.assumed is not None and dropped:
                self.replanner.forget(t)  # the wind has dropped: plan without it from now on
                self.replanner.replan(t, "wind estimate below the threshold: planned without wind")
            return forces
        self._below_since = None
        if self._above_since is None:
            self._above_since = t
        assumed = self.replanner.assumed
        if assumed is not None and self.observed:  # the wind has changed: plan against the new estimate
            moved = _largest(_minus(forces, self._assumed_forces)) >= self.triggers.estimate_threshold
            self._moved_since = (self._moved_since if self._moved_since is not None else t) if moved else None
            if moved and t - self._moved_since >= delay - 1e-9:
                self._moved_since = None
                self._assume(t, forces, ramp_from=None, trigger="wind estimate changed")
            return forces
        if assumed is None and t - self._above_since >= delay - 1e-9:
            self._assume(t, forces, ramp_from=None, trigger="wind estimated")
        return forces

    def _assume(self, t: float, forces, ramp_from, trigger: str) -> None:
        """Plan against the estimated ``forces`` from t [s] on, and replan in that wind."""
        gusts = self._estimated_gust(t, forces, ramp_from=ramp_from)
        for gust in gusts:
            self._taken_up[(gust.at, gust.force)] = t
        self.replanner.assume(gusts)
        self._assumed_forces = (np.array(forces[0], dtype=float), np.array(forces[1], dtype=float))
        said = "; ".join(f"{[round(f, 2) for f in g.force]} N on {g.body}" for g in gusts)
        self._wind_replan(t, f"{trigger}: {said}", through=self._through(t))

    def _estimated_gust(self, t: float, forces, ramp_from: float | None = None) -> tuple:
        """The estimate as gusts (one per body it pushes, above a tenth of the threshold) blowing to past the end of
        the motion: fully on from t (the wind has built up), or ramping on from ``ramp_from`` (a newer
        estimate blending from the last one).
        """
        end = float(np.sum(self.mission.times)) + 1e3
        rise = 0.5
        at = t - rise if ramp_from is None else ramp_from
        task, drones = forces
        bodies = [(END_EFFECTOR, task)] + [(f"drone_{i + 1}", f) for i, f in enumerate(drones)]
        least = 0.1 * self.triggers.estimate_threshold
        return tuple(GustEvent(at, tuple(float(x) for x in f), end - at, body, rise)
                     for body, f in bodies if np.linalg.norm(f) >= least)


def _largest(forces) -> float:
    """The largest of the forces (task point (3,), drones (n_d, 3)) [N]."""
    task, drones = forces
    return max(float(np.linalg.norm(task)), float(np.linalg.norm(drones, axis=1).max(initial=0.0)))


def _minus(forces, other):
    """forces - other, both (task point, drones)."""
    return forces[0] - other[0], forces[1] - other[1]


__all__ = ["ForcedPlant", "InFlight", "TriggerSettings", "jet"]
