"""One episode of a capstone stack: its process, the connection, and the messages of
every env step.

:class:`CapstoneSession` plays the original simulator for a ``sdc_gym/TrackLoop-v0`` env.
At :meth:`~CapstoneSession.start` it launches the stack's command (if given) under the
planner bridge's process machinery (:class:`~sdc_gym.bridge.process.PlannerProcess`: its
own session below a subreaper, output in a capped log, the whole tree ended by
:meth:`~CapstoneSession.close` and if the owner dies) and connects to its styx server.
Each :meth:`~CapstoneSession.action` call is one env step: it sends that step's
messages, built from the step's ``info`` and the env's lights
(:mod:`sdc_gym.capstone.protocol`), and returns the action to step with, the latest
value of each of the stack's three commands, clamped to the car's ranges as the
original's car controller clamps them. Before the stack's first command the pedals are
released and the wheel straight (the original car waits the same way).

Timing: ``lockstep=False`` (default, the original's only mode) paces the env to wall time
(a step is never taken before its simulated time) and sends telemetry without waiting;
``lockstep=True`` waits after every telemetry message until the server has handled it
(see :mod:`sdc_gym.capstone.client`) and runs as fast as the stack keeps up.
``sim_time=True`` (a stack launched with ``/use_sim_time`` true) adds sdc-gym's
``/clock`` (:mod:`sdc_gym.capstone.sim_clock`): each step first sets the stack's clock to
the env's time and waits for the DBW node's commands of that tick, then exchanges
telemetry in lock-step (``docs/capstone.md``, "Time", says when a step is handled). Rates, in
env steps: telemetry every step, ``control``, ``trafficlights`` and (when the env has
obstacles) ``obstacle`` every ``report_every`` steps, ``image`` every ``image_every``
steps (0: no camera, the default; the original's camera checkbox starts off).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from sdc_gym.bridge.errors import PlannerLogFlooded
from sdc_gym.bridge.planner_log import DEFAULT_LOG_LIMIT_BYTES
from sdc_gym.bridge.process import PlannerProcess, free_port
from sdc_gym.capstone.client import StyxClient
from sdc_gym.capstone.errors import RosClockFailed, StackDisconnected, StackStalled
from sdc_gym.capstone.protocol import (
    BRAKE,
    COMMAND_EVENTS,
    CONTROL,
    DEFAULT_HOST,
    DEFAULT_JPEG_QUALITY,
    DEFAULT_PORT,
    IMAGE,
    IMAGE_FORMATS,
    OBSTACLE,
    STEER,
    TELEMETRY,
    THROTTLE,
    TRAFFIC_LIGHTS,
    CarReport,
    car_report,
    control_fields,
    encode_image,
    obstacle_fields,
    telemetry_fields,
    traffic_light_fields,
)
from sdc_gym.capstone.sim_clock import DBW_COMMAND_TOPICS, DEFAULT_ROS_PYTHON, RosClock
from sdc_gym.vehicle.dbw_vehicle import PHYSICS_DT

PORT_PLACEHOLDER: Final = "{port}"
MASTER_PORT_PLACEHOLDER: Final = "{master_port}"  # a free port for the stack's ROS master
DEATH_WAIT_S: Final = 1.0  # for the exit status of a stack whose connection ended


@dataclass(frozen=True)
class CapstoneOptions:
    """How a capstone episode runs (``evaluate.py``'s ``--stack-*`` flags).

    Attributes:
        host, port: the styx server's address; ``port=None``: a free port when the
            command has ``{port}``, else 4567 like the original.
        cwd: the stack's working directory (e.g. the team's ``ros`` folder).
        log_path, log_limit: the stack's output file and its largest size in bytes.
        startup_timeout: wall s for the server to accept the connection.
        reply_timeout: wall s; lock-step: for the server to handle one telemetry
            message; and the longest silence of a stack that has started to drive
            (while ``dbw_enable`` is on; ``startup_timeout`` before its first command),
            before the episode ends ``stack_stalled``.
        lockstep: step as fast as the stack keeps up instead of in real time.
        sim_time: own the stack's ``/clock`` (implies lock-step): for a stack launched
            with ``/use_sim_time`` true on the master at ``ros_master_uri`` (``None``: a
            free port when the command has ``{master_port}``, else ``$ROS_MASTER_URI``,
            else roscore's default; a stack started here gets it as its
            ``ROS_MASTER_URI``); ``ros_python`` runs the clock
            node; ``clock_topics`` answer a tick (the DBW node's commands); a tick they
            have not all answered within ``tick_timeout`` wall s is *missed*: the step
            goes on with the commands held (``reply_timeout`` of them ends the episode
            ``stack_stalled``).
        report_every, image_every: env steps between ``control``/``trafficlights``/
            ``obstacle`` and between ``image`` messages (0: never).
        image_width, image_height, image_format, image_quality: the camera frame.
    """

    host: str = DEFAULT_HOST
    port: int | None = None
    cwd: str | None = None
    log_path: str | None = None
    log_limit: int = DEFAULT_LOG_LIMIT_BYTES
    startup_timeout: float = 30.0
    reply_timeout: float = 5.0
    lockstep: bool = False
    sim_time: bool = False
    ros_master_uri: str | None = None
    ros_python: str = DEFAULT_ROS_PYTHON
    clock_topics: tuple[str, ...] = DBW_COMMAND_TOPICS
    tick_timeout: float = 1.0
    report_every: int = 1
    image_every: int = 0
    image_width: int = 800
    image_height: int = 600
    image_format: str = "jpeg"
    image_quality: int = DEFAULT_JPEG_QUALITY

    def __post_init__(self) -> None:
        for name in ("startup_timeout", "reply_timeout", "tick_timeout"):
            if not getattr(self, name) > 0:
                raise ValueError(f"CapstoneOptions.{name} must be > 0 s, got "
                                 f"{getattr(self, name)!r}")
        for name in ("report_every", "image_every"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ValueError(f"CapstoneOptions.{name} must be an int >= 0 steps, got "
                                 f"{value!r}")
        if self.report_every < 1:
            raise ValueError(f"CapstoneOptions.report_every must be >= 1 step, got "
                             f"{self.report_every}")
        if self.image_format not in IMAGE_FORMATS:
            raise ValueError(f"CapstoneOptions.image_format must be one of {IMAGE_FORMATS}, "
                             f"got {self.image_format!r}")
        topics = self.clock_topics
        if isinstance(topics, str) or not all(isinstance(t, str) for t in topics):
            raise ValueError(f"CapstoneOptions.clock_topics must be a sequence of topic "
                             f"names, got {topics!r}")
        object.__setattr__(self, "clock_topics", tuple(topics))  # a list from JSON
        if self.sim_time and not self.clock_topics:
            raise ValueError("CapstoneOptions.clock_topics must name at least one topic "
                             "that answers a tick (the DBW node's commands by default)")
        if self.port is not None and not 0 < self.port < 65536:
            raise ValueError(f"CapstoneOptions.port must be in 1..65535, got {self.port}")


class CapstoneSession:
    """A stack (``command``, or one already running at ``options.host:port``) driving
    ``env`` (a ``TrackLoop-v0``); see the module docstring."""

    def __init__(self, env: Any, command: str | None = None,
                 options: CapstoneOptions | None = None) -> None:
        self.options = options or CapstoneOptions()
        unwrapped = env.unwrapped
        self.env = unwrapped
        setup = unwrapped.world.setup
        self._centre_offset = float(setup.centre_offset)
        self._road_wheel_ratio = float(unwrapped.params.road_wheel_ratio)
        lock = float(unwrapped.max_steering_angle)
        self._low = np.array([0.0, 0.0, -lock])
        self._high = np.array([1.0, float(unwrapped.max_brake_torque), lock])
        self._step_s = PHYSICS_DT * int(unwrapped.steps_per_action)
        port = self.options.port
        if port is None:
            port = free_port() if command and PORT_PLACEHOLDER in command else DEFAULT_PORT
        self.port = int(port)
        self.ros_master_uri = self.options.ros_master_uri
        if command is not None and MASTER_PORT_PLACEHOLDER in command:
            if self.ros_master_uri is not None:
                raise ValueError(f"the stack command has {MASTER_PORT_PLACEHOLDER} and "
                                 f"ros_master_uri is {self.ros_master_uri!r}: give one")
            master_port = free_port()
            while master_port == self.port:
                master_port = free_port()
            command = command.replace(MASTER_PORT_PLACEHOLDER, str(master_port))
            self.ros_master_uri = f"http://127.0.0.1:{master_port}"
        # The stack's nodes and sdc-gym's clock node on one master.
        stack_env = None if self.ros_master_uri is None else {
            "ROS_MASTER_URI": self.ros_master_uri}
        self.process = (None if command is None else PlannerProcess(
            command, cwd=self.options.cwd, port=self.port, log_path=self.options.log_path,
            log_limit=self.options.log_limit, env=stack_env))
        self.client = StyxClient(self.options.host, self.port)
        self.clock: RosClock | None = None
        if self.options.sim_time:
            clock_log = (None if self.options.log_path is None
                         else f"{self.options.log_path}.clock")
            self.clock = RosClock(self.ros_master_uri, self.options.clock_topics,
                                  self.options.ros_python, clock_log)
        self.missed_ticks = 0  # sim time: ticks the stack did not answer in time
        self.late_steps = 0  # sim time: answered ticks whose commands came a step late
        self.clock_offset_ns = 0  # sim time: ROS time - env time (the start-up's ticks)
        self.startup_wall = 0.0  # sim time: wall s until the stack's first command
        self._step_ns = round(self._step_s * 1e9)
        self._camera: Any = None
        self._steps = 0
        self._wall_start: float | None = None
        self._driving = False  # the stack has sent a command while dbw is on

    # ------------------------------------------------------------------ life cycle
    def start(self) -> None:
        """Start the stack (if a command was given) and connect to its server."""
        if self.process is not None:
            self.process.start()
        self.client.connect(self.options.startup_timeout, alive=self.check_stack)
        if self.clock is not None:  # the styx server is up, so its master is
            self.clock.start(self.options.startup_timeout)

    def check_stack(self) -> None:
        """Raise when the stack's process died or flooded its log."""
        if self.process is None:
            return
        if self.process.log_flooded:
            raise PlannerLogFlooded(
                f"the stack printed more than {self.process.log_limit} bytes; its log "
                f"{self.process.log_path} keeps the beginning and the end")
        self.process.check_alive()

    def close(self) -> None:
        """Disconnect and end the stack's whole process tree (safe to repeat)."""
        self.client.close()
        if self.clock is not None:
            self.clock.close()
        if self.process is not None:
            self.process.stop()

    # ------------------------------------------------------------------ one step
    def action(self, info: dict[str, Any]) -> NDArray[np.float32]:
        """Send this step's messages (``info``: the env's latest) and return the action
        to step with; raises a :class:`~sdc_gym.bridge.errors.BridgeError` on a fault."""
        try:
            return self._action(info)
        except (StackDisconnected, StackStalled, RosClockFailed) as error:
            # A stack that died closes its socket first: name the death, not its symptom.
            if self.process is not None and self.process.wait_exit(DEATH_WAIT_S) is not None:
                self.check_stack()
            raise error

    def _action(self, info: dict[str, Any]) -> NDArray[np.float32]:
        self.check_stack()
        car = car_report(info, self._centre_offset, self._road_wheel_ratio)
        self._send(info, car)
        if self.clock is not None and self._steps == 0 and car.dbw_enabled:
            self._start_up(info, car)
        self._steps += 1
        commands = self.client.commands()
        self._check_silence(commands, car.dbw_enabled)
        path = self.client.take_drawline()
        if path is not None:
            self.env.set_debug_path(path)
        action = np.array([commands.get(THROTTLE, 0.0), commands.get(BRAKE, 0.0),
                           commands.get(STEER, 0.0)])
        return np.clip(action, self._low, self._high).astype(np.float32)

    def _send(self, info: dict[str, Any], car: CarReport) -> None:
        """This step's messages (sim time: the clock's tick first), telemetry last."""
        options = self.options
        answered = self._tick(info, car.dbw_enabled) if self.clock is not None else False
        if self._steps % options.report_every == 0:
            self.client.emit(CONTROL, control_fields(car))
            world = self.env.world
            if len(self.env.track.light_yaw):
                self.client.emit(TRAFFIC_LIGHTS, traffic_light_fields(
                    self.env.track.light_positions, self.env.track.light_yaw,
                    world.state.light_states[0]))
            obstacles = world.state.obstacles[0]
            if len(obstacles):  # none configured: no event, as a track without lights
                self.client.emit(OBSTACLE, obstacle_fields(obstacles))
        if options.image_every and self._steps % options.image_every == 0:
            self.client.emit(IMAGE, {"image": self.image(info)})
        telemetry = telemetry_fields(car)
        if options.lockstep or options.sim_time:
            before = [self.client.stats.received[event] for event in COMMAND_EVENTS]
            self.client.exchange(telemetry, options.reply_timeout)
            if answered and any(self.client.stats.received[event] == count
                                for event, count in zip(COMMAND_EVENTS, before, strict=True)):
                self.late_steps += 1  # the server had not had them all yet
        else:
            self._pace()
            self.client.emit(TELEMETRY, telemetry)

    def _start_up(self, info: dict[str, Any], car: CarReport) -> None:
        """Sim time: step 0's messages again, one tick later each time, until the stack's
        first command (``startup_timeout`` s after connecting at most). The env waits for
        the stack, the car at its start and the lights as they are, so how long the
        nodes take to start on the wall clock does not change the episode; ROS time is
        the env's time + :attr:`clock_offset_ns` from then on."""
        start = time.perf_counter()
        while not self.client.commands():
            self._check_silence({}, car.dbw_enabled)
            self.check_stack()
            self.clock_offset_ns += self._step_ns
            self._send(info, car)
        self.startup_wall = time.perf_counter() - start

    def _tick(self, info: dict[str, Any], dbw_enabled: bool) -> bool:
        """Sim time: set the stack's ``/clock`` to the env's time (+ the start-up's
        offset) and wait for its answer; whether every watched topic answered. Until the
        stack drives (and while DBW is off) a tick waits one step of wall time at most:
        nodes that are starting see time pass no faster than real time."""
        assert self.clock is not None
        driving = self._driving and dbw_enabled
        wait = self.options.tick_timeout if driving else self._step_s
        answer = self.clock.tick(self.clock_offset_ns + round(float(info["time"]) * 1e9),
                                 wait)
        if driving and answer.missing:
            self.missed_ticks += 1
        return not answer.missing

    def _pace(self) -> None:
        """Real time: wait until the wall clock reaches this step's simulated time."""
        now = time.perf_counter()
        if self._wall_start is None:
            self._wall_start = now
        due = self._wall_start + self._steps * self._step_s
        if due > now:
            time.sleep(due - now)

    def _check_silence(self, commands: dict[str, float], dbw_enabled: bool) -> None:
        """A stack whose nodes fell silent (its server may still answer): no command for
        ``reply_timeout`` wall s once it drives, or ``startup_timeout`` s after connecting,
        while ``dbw_enable`` is on (in manual mode a stack must be silent)."""
        self._driving = self._driving or (dbw_enabled and bool(commands))
        silence = self.client.silent_for()
        limit = self.options.reply_timeout if self._driving else self.options.startup_timeout
        if dbw_enabled and silence > limit:
            since = "its last one" if self._driving else "connecting"
            raise StackStalled(f"the stack sent no command for {silence:.1f} s since {since} "
                               "while dbw_enable was on")

    def image(self, info: dict[str, Any]) -> str:
        """The camera frame at the car's pose, encoded and in base64."""
        if self._camera is None:
            from sdc_gym.sensors.track_camera import CameraConfig, TrackCamera

            options = self.options
            base = CameraConfig(variation=False)
            scale = options.image_width / base.width
            config = CameraConfig(width=options.image_width, height=options.image_height,
                                  fx=base.fx * scale, fy=base.fy * scale, variation=False)
            self._camera = TrackCamera(config)
        track = self.env.track
        frame = self._camera.render(float(info["x"]), float(info["y"]), float(info["yaw"]),
                                    track.light_positions, track.light_yaw,
                                    self.env.world.state.light_states[0])
        return encode_image(frame, self.options.image_format, self.options.image_quality)

    def extras(self) -> dict[str, Any]:
        """Figures of the connection for the episode's result."""
        stats = self.client.stats
        extras: dict[str, Any] = {
            "stack_messages_sent": stats.sent,
            "stack_commands_received": sum(stats.received.values()),
            "stack_exchanges": stats.exchanges,
            "stack_wait_time": stats.wait_time,
            "stack_protocol": self.client.protocol,
        }
        if self.clock is not None:
            extras.update({"stack_clock_ticks": self.clock.ticks,
                           "stack_missed_ticks": self.missed_ticks,
                           "stack_late_steps": self.late_steps,
                           "stack_clock_offset": self.clock_offset_ns / 1e9,
                           "stack_startup_wall": self.startup_wall,
                           "stack_clock_pid": self.clock.pid})
        if self.process is not None:
            extras["stack_pid"] = self.process.pid
            extras["stack_log"] = str(self.process.log_path)
        return extras


def run_episode(env: Any, session: CapstoneSession, seed: int | None = None,
                ) -> dict[str, Any]:
    """Drive one episode of ``env`` with ``session`` (started here, closed at the end);
    the env's summary, with ``abort_reason`` and ``abort_message`` when a fault ended it."""
    from sdc_gym.bridge.errors import BridgeError

    _, info = env.reset(seed=seed)
    result: dict[str, Any]
    wall = time.perf_counter()
    try:
        session.start()
        wall = time.perf_counter()  # the stack's start-up is not part of the episode
        while True:
            _, _, terminated, truncated, info = env.step(session.action(info))
            if terminated or truncated:
                result = dict(info["summary"])
                break
    except BridgeError as error:
        result = dict(env.unwrapped.summary())
        result["termination_reason"] = error.reason
        result["abort_reason"], result["abort_message"] = error.reason, str(error)
    finally:
        session.close()
    result.update(session.extras())
    result["wall_time"] = time.perf_counter() - wall
    sim = float(result.get("time", 0.0))
    result["real_time_factor"] = sim / result["wall_time"] if result["wall_time"] else math.nan
    return result


def stack_log_path(folder: str | Path, name: str) -> str:
    """A log file for a stack's output in ``folder``."""
    return str(Path(folder) / f"{name}.log")
