"""Every case of issue 26 (hostile input, second pass) and of the audit of 2026-12-02, run
once, each printed with what it gives now ("clear": a SystemExit/ValueError naming the
input; "OPEN": accepted; "RAW": another exception) and a markdown table at the end.

    .venv/bin/python tests/hostile_reproduction.py   # about 3 minutes (a 58 MB file, one episode)

The exact messages are pinned by tests/test_hostile_input.py and
tests/test_hostile_batches.py; this script is the whole list in one run.
"""

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import sdc_gym  # noqa

sys.path.insert(0, os.getcwd())
from tests.conftest import UDACITY

T = Path(tempfile.mkdtemp())
H, TR = "sdc_gym/HighwayLoop-v0", "sdc_gym/TrackLoop-v0"
SITE = {"track": "site", "max_duration": 5.0}
results = []


def case(name):
    def deco(fn):
        t0 = time.perf_counter()
        try:
            out = fn()
            msg = f"NO ERROR ({out!r})"[:300]
            kind = "OPEN"
        except SystemExit as e:
            msg = f"SystemExit: {e}"
            kind = "clear"
        except (ValueError, TypeError) as e:
            msg = f"{type(e).__name__}: {e}"
            kind = "clear?"
        except Exception as e:
            msg = f"{type(e).__name__}: {e}"
            kind = "RAW"
        results.append((name, kind, msg[:400], time.perf_counter() - t0))
        print(f"[{kind}] {name} ({time.perf_counter() - t0:.1f}s)\n    {msg[:400]}", flush=True)

    return deco


def bomb():
    names = "abcdefghi"
    lines = ["a: &a [" + ", ".join(["x"] * 10) + "]"]
    lines += [
        f"{names[i]}: &{names[i]} [" + ", ".join([f"*{names[i - 1]}"] * 10) + "]"
        for i in range(1, 9)
    ]
    return "\n".join(lines) + "\n"


@case("alias bomb scenario via evaluate.py")
def _():
    p = T / "bomb.yaml"
    p.write_text(bomb())
    import evaluate

    evaluate.main(
        [
            "--scenario",
            str(p),
            "--agents",
            "lane_keeping",
            "--output",
            str(T / "r1"),
            "--episodes",
            "1",
            "--workers",
            "1",
            "--no-progress",
        ]
    )


@case("alias bomb env config via evaluate --env-config")
def _():
    p = T / "bomb2.yaml"
    p.write_text(bomb())
    import evaluate

    evaluate.main(
        [
            "--config",
            str(p),
            "--agents",
            "lane_keeping",
            "--output",
            str(T / "r2"),
            "--episodes",
            "1",
            "--workers",
            "1",
            "--no-progress",
        ]
    )


@case("10,000-car list message length")
def _():
    gym.make(H, config={"traffic": {"car_count": [{"lane": 1}] * 10000}})


@case("decision_period_s 1e6")
def _():
    gym.make("sdc_gym/TrackLoopBehavior-v0", config={"decision_period_s": 1e6})


@case("camera width 1e6")
def _():
    gym.make(TR, config={"camera": {"enabled": True, "width": 1000000}})


@case("make_vec num_envs=10**7")
def _():
    gym.make_vec(H, num_envs=10**7, vectorization_mode="vector_entry_point")


@case("light config 100,000 stop lines")
def _():
    from sdc_gym.road.track_map import load_light_config

    p = T / "l.yaml"
    p.write_text(
        "camera_info:\n  image_width: 800\n  image_height: 600\nstop_line_positions:\n"
        + "  - [1.0, 2.0]\n" * 100000
    )
    load_light_config(p)


@case("map 'x'*100000")
def _():
    gym.make(H, config={"map": "x" * 100000})


for a in ("zeros((0,3))", "zeros((5,0))", "[]"):

    @case(f"HighwayLoop empty {a}")
    def _(a=a):
        e = gym.make(H, config={"map": "oval", "max_duration": 5.0})
        e.reset(seed=0)
        e.step(eval("np." + a) if a != "[]" else [])


@case("HighwayLoopBehavior object array")
def _():
    e = gym.make(
        "sdc_gym/HighwayLoopBehavior-v0", config={"highway": {"map": "oval", "max_duration": 5.0}}
    )
    e.reset(seed=0)
    e.step(np.array([1], dtype=object))


VEC = {
    H: (
        {"map": "oval", "max_duration": 0.2},
        lambda n, env: np.zeros((n, env.single_action_space.shape[0], 2)),
    ),
    "sdc_gym/HighwayLoopBehavior-v0": (
        {"highway": {"map": "oval", "max_duration": 0.5}},
        lambda n, env: np.zeros(n, dtype=np.int64),
    ),
    TR: ({"track": "site", "max_duration": 0.2}, lambda n, env: np.zeros((n, 3))),
    "sdc_gym/TrackLoopBehavior-v0": (
        {"track": {"track": "site", "max_duration": 1.0}},
        lambda n, env: np.zeros(n, dtype=np.int64),
    ),
}
for vid, (cfg, act) in VEC.items():

    @case(f"vector {vid} NaN batch after an env ended")
    def _(vid=vid, cfg=cfg, act=act):
        envs = gym.make_vec(vid, num_envs=2, vectorization_mode="vector_entry_point", config=cfg)
        envs.reset(seed=0)
        a = act(2, envs)
        for _ in range(200):
            _, _, te, tr, _ = envs.step(a)
            if (te | tr).any():
                break
        assert (te | tr).any()
        bad = a.astype(np.float64).copy()
        bad[int(np.flatnonzero(te | tr)[0])] = np.nan
        envs.step(bad)


@case("reset options='x' (highway)")
def _():
    e = gym.make(H, config={"map": "oval"})
    e.reset(options="x")


@case("reset unknown option key (highway)")
def _():
    e = gym.make(H, config={"map": "oval"})
    e.reset(options={"senario": None})


@case("reset {'scenario': ...} on the track env")
def _():
    e = gym.make(TR, config=SITE)
    e.reset(options={"scenario": None})


@case("reset {'scenario': ...} on TrackLoopBehavior")
def _():
    e = gym.make("sdc_gym/TrackLoopBehavior-v0", config={"track": SITE})
    e.reset(options={"scenario": None})


@case("reset_mask ['no']*4 (track batch)")
def _():
    envs = gym.make_vec(
        TR,
        num_envs=4,
        vectorization_mode="vector_entry_point",
        config=SITE,
        autoreset_mode="Disabled",
    )
    envs.reset(seed=0)
    envs.reset(options={"reset_mask": ["no"] * 4})


@case("reset_mask ['no']*4 (highway batch)")
def _():
    envs = gym.make_vec(
        H,
        num_envs=4,
        vectorization_mode="vector_entry_point",
        config={"map": "oval"},
        autoreset_mode="Disabled",
    )
    envs.reset(seed=0)
    envs.reset(options={"reset_mask": ["no"] * 4})


@case("reset options='x' (batch)")
def _():
    envs = gym.make_vec(
        H, num_envs=2, vectorization_mode="vector_entry_point", config={"map": "oval"}
    )
    envs.reset(options="x")


@case("figure eight crossing at first waypoint")
def _():
    from sdc_gym.road.highway_map import load_highway_map
    from tests.test_file_validation import highway_rows

    t = np.linspace(0.0, 2 * np.pi, 50, endpoint=False)
    p = T / "eight.csv"
    p.write_text(highway_rows(np.column_stack([1000 * np.sin(t), 500 * np.sin(2 * t)]) + 2000.0))
    load_highway_map(p)


SCEN = {
    "gap 0": "ego: {lane: 1, speed: 20}\ncars:\n  - {lane: 1, gap: 0, speed: 20}\n",
    "gap 2": "ego: {lane: 1, speed: 20}\ncars:\n  - {lane: 1, gap: 2, speed: 20}\n",
    "two cars same spot": "ego: {lane: 1, speed: 20}\ncars:\n"
    "  - {name: a, lane: 0, gap: 30, speed: 20}\n  - {name: b, lane: 0, gap: 30, speed: 20}\n",
    "ego d 100": "ego: {d: 100, speed: 20}\n",
    "lane_change to lane 7": "ego: {lane: 1, speed: 20}\ncars:\n"
    "  - {name: a, lane: 0, gap: 30, speed: 20}\nactions:\n"
    "  - {car: a, when: {time: 1}, do: lane_change, lane: 7}\n",
    "reach_lane 5": "ego: {lane: 1, speed: 20}\nsuccess:\n  reach_lane: {lane: 5, within: 10}\n",
    "duplicated duration": "ego:\n  lane: 1\nduration: 6\ncars: []\nduration: 20\n",
}
for n, text in SCEN.items():

    @case(f"scenario {n}")
    def _(n=n, text=text):
        p = T / f"s_{n.replace(' ', '_')}.yaml"
        p.write_text(text)
        e = gym.make(H, config={"max_duration": 5.0})
        e.reset(seed=0, options={"scenario": str(p)})


for rep in (
    [{"replay": {}}],
    [{"replay": 5}],
    [{"kind": "collision", "time": 3.0, "replay": {"map": "original"}}],
):

    @case(f"incidents.json {json.dumps(rep)[:60]}")
    def _(rep=rep):
        p = T / "incidents.json"
        p.write_text(json.dumps(rep))
        import evaluate

        evaluate.main(
            [
                "--scenario",
                str(p),
                "--agents",
                "lane_keeping",
                "--output",
                str(T / f"ri{id(rep)}"),
                "--workers",
                "1",
                "--no-progress",
            ]
        )


@case("import sdc_gym.validation.scenarios alone")
def _():
    r = subprocess.run(
        [sys.executable, "-c", "import sdc_gym.validation.scenarios"],
        capture_output=True,
        text=True,
    )
    if r.returncode:
        raise RuntimeError(r.stderr[-300:])
    raise SystemExit("imports fine (valid)")


def train_cfg(*cli, text=None):
    import yaml

    import train

    p = T / "run.yaml"
    p.write_text(
        text
        if text is not None
        else yaml.safe_dump(
            {"env": "sdc_gym/HighwayLoopBehavior-v0", "config": {"highway": {"max_duration": 20.0}}}
        )
    )
    return train.run_config(
        train.parse_args(["--config", str(p), "--output", str(T / "trun"), *cli])
    )


@case("--hp activation_fn=torch.nn.ReLU")
def _():
    c = train_cfg("--hp", "policy_kwargs.activation_fn=torch.nn.ReLU")
    raise SystemExit(f"valid: resolved, kept {c['hyperparams']['policy_kwargs']}")


@case("--hp activation_fn=torch.nn.Relu6")
def _():
    train_cfg("--hp", "policy_kwargs.activation_fn=torch.nn.Relu6")


@case("algo sac on Discrete")
def _():
    train_cfg("--algo", "sac")


@case("--hp net_arch=[0]")
def _():
    train_cfg("--hp", "policy_kwargs.net_arch=[0]")


@case("empty --config")
def _():
    train_cfg(text="# nothing\n")


@case("duplicated YAML key in run config")
def _():
    train_cfg(text="algo: ppo\ntimesteps: 10\nalgo: dqn\n")


@case("evaluate --agents dbw_ground_truth on highway")
def _():
    import evaluate

    evaluate.main(
        [
            "--agents",
            "dbw_ground_truth",
            "--output",
            str(T / "r3"),
            "--episodes",
            "1",
            "--workers",
            "1",
            "--no-progress",
        ]
    )


@case("stale .tmp files removed")
def _():
    from sdc_evaluation.run_folders import remove_stale_temporaries

    d = T / "stale"
    d.mkdir()
    (d / ".replay_buffer.pkl.abc.tmp").write_bytes(b"x")
    (d / ".r.png.999999.tmp").write_bytes(b"x")
    raise SystemExit(f"removed {[p.name for p in remove_stale_temporaries(d)]}")


# audit
@case("light file unknown key")
def _():
    from sdc_gym.road.track_map import load_light_config

    p = T / "l2.yaml"
    p.write_text(
        "camera_info:\n  image_width: 800\n  image_height: 600\n"
        "stop_line_positions:\n  - [1148.56, 1184.65]\ncolour: red\n"
    )
    load_light_config(p)


@case("stop line at 1e7 m")
def _():
    from sdc_gym.road.track_map import load_track

    p = T / "l3.yaml"
    p.write_text(
        "camera_info:\n  image_width: 800\n  image_height: 600\n"
        "stop_line_positions:\n  - [10000000.0, 1184.65]\n"
    )
    load_track(UDACITY / "capstone" / "sim_waypoints.csv", p)


@case("site light file on the sim track")
def _():
    from sdc_gym.road.track_map import load_track

    load_track(
        UDACITY / "capstone" / "sim_waypoints.csv",
        UDACITY / "capstone" / "site_traffic_light_config.yaml",
    )


@case("site light file on sim track via env config")
def _():
    gym.make(TR, config={"lights": str(UDACITY / "capstone" / "site_traffic_light_config.yaml")})


@case("full_info='no'")
def _():
    gym.make_vec(H, num_envs=2, vectorization_mode="vector_entry_point", full_info="no")


@case("num_envs=True")
def _():
    gym.make_vec(TR, num_envs=True, vectorization_mode="vector_entry_point")


@case("start_s 1e300")
def _():
    gym.make(H, config={"start_s": 1e300})


@case("car_count 1000")
def _():
    gym.make(H, config={"traffic": {"car_count": 1000}})


@case("car_count 57 (one past the road)")
def _():
    gym.make(H, config={"traffic": {"car_count": 57}})


@case("58 MB map file")
def _():
    p = T / "big.csv"
    with open(p, "w") as f:
        line = "1000.0 2000.0 0.0 0.5 0.5\n"
        f.write(line * (58_000_000 // len(line)))
    gym.make(H, config={"map": str(p)})


# batch products
@case("batch: num_envs 4096 x path_points 10000")
def _():
    gym.make_vec(
        H, num_envs=4096, vectorization_mode="vector_entry_point", config={"path_points": 10000}
    )


@case("batch: num_envs 4096 x car_count 65 (spawn_range 1000)")
def _():
    gym.make_vec(
        H,
        num_envs=4096,
        vectorization_mode="vector_entry_point",
        config={"map": "oval", "traffic": {"car_count": 65, "spawn_range": 1000.0}},
    )


@case("batch: 4096 x decision_frames 50000 behavior")
def _():
    gym.make_vec(
        "sdc_gym/HighwayLoopBehavior-v0",
        num_envs=4096,
        vectorization_mode="vector_entry_point",
        config={"decision_frames": 50000, "highway": {"max_duration": 1000.0}},
    )


@case("batch track 4096 x camera 3840x2160")
def _():
    gym.make_vec(
        TR,
        num_envs=4096,
        vectorization_mode="vector_entry_point",
        config={"camera": {"enabled": True, "width": 3840, "height": 2160}},
    )


@case("batch track behavior 4096 x decision 1000 s")
def _():
    gym.make_vec(
        "sdc_gym/TrackLoopBehavior-v0",
        num_envs=4096,
        vectorization_mode="vector_entry_point",
        config={"decision_period_s": 1000.0},
    )


# agent kinds
for spec, env in (
    ("dqn:evaluate.py", H),
    ("rllib:agents", H),
    ("external:./path_planning", TR),
    ("capstone:roslaunch x", H),
    ("dqn:agents/highway/policies/dqn_highway.zip", TR),
    ("dqn_highway", TR),
    ("ppo:agents/highway/policies/dqn_highway.zip", H),
    ("dqn:/nonexistent.zip", H),
    ("rllib:/nonexistent", H),
):

    @case(f"agent {spec} on {env}")
    def _(spec=spec, env=env):
        import evaluate

        args = [
            "--agents",
            spec,
            "--output",
            str(T / f"ra{abs(hash(spec + env))}"),
            "--episodes",
            "1",
            "--workers",
            "1",
            "--no-progress",
        ]
        if env == TR:
            args += ["--env", env]
        evaluate.main(args)


print("\n\n| case | outcome | message | s |\n|---|---|---|---|")
for n, k, m, s in results:
    print(f"| {n} | {k} | {m[:200]} | {s:.1f} |")
