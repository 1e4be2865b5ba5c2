"""The installed distribution, outside the repo: the README's install-from-pip path.

The wheel is built from the tree (``pip wheel --no-deps --no-build-isolation``), installed
with ``pip install --no-deps`` into a fresh venv in a temporary folder (its dependencies
are this venv's site-packages, through a ``.pth`` file, so nothing is downloaded), and
run from a user's own project folder that has packages named ``agents/`` and
``evaluation/`` of its own: ``sdc-evaluate`` drives an episode, ``python -m sdc_training``
trains a few hundred steps, the other two entry points answer ``--help``, and the user's
packages and ours import side by side.

numba compiles the kernels where the package is installed (its cache lives next to the
modules, stamped with the hash of the package's kernel modules:
:mod:`sdc_gym.kernel_compiler`). A cold install costs ~47 s CPU for the highway's kernels
(a lane-keeping episode: 5 s once cached) and ~32 s for the behavior env's (the
training); the files are the same bytes as the checkout's, so the checkout's cache files
are copied into the install first and load there (the stamp decides; a stale or missing
one is compiled). With the checkout's caches current the module took 52 s CPU (124 s wall
at load 14 on the 2-core machine), most of it five interpreters importing torch and
numba; cold, with only part of them, 84 s (docs/install.md).
"""

from __future__ import annotations

import csv
import os
import shutil
import subprocess
import sys
import sysconfig
import tomllib
import zipfile
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ("sdc_gym", "agents", "evaluation", "training", "configs", "evaluate.py",
           "train.py", "pyproject.toml", "README.md")
"""What the wheel is built from (a copy, so that the build writes nothing into the repo)."""
IMPORT_NAMES = {"sdc_gym": "sdc_gym", "agents": "sdc_agents", "evaluation": "sdc_evaluation",
                "training": "sdc_training", "configs": "sdc_configs"}
"""Folder -> installed import name (pyproject's package-dir)."""
TOP_LEVEL = {*IMPORT_NAMES.values(), "sdc_gym_cli"}


def test_the_package_list_names_every_package_folder_of_the_tree():
    """pyproject lists the packages (setuptools' find would name them by folder): every
    folder with an ``__init__.py`` is there under its import name, and nothing else."""
    settings = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    folders = {folder: name for name, folder in settings["package-dir"].items()}
    assert {"sdc_gym": "sdc_gym", **folders} == {**IMPORT_NAMES, ".": "sdc_gym_cli"}
    expected = {"sdc_gym_cli"}
    for folder, name in IMPORT_NAMES.items():
        for init in (ROOT / folder).rglob("__init__.py"):
            parts = init.parent.relative_to(ROOT / folder).parts
            expected.add(".".join((name, *parts)))
    assert set(settings["packages"]) == expected


def test_config_arguments_name_a_file_or_a_packaged_config(tmp_path, monkeypatch):
    """``--config`` / ``--tune`` (:func:`sdc_configs.config_path`): a file that exists is
    itself; else the repo path, the file name or the bare name of a packaged config, from
    any folder; anything else an error naming the value and the packaged configs."""
    import argparse

    from sdc_configs import config_path, packaged, packaged_names

    configs = ROOT / "configs"
    assert packaged() == configs  # the editable install maps sdc_configs onto configs/
    monkeypatch.chdir(tmp_path)
    for text in ("configs/track_loop.yaml", "track_loop.yaml", "track_loop"):
        assert config_path(text) == configs / "track_loop.yaml"
    assert config_path("tune/highway_ppo") == configs / "tune" / "highway_ppo.yaml"
    own = tmp_path / "track_loop.yaml"  # the user's own file of the same name wins
    own.write_text("config: {}\n")
    assert config_path("track_loop.yaml") == Path("track_loop.yaml")
    assert "hyperparams/dqn" in packaged_names() and "train_highway_behavior" in packaged_names()
    with pytest.raises(argparse.ArgumentTypeError,
                       match=r"'nowhere.yaml': no such file, nor a packaged config; "
                             r"packaged: .*highway_dense_traffic, .*track_loop"):
        config_path("nowhere.yaml")


@dataclass(frozen=True)
class Install:
    venv: Path
    wheel: Path
    project: Path  # the user's own project folder (the working folder of every command)

    def bin(self, name: str) -> str:
        return str(self.venv / "bin" / name)

    def run(self, *command: str) -> subprocess.CompletedProcess[str]:
        environment = {key: value for key, value in os.environ.items()
                       if key not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
        result = subprocess.run(command, cwd=self.project, env=environment, text=True,
                                capture_output=True, check=False)
        assert result.returncode == 0, f"{command}:\n{result.stdout}\n{result.stderr}"
        return result


def site_packages(python: Path) -> Path:
    return Path(subprocess.check_output(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        text=True).strip())


def copy_kernel_caches(source: Path, target: Path) -> int:
    """The checkout's numba cache files of ``sdc_gym`` into the installed package's
    ``__pycache__`` folders (the number copied)."""
    copied = 0
    for path in source.glob("**/__pycache__/*.nb[ic]"):
        destination = target / path.relative_to(source)
        destination.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(path, destination)
        copied += 1
    return copied


USER_AGENTS = '''"""A user's own agents package (the name sdc-gym's folder has in its repo)."""
from pathlib import Path

# Leaves a mark when imported, so the test sees whether sdc-gym's commands import it.
(Path(__file__).parents[1] / "imported.txt").open("a").write(__name__ + "\\n")
'''


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Install:
    base = tmp_path_factory.mktemp("wheel")
    source = base / "source"
    source.mkdir()
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, source / name, ignore=ignore)
        else:
            shutil.copy2(ROOT / name, source / name)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps",
                    "--no-build-isolation", "--wheel-dir", str(base / "dist"), str(source)],
                   check=True, capture_output=True)
    [wheel] = (base / "dist").glob("sdc_gym-*.whl")
    venv = base / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    target = site_packages(venv / "bin" / "python")
    paths = sysconfig.get_paths()
    (target / "project_dependencies.pth").write_text(
        "\n".join(dict.fromkeys([paths["purelib"], paths["platlib"]])) + "\n")
    subprocess.run([sys.executable, "-m", "pip", "--python", str(venv / "bin" / "python"),
                    "install", "--quiet", "--no-deps", "--no-index", str(wheel)],
                   check=True, capture_output=True)
    copy_kernel_caches(ROOT / "sdc_gym", target / "sdc_gym")
    project = base / "my_project"
    (project / "agents").mkdir(parents=True)
    (project / "agents" / "__init__.py").write_text(USER_AGENTS)
    (project / "agents" / "my_driver.py").write_text('NAME = "my_driver"\n')
    (project / "evaluation").mkdir()
    (project / "evaluation" / "__init__.py").write_text('"""The user\'s own."""\n')
    (project / "evaluation" / "my_metrics.py").write_text("SCORE = 1\n")
    return Install(venv, wheel, project)


def test_the_wheel_installs_only_prefixed_names_and_ships_its_data(installed):
    names = zipfile.ZipFile(installed.wheel).namelist()
    assert {name.split("/")[0] for name in names} - {"sdc_gym-0.1.0.dist-info"} == TOP_LEVEL
    for data in ("sdc_configs/train_highway_behavior.yaml", "sdc_configs/hyperparams/dqn.yaml",
                 "sdc_configs/tune/highway_ppo.yaml", "sdc_configs/track_loop.yaml",
                 "sdc_agents/highway/policies/dqn_highway.zip",
                 "sdc_agents/highway/policies/dqn_swa_highway.zip",  # evaluate.py's default
                 "sdc_agents/highway/policies/dqn_swa_highway.yaml",
                 "sdc_agents/track/models/light_cnn.pt", "sdc_gym/scenarios/library/"
                 "a_early_lane_change.yaml", "sdc_gym_cli/evaluate.py", "sdc_gym_cli/train.py"):
        assert data in names, data


def test_next_to_a_users_own_agents_an_evaluation_and_a_training_run(installed):
    project = installed.project
    # One short episode of the committed policy, by the repo path the docs use: the
    # user's own agents/ folder does not hide the packaged one.
    (project / "short.yaml").write_text("config:\n  max_duration: 10.0\n")
    installed.run(installed.bin("sdc-evaluate"), "--agents",
                  "dqn:agents/highway/policies/dqn_highway.zip", "--seeds", "0", "--config",
                  "short.yaml", "--workers", "1", "--no-plots", "--no-progress",
                  "--output", "results/first")
    with (project / "results" / "first" / "episodes.csv").open() as handle:
        [episode] = list(csv.DictReader(handle))
    assert episode["agent"] == "dqn:agents/highway/policies/dqn_highway.zip"
    assert float(episode["distance"]) > 100.0  # 10 s at highway speed
    # A short training by the packaged run config's name, from the user's folder.
    trained = installed.run(installed.bin("python"), "-m", "sdc_training", "--config",
                            "train_highway_behavior", "--timesteps", "300", "--n-envs", "1",
                            "--eval-every", "0", "--hp", "learning_starts=100",
                            "--no-progress", "--output", "runs/first")
    assert "trained 300 steps" in trained.stdout
    assert (project / "runs" / "first" / "model.zip").is_file()
    assert "hyperparams" not in {p.name for p in project.iterdir()}
    assert not (project / "imported.txt").exists(), "sdc-gym imported the user's agents"
    # The other two entry points, and both packages side by side in one interpreter.
    assert "--agents" in installed.run(installed.bin("python"), "-m", "sdc_evaluation",
                                       "--help").stdout
    assert "--hp KEY=VALUE" in installed.run(installed.bin("sdc-train"), "--help").stdout
    both = installed.run(installed.bin("python"), "-c",
                         "import agents.my_driver, evaluation.my_metrics, "
                         "sdc_evaluation.runner, sdc_agents.registry; "
                         "print(agents.__file__); print(sdc_evaluation.runner.__file__)")
    user_file, ours = both.stdout.split()
    assert Path(user_file) == project / "agents" / "__init__.py"
    assert Path(ours).is_relative_to(installed.venv)
    assert (project / "imported.txt").read_text() == "agents\n"
