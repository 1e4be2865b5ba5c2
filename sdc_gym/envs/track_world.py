"""The track loop's world for a batch of envs: config once, every env's state as arrays.

:class:`TrackWorld` holds ``envs`` episodes of one ``sdc_gym/TrackLoop-v0`` config
(:class:`~sdc_gym.envs.track_setup.TrackSetup`): the cars, lights, manual schedules,
obstacles and metrics of all of them as arrays with a leading env axis, advanced by the
frame kernel of :mod:`sdc_gym.envs.track_kernel`. Envs are reset one at a time
(:meth:`TrackWorld.reset_at`, each from its own generator) and stepped together
(:meth:`TrackWorld.advance`). :class:`~sdc_gym.envs.track_loop.TrackLoopEnv` is the batch
of one; the behavior-level world (:mod:`sdc_gym.envs.track_behavior_world`) runs the same
world with the drive-by-wire stack inside the kernel.

The driving metrics (:class:`~sdc_gym.metrics.batch.DrivingMetricsBatch`) take a call's
frames in one chunk (their results do not depend on the chunking). An env whose episode
ends before the others' frames are done is given copies of its last frame for the rest of
the chunk; its step info and summary are taken before that (and served from then on), and
its metrics start afresh at its reset.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.envs.track_kernel import (
    HAVE_CONTACT,
    HAVE_MANUAL,
    HAVE_PROJECTION,
    NEED_CONTACT,
    NEED_MANUAL,
    NEED_PROJECTION,
    REASONS,
    FrameBuffers,
    StepOutputs,
    TrackConstants,
    frame_buffers,
    manual_at,
    run_steps,
    step_outputs,
    track_state,
    update_stop_line,
)
from sdc_gym.envs.track_setup import (
    OBSTACLE_CLEARANCE_M,
    RNG_STREAMS,
    SEED_BOUND,
    TrackSetup,
)
from sdc_gym.geometry.collision import boxes_overlap
from sdc_gym.kernel_compiler import bind
from sdc_gym.lights.light_kernel import refresh_lights
from sdc_gym.lights.traffic_lights import RED, UNKNOWN, YELLOW
from sdc_gym.metrics.incidents import Incident
from sdc_gym.metrics.track_metrics_batch import (
    TrackMetricsBatch,
    stop_line_events,
)
from sdc_gym.units import MPS_TO_MPH
from sdc_gym.validation.bounds import check_batch_sizes, check_env_count
from sdc_gym.vehicle.dbw_kernel import (
    SPEED,
    YAW,
    YAW_RATE,
    X,
    Y,
    reset_vehicle,
)
from sdc_gym.vehicle.dbw_vehicle import PHYSICS_DT, VehicleState, lag_gains, vehicle_constants
from sdc_gym.vehicle.manual_driver import ManualDriver

_NO_INCIDENTS: tuple[Incident, ...] = ()
_OBSERVED_CAR_COLUMNS = [X, Y, YAW, SPEED, YAW_RATE]  # the observation's first five values
_REACH_MARGIN = 1e-9  # the kernel's broad phase is never narrower than Python's


class TrackWorld:
    """``envs`` episodes of one ``TrackLoop-v0`` config; see the module docstring.

    Args:
        config: the env config (:data:`~sdc_gym.envs.track_setup.TRACK_DEFAULTS` keys).
        envs: number of envs.
        owner: the name config errors are reported under.
        frames_per_step: physics frames of one step of the batch, for its bounds (None: the
            config's ``steps_per_action``; a behavior env's decision is longer).
        batch_names: the env and the key of ``frames_per_step`` in the batch bounds'
            messages; None: ``owner``'s and ``steps_per_action``.
    """

    def __init__(self, config: Mapping[str, Any] | None = None, *, envs: int = 1,
                 owner: str = "TrackLoop-v0", frames_per_step: int | None = None,
                 batch_names: tuple[str, str] | None = None) -> None:
        envs = check_env_count(envs, f"{owner}: num_envs")
        self.setup = setup = TrackSetup(config, owner)
        # The batch's products (num_envs x each size), before its first per-env array.
        camera = setup.camera_config if setup.camera is not None else None
        batch_owner, frames_key = batch_names or (owner, "steps_per_action")
        check_batch_sizes(batch_owner, envs,
                          frames_per_step=frames_per_step or setup.steps_per_action,
                          cars=setup.obstacle_count, frames_key=frames_key,
                          cars_key="obstacles.count", camera_key="camera.width x height",
                          camera_pixels=camera.width * camera.height if camera else 0)
        self.envs = envs
        self.config = setup.config
        self.track = track = setup.track
        self.reference = track.reference
        self.metrics = TrackMetricsBatch(track, setup.rules, setup.front_offset, envs)
        obstacles = setup.config["obstacles"]
        reach = 0.5 * np.hypot(setup.car_length, setup.car_width) + 0.5 * math.hypot(
            obstacles["length"], obstacles["width"])
        self.obstacle_reach_sq = float(reach * reach)
        self.constants = TrackConstants(
            vehicle_constants(setup.params), lag_gains(setup.params, PHYSICS_DT),
            self.reference.geometry(), track.stop_lines_sorted_s,
            track.stop_lines_sorted_index, self.metrics.lines, setup.lights.schedule,
            PHYSICS_DT, setup.steps_per_action, setup.road_half_width,
            float(setup.centre_offset), self.obstacle_reach_sq * (1.0 + _REACH_MARGIN),
            float(setup.progress_scale), setup.laps, setup.max_frames, float(track.length))
        self.state = track_state(envs, track.light_count, setup.obstacle_count,
                                 self.metrics.state)
        self.drivers: list[ManualDriver | None] = [None] * envs
        self.camera_rngs: list[np.random.Generator | None] = [None] * envs
        self.obstacles_sd = [np.zeros((0, 2))] * envs
        self.obstacles_heading = [np.zeros(0)] * envs
        self.done_reason = [""] * envs
        self._frozen: list[dict[str, Any] | None] = [None] * envs
        self.ready = np.zeros(envs, dtype=bool)
        self._steps_capacity = 0
        self.buffers: FrameBuffers = frame_buffers(envs, 0)
        self.outputs: StepOutputs = step_outputs(envs, 0)
        self.events = stop_line_events(0)
        self._steps_left = np.zeros(envs, dtype=np.int64)
        self._bound: dict[Any, tuple[int, Callable[[], Any]]] = {}  # see kernel_call
        self.generation = 0  # of the state and buffers: bound calls are redone when it grows

    # ------------------------------------------------------------------ episodes
    def reset_at(self, env: int, rng: np.random.Generator) -> None:
        """Start env ``env``'s episode: every random component draws a child generator
        from ``rng`` (so switching one on or off, e.g. the camera, changes no other)."""
        setup, st, cfg = self.setup, self.state, self.config
        seeds = rng.integers(0, SEED_BOUND, size=len(RNG_STREAMS))
        rngs = {name: np.random.default_rng(int(value))
                for name, value in zip(RNG_STREAMS, seeds, strict=True)}
        self.camera_rngs[env] = rngs["camera"]
        start_s, start_d = setup.start_s, float(cfg["start_d"])
        speed = float(cfg["start_speed"])
        x, y = self.reference.to_xy(start_s, start_d).tolist()
        yaw = float(self.reference.heading(start_s))
        reset_vehicle(self.constants.vehicle, st.vehicle, env, x, y, yaw, speed, 0.0, 0.0, 0.0)
        st.s[env], st.d[env] = start_s, start_d
        st.frame[env] = 0
        lights = setup.lights
        st.light_offsets[env] = lights.draw_offsets(rngs["lights"])
        st.light_clock[env] = 0.0
        st.light_next_change[env] = refresh_lights(lights.schedule, st.light_offsets[env], 0.0,
                                                   st.light_states[env])
        self.metrics.reset_at(env, x, y, start_s, start_d, speed)
        self._place_obstacles(env, start_s, rngs["obstacles"])
        self._set_manual_schedule(env, setup.manual_schedule(rngs["manual_schedule"]))
        st = self.state  # the schedule may have grown the state's periods array
        st.manual_frames_total[env] = st.step_manual_frames[env] = 0
        self.drivers[env] = ManualDriver(setup.params, rngs["manual_driver"])
        st.take_over[env] = False
        st.dbw_enabled[env] = not manual_at(st, env, 0)
        st.laps[env] = 0
        st.lap_mark[env] = self.constants.length
        st.contact[env] = -1
        st.in_step[env] = False
        st.terminated[env] = st.truncated[env] = False
        st.reason[env] = 0
        self.done_reason[env] = ""
        self._frozen[env] = None
        update_stop_line(self.constants, st, env)
        self.ready[env] = True

    def _set_manual_schedule(self, env: int, periods: list[tuple[int, int]]) -> None:
        st = self.state
        if len(periods) > st.manual_periods.shape[1]:
            grown = np.zeros((self.envs, len(periods), 2), dtype=np.int64)
            grown[:, :st.manual_periods.shape[1]] = st.manual_periods
            self.state = st = st._replace(manual_periods=grown)
            self.generation += 1
        if periods:
            st.manual_periods[env, :len(periods)] = periods
        st.manual_count[env] = len(periods)
        st.manual_index[env] = 0

    def _place_obstacles(self, env: int, start_s: float, rng: np.random.Generator) -> None:
        obstacles = self.config["obstacles"]
        reference = self.reference
        if obstacles["positions"]:
            sd = np.array(obstacles["positions"], dtype=np.float64).reshape(-1, 2)
        elif obstacles["count"]:
            count = int(obstacles["count"])
            length = self.track.length
            s = start_s + rng.uniform(OBSTACLE_CLEARANCE_M, length - OBSTACLE_CLEARANCE_M,
                                      count)
            d = rng.uniform(-1.0, 1.0, count) * obstacles["max_offset_d"]
            sd = np.column_stack([reference.wrap_s(s), d])
        else:
            sd = np.zeros((0, 2))
        xy = reference.to_xy(sd[:, 0], sd[:, 1]).reshape(-1, 2)
        self.state.obstacles[env] = xy
        self.obstacles_heading[env] = reference.heading(sd[:, 0]).reshape(-1)
        self.obstacles_sd[env] = sd

    # ------------------------------------------------------------------ stepping
    def _capacity(self, steps: int) -> None:
        """Buffers for calls of up to ``steps`` env steps."""
        if steps > self._steps_capacity:
            frames = steps * self.setup.steps_per_action
            self.buffers = frame_buffers(self.envs, frames)
            self.outputs = step_outputs(self.envs, steps)
            lights = max(self.track.light_count, 1)
            self.events = stop_line_events(self.envs * frames * lights)
            self._steps_capacity = steps
            self.generation += 1

    def kernel_call(self, function: Any, *extra: Any) -> Callable[[], Any]:
        """``function(constants, state, buffers, outputs, events, *extra)`` as a call bound
        to this world's arrays (:func:`~sdc_gym.kernel_compiler.bind`: no type dispatch
        per call), rebound after the state or the buffers were replaced
        (:attr:`generation`)."""
        generation, call = self._bound.get(function, (-1, None))
        if call is None or generation != self.generation:
            call = bind(function, self.constants, self.state, self.buffers, self.outputs,
                        self.events, *extra)
            self._bound[function] = (self.generation, call)
        return call

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_bound"] = {}  # machine code entry points: bound again after unpickling
        return state

    def step(self, active: NDArray[np.bool_]) -> tuple[NDArray[np.float64], list[Any]]:
        """One env step of the ``active`` envs, each with its commands
        (``state.command``, checked by :meth:`TrackSetup.read_action`): each env's reward
        (0 for the others) and the incidents that began in the step."""
        self._steps_left[:] = active
        incidents = self.advance(1, self._run_steps)
        reward = np.zeros(self.envs)
        for env in active.nonzero()[0].tolist():
            reward[env] = self.rewards(env, incidents[env])[0]
        return reward, incidents

    def _run_steps(self) -> bool:
        return self.kernel_call(run_steps, self._steps_left)()

    def advance(self, steps: int, kernel: Callable[[], bool]) -> list[Any]:
        """Run ``kernel`` (a call of a frame kernel over this world's state, returning
        whether some env paused) until no env is paused, serving the pauses; then the
        driving metrics of the call's frames. Returns each env's new incidents."""
        if not self.ready.all():
            raise RuntimeError("call reset() before step()")
        self._capacity(steps)
        self._frozen = [None] * self.envs
        self.buffers.count[:] = 0
        self.outputs.steps[:] = 0
        self.events.counts[:] = 0
        while kernel():
            self._serve_pauses()
        self.update_done_reasons()
        return self._record()

    def _serve_pauses(self) -> None:
        """What the kernel leaves to Python (see :mod:`sdc_gym.envs.track_kernel`)."""
        st = self.state
        for env in (st.stage == NEED_MANUAL).nonzero()[0].tolist():
            vehicle = self.vehicle_state(env)
            driver = self.drivers[env]
            assert driver is not None
            if st.take_over[env]:
                driver.reset(vehicle)
                st.take_over[env] = False
            st.forced[env] = driver.act(vehicle, self.reference, self.setup.speed_limit,
                                        self._manual_stop_distance(env))
            st.stage[env] = HAVE_MANUAL
        for env in (st.stage == NEED_PROJECTION).nonzero()[0].tolist():
            car = st.vehicle[env]
            (st.fix_s[env],), (st.fix_d[env],) = self.reference.project_few(
                [[float(car[X]), float(car[Y])]], [float(st.guess[env])])
            st.stage[env] = HAVE_PROJECTION
        for env in (st.stage == NEED_CONTACT).nonzero()[0].tolist():
            st.contact[env] = self._touching(env)
            st.stage[env] = HAVE_CONTACT

    def _manual_stop_distance(self, env: int) -> float | None:
        """The human stops for the next line if its light is red or yellow (rear axle, m)."""
        line, distance = self.track.next_stop_line(float(self.state.s[env]))
        if line >= 0 and self.state.light_states[env, line] in (RED, YELLOW):
            return distance
        return None

    def _touching(self, env: int) -> int:
        """The first obstacle the car's body touches now, or -1 (the exact box test)."""
        setup = self.setup
        st = self.vehicle_state(env)
        cx = st.x + setup.centre_offset * math.cos(st.yaw)
        cy = st.y + setup.centre_offset * math.sin(st.yaw)
        obstacles = self.config["obstacles"]
        for index, (ox, oy) in enumerate(self.state.obstacles[env].tolist()):
            if (ox - cx) ** 2 + (oy - cy) ** 2 <= self.obstacle_reach_sq and bool(
                    boxes_overlap((cx, cy), st.yaw, setup.car_length, setup.car_width,
                                  (ox, oy), self.obstacles_heading[env][index],
                                  obstacles["length"], obstacles["width"])):
                return index
        return -1

    def _record(self) -> list[Any]:
        """The call's frames into the driving metrics, in chunks that end where some env's
        frames end (see the module docstring); each env's new incidents."""
        st, buffers, metrics = self.state, self.buffers, self.metrics
        counts = buffers.count
        longest = int(counts.max())
        incidents: list[Any] = [_NO_INCIDENTS] * self.envs
        if longest == 0:
            self.metrics.collect(self.events, 0)
            return incidents
        if (self.envs == 1 and not int(self.events.counts[0])
                and int(st.contact[0]) < 0):
            # One env, no red-light run, no contact: one chunk of its frames as they are.
            new = metrics.driving.record(buffers.xy[:, :longest], buffers.s[:, :longest],
                                         buffers.d[:, :longest],
                                         buffers.speed[:, :longest])
            self.metrics.collect(self.events, longest)
            return new
        ended = st.terminated | st.truncated
        short = (counts < longest).nonzero()[0].tolist()
        for env in short:  # copies of the last frame (or of the car) after an env's end
            n = int(counts[env])
            if n:
                for array in (buffers.xy, buffers.s, buffers.d, buffers.speed):
                    array[env, n:longest] = array[env, n - 1]
            else:
                car = st.vehicle[env]
                buffers.xy[env, :longest] = (car[X], car[Y])
                buffers.s[env, :longest] = st.s[env]
                buffers.d[env, :longest] = st.d[env]
                buffers.speed[env, :longest] = car[SPEED]
        red = self._red_events()
        contact_at = {env: int(counts[env]) - 1 for env in (st.contact >= 0).nonzero()[0].tolist()
                      if counts[env]}
        bounds = sorted({int(n) for n in counts.tolist() if n} | {longest})
        low = 0
        for high in bounds:
            extra = None
            if red:
                extra = [[(frame - low, kind, value) for frame, kind, value in red.get(env, ())
                          if low <= frame < high] for env in range(self.envs)]
                extra = extra if any(extra) else None
            ids = None
            if contact_at and any(low <= frame < high for frame in contact_at.values()):
                ids = np.full((self.envs, high - low), -1, dtype=np.int64)
                for env, frame in contact_at.items():
                    if low <= frame < high:
                        ids[env, frame - low] = st.contact[env]
            new = metrics.driving.record(buffers.xy[:, low:high], buffers.s[:, low:high],
                                         buffers.d[:, low:high], buffers.speed[:, low:high],
                                         ids, extra)
            for env, items in enumerate(new):
                if items and counts[env] > low:
                    incidents[env] = [*incidents[env], *items]
            if high < longest:
                for env in ((counts == high) & ended).nonzero()[0].tolist():
                    self._frozen[env] = self._metrics_view(env)
            low = high
        self.metrics.collect(self.events, longest)
        return incidents

    def _red_events(self) -> dict[int, list[tuple[int, str, float]]]:
        events = self.events
        rows = int(events.counts[0])
        red: dict[int, list[tuple[int, str, float]]] = {}
        for env, frame, line in events.red[:rows].tolist():
            red.setdefault(env, []).append((frame, "red_light", float(line)))
        events.counts[0] = 0
        return red

    def rewards(self, env: int, incidents: Any) -> list[float]:
        """Env ``env``'s reward of each step of the last call: its progress part plus the
        penalty of each incident that began in it on a frame the agent drove."""
        out = self.outputs
        steps = int(out.steps[env])
        rewards = out.reward[env, :steps].tolist()
        if incidents:
            first = out.first_frame[env, :steps].tolist()
            frames = out.frames[env, :steps].tolist()
            starts = out.buffer_start[env, :steps].tolist()
            manual = out.manual_frames[env, :steps].tolist()
            penalty = self.setup.incident_penalty
            step = 0
            for incident in incidents:  # in step order
                while incident.step > first[step] + frames[step]:
                    step += 1
                frame = incident.step - first[step] - 1  # Incident.step counts from 1
                if not (manual[step] and self.buffers.manual[env, starts[step] + frame]):
                    rewards[step] += penalty[incident.kind]
        return rewards

    def step_incidents(self, env: int, incidents: Any, step: int) -> list[Incident]:
        """The incidents of ``incidents`` that began in the call's step ``step``."""
        out = self.outputs
        first = int(out.first_frame[env, step])
        last = first + int(out.frames[env, step])
        return [incident for incident in incidents if first < incident.step <= last]

    def update_done_reasons(self) -> None:
        """The termination reasons of the envs whose episode ended in the last call."""
        for env in self.state.reason.nonzero()[0].tolist():
            self.done_reason[env] = REASONS[int(self.state.reason[env])]

    # ------------------------------------------------------------------ reading one env
    def vehicle_state(self, env: int) -> VehicleState:
        """Env ``env``'s car now (a snapshot)."""
        return VehicleState(*self.state.vehicle[env].tolist())

    def is_success(self, env: int) -> bool:
        frozen = self._frozen[env]
        laps = frozen["laps"] if frozen else int(self.metrics.driving.laps[env])
        return laps >= self.setup.laps

    def _metrics_view(self, env: int) -> dict[str, Any]:
        """What env ``env``'s info and summary read from the metrics, now."""
        return {"step_info": self.metrics.step_info(env),
                "front": self.metrics.next_stop_line(env),
                "laps": int(self.metrics.driving.laps[env]),
                "summary": self.summary(env)}

    def observation(self, env: int) -> dict[str, Any]:
        """Env ``env``'s ``TrackLoop-v0`` observation (new arrays)."""
        return self.observations(env)

    def observations(self, rows: NDArray[np.int64] | slice | int | None = None
                     ) -> dict[str, Any]:
        """The ``TrackLoop-v0`` observations of envs ``rows`` (default: all; an index
        array or a slice), each key's values stacked along a leading axis (new arrays);
        ``rows`` an int: that env's own observation, no leading axis (the single env's
        step, so it indexes one row instead of slicing a batch of one)."""
        st, setup = self.state, self.setup
        rows = slice(None) if rows is None else rows
        one = isinstance(rows, int | np.integer)
        # The columns as float64 (the line index cast as a stack would), then float32;
        # filled in place, which costs a fraction of np.column_stack for one env.
        vehicle = st.vehicle[rows]  # (7,) for one env, (envs, 7) for rows
        columns = np.empty((*vehicle.shape[:-1], 7))
        columns[..., 0:5] = vehicle[..., _OBSERVED_CAR_COLUMNS]
        columns[..., 5] = st.next_line[rows]
        columns[..., 6] = st.line_distance[rows]
        values = columns.astype(np.float32)
        observation: dict[str, Any] = {
            "pose": values[..., 0:3],
            "velocity": values[..., 3:4],
            "yaw_rate": values[..., 4:5],
            "dbw_enabled": (int(st.dbw_enabled[rows]) if one
                            else st.dbw_enabled[rows].astype(np.int64)),
            "next_stop_line": values[..., 5:7],
        }
        if self.config["observe_light_states"]:
            observation["light_states"] = st.light_states[rows].copy()
        if setup.camera is not None:
            envs = [rows] if one else (range(self.envs)[rows] if isinstance(rows, slice)
                                       else rows.tolist())
            images = [setup.camera.render(
                float(st.vehicle[env, X]), float(st.vehicle[env, Y]),
                float(st.vehicle[env, YAW]), self.track.light_positions,
                self.track.light_yaw, st.light_states[env], self.camera_rngs[env])
                for env in envs]
            observation["camera"] = images[0] if one else np.stack(images)
        if setup.obstacle_count:
            observation["obstacles"] = st.obstacles[rows].astype(np.float32)
        return observation

    def info(self, env: int, incidents: Any, *, final: bool) -> dict[str, Any]:
        """Env ``env``'s ``TrackLoop-v0`` info after a step (``incidents``: those that
        began in the step)."""
        st = self.state
        vehicle = self.vehicle_state(env)
        frozen = self._frozen[env]
        info: dict[str, Any] = dict(frozen["step_info"]) if frozen else self.metrics.step_info(env)
        line = int(st.next_line[env])
        front_line, front_distance = frozen["front"] if frozen else (
            self.metrics.next_stop_line(env))
        if front_line < 0:
            front_distance = self.track.length  # like stop_line_distance without lines
        info.update({
            "x": vehicle.x,
            "y": vehicle.y,
            "yaw": vehicle.yaw,
            "s": float(st.s[env]),
            "d": float(st.d[env]),
            "speed_mph": vehicle.speed * MPS_TO_MPH,
            "throttle": vehicle.throttle,
            "brake_torque": vehicle.brake_torque,
            "steering_wheel_angle": vehicle.steering_wheel_angle,
            "dbw_enabled": bool(st.dbw_enabled[env]),
            "manual_frames": int(st.step_manual_frames[env]),
            "next_stop_line": line,
            "stop_line_distance": float(st.line_distance[env]),
            "next_stop_line_front": front_line,
            "stop_line_distance_front": front_distance,
            "light_state_ahead": int(st.light_states[env, line]) if line >= 0 else UNKNOWN,
            "new_incidents": [incident.kind for incident in incidents],
            "is_success": self.is_success(env),
            "termination_reason": self.done_reason[env] if final else "",
            "summary": self.summary(env) if final else None,
        })
        return info

    def summary(self, env: int) -> dict[str, Any]:
        """Env ``env``'s episode summary so far (at its end: ``info["summary"]``)."""
        frozen = self._frozen[env]
        if frozen:
            return dict(frozen["summary"])
        metrics = self.metrics
        summary = metrics.summary(env)
        summary["is_success"] = int(metrics.driving.laps[env]) >= self.setup.laps
        summary["termination_reason"] = self.done_reason[env]
        summary["incident_log"] = [incident.as_dict()
                                   for incident in metrics.driving.incidents[env]]
        summary["manual_time"] = int(self.state.manual_frames_total[env]) * PHYSICS_DT
        summary["obstacles"] = self.state.obstacles[env].tolist()
        return summary


def float_commands(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """Commands as the env reads them from a float32 action (float32 values as float64)."""
    return np.asarray(values, dtype=np.float32).astype(np.float64)
