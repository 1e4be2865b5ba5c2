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
	$(PY) -m pip install --quiet -e ".[dev,ray,video]"
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

evaluate: $(STAMP)  ## the main job: evaluate the reference agent(s) on the default env
	$(PY) evaluate.py

test: $(STAMP) $(CHROMIUM)  ## the test suite
	$(PY) -m pytest

lint: $(STAMP)
	$(VENV)/bin/ruff check .

bench: $(STAMP)  ## speed against highway-env, printed as ratios
	$(PY) benchmarks/bench_highway.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache results
