# One-command set-up: every target creates .venv and installs the project on first use.
# torch is pinned to the CPU build first (a plain `torch` would resolve a multi-GB CUDA one).
VENV ?= .venv
PYTHON ?= python3
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: evaluate test lint bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e ".[dev,ray,capstone,video,tuning]"
	# Compile every env's kernels now (cached in __pycache__), so the first env step is warm.
	$(PY) -m sdc_gym.precompile
	touch $(STAMP)

# The HTML report's test opens it in a real headless browser: Debian's chromium, installed
# here when missing (as root, e.g. on CI, after a line that says so; others are told the
# command).
CHROMIUM ?= /usr/bin/chromium
$(CHROMIUM):
	@if [ "$$(id -u)" = 0 ]; then \
		echo "make test: $(CHROMIUM) is missing; installing Debian's chromium now, as root," \
			"with apt-get (the HTML report's test opens the page in it; to skip this," \
			"install chromium yourself first)."; \
		apt-get -o DPkg::Lock::Timeout=600 update -qq && \
		apt-get -o DPkg::Lock::Timeout=600 install -y -qq --no-install-recommends chromium; \
	else \
		echo "$(CHROMIUM) is missing: sudo apt-get install --no-install-recommends chromium"; \
		exit 1; \
	fi

# The capstone's ROS 1 end-to-end test (tests/test_capstone_ros.py): Debian's ROS 1
# packages, installed here when missing and root; otherwise the command is printed and
# that test is skipped. The target is the last message definition the workspace needs
# (ros-core and the -dev packages do not bring the .msg files: ros-std-msgs and
# ros-geometry-msgs do; a machine with roscore but without them fails catkin_make).
ROS_MESSAGES ?= /usr/share/geometry_msgs/msg/PoseStamped.msg
ROS_PACKAGES := ros-core python3-rospy catkin ros-message-generation libstd-msgs-dev \
	libgeometry-msgs-dev python3-std-msgs python3-geometry-msgs ros-std-msgs ros-geometry-msgs
$(ROS_MESSAGES):
	@if [ "$$(id -u)" = 0 ]; then \
		apt-get -o DPkg::Lock::Timeout=600 update -qq && \
		apt-get -o DPkg::Lock::Timeout=600 install -y -qq --no-install-recommends $(ROS_PACKAGES); \
	else \
		echo "$(ROS_MESSAGES) is missing (the ROS test will be skipped): sudo apt-get install --no-install-recommends $(ROS_PACKAGES)"; \
	fi

evaluate: $(STAMP)  ## the main job: evaluate the reference agent(s) on the default env
	$(PY) evaluate.py

test: $(STAMP) $(CHROMIUM) $(ROS_MESSAGES)  ## the test suite
	$(PY) -m pytest

lint: $(STAMP)
	$(VENV)/bin/ruff check .

bench: $(STAMP)  ## speed against highway-env, printed as ratios
	$(PY) benchmarks/bench_highway.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache results
