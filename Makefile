# make test : set up everything on a fresh machine, then run the whole suite.
# make run  : set up, then open the viewer on a bundled sample (headless: print the
#             reconstruction and render a screenshot instead).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
SAMPLE := sample_data/hertz_shear_turning.npz
# a display for the viewer benchmark: the user's own, or a virtual one
XRUN   := $(if $(DISPLAY)$(WAYLAND_DISPLAY),,xvfb-run -a -s "-screen 0 1920x1080x24")

# Debian packages for Xvfb and Qt's xcb platform plugin (GUI tests run in Xvfb).
DEBS := xvfb xauth libxkbcommon-x11-0 libxcb-cursor0 libxcb-icccm4 libxcb-keysyms1 \
        libxcb-shape0 libxcb-image0 libxcb-render-util0 libxcb-xinerama0 libegl1 libgl1 \
        libglib2.0-0 libfontconfig1 libdbus-1-3

.PHONY: test run lint bench system-deps clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	$(PY) -c "from solver.warmup import warm_up; warm_up()"  # compile the contact fit once (numba)
	touch $(STAMP)

system-deps:
	@missing=""; for p in $(DEBS); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ]; then \
	    echo "installing:$$missing"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing >/dev/null; \
	  else \
	    echo "missing Debian packages (run as root or install them):$$missing"; exit 1; \
	  fi; \
	fi

# one pytest worker per core (at most 4), each with its own Xvfb: about 40% less wall time on 2 cores
test: system-deps $(STAMP)
	$(PY) -m pytest -n auto --maxprocesses=4 --dist worksteal

run: $(STAMP)
	@if [ -n "$$DISPLAY$$WAYLAND_DISPLAY" ]; then \
	  $(PY) -m tactile_viewer $(SAMPLE); \
	else \
	  echo "no display: printing the reconstruction and rendering one frame instead of opening the window"; \
	  $(PY) -m tactile_viewer $(SAMPLE) --report && \
	  $(PY) -m tactile_viewer $(SAMPLE) --frame 30 --screenshot sample_frame30.png; \
	fi

lint: $(STAMP)
	$(PY) -m ruff check solver measurement tactile_viewer tests tools benchmarks

bench: system-deps $(STAMP)
	$(PY) -m measurement.bench
	$(XRUN) $(PY) -m benchmarks.viewer_speed

clean:
	rm -rf $(VENV) .pytest_cache
