# sarmitsuba: one command to set up and render, one to set up and test (see README).
# `make setup` installs libLLVM >= 16 (Debian's libllvm19; Dr.Jit's LLVM backend needs it),
# creates .venv and installs the package with its dev, Sionna and FastSAR extras.

VENV   ?= .venv
PYTHON ?= python3
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
SCENE  ?=
OUT    ?= out/urban

.PHONY: setup llvm render test bench docs docs-browser clean

setup: llvm $(STAMP)

llvm:
	@if PATH="$$PATH:/sbin:/usr/sbin" ldconfig -p | grep -qE 'libLLVM(-(1[6-9]|[2-9][0-9])\.so|\.so\.(1[6-9]|[2-9][0-9]))'; then \
	  echo "libLLVM >= 16 found"; \
	else \
	  echo "installing libllvm19 (Dr.Jit's LLVM backend needs libLLVM >= 16)"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq libllvm19; \
	fi

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	@# setuptools prints an information-only banner for every editable install of a package-dir layout
	@# (plugins/ and scenes/ install as sarmitsuba_plugins and sarmitsuba_scenes): only that message is
	@# filtered; a deprecation or any other build warning still shows
	PYTHONWARNINGS="ignore:Editable installation:UserWarning" $(PY) -m pip install -q -e '.[dev,sionna,fastsar]'
	touch $(STAMP)

render: setup
	$(PY) -m sarmitsuba render $(SCENE) --out $(OUT)

# -n auto: one pytest worker per core (pytest-xdist); --dist loadfile keeps a file's tests, and the
# renders its module fixtures share, on one worker.
test: setup
	$(PY) -m pytest -q -n auto --dist loadfile

bench: setup
	$(PY) benchmarks/run.py

# The manual (Sphinx, MyST pages, numpydoc API reference, the gallery's examples executed) into
# docs/_build/html; any warning fails the build (-W), and every warning is shown first
# (--keep-going). Then every internal link, anchor and image of the result is checked, and that
# every example left a figure.
docs: setup
	PYTHONWARNINGS="ignore:Editable installation:UserWarning" $(PY) -m pip install -q -e '.[docs]'
	rm -rf docs/_build docs/api/generated docs/gallery
	$(PY) -m sphinx -W --keep-going -q -b html docs docs/_build/html
	$(PY) docs/tools/check_links.py docs/_build/html --gallery-figures
	@echo "manual: docs/_build/html/index.html"

# The built manual in headless Chromium (Debian's chromium and chromium-driver, installed when
# missing): console errors, images, equations, search; screenshots into docs/_build/browser.
docs-browser:
	@if ! command -v chromedriver >/dev/null; then \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends chromium chromium-driver; \
	fi
	$(PY) docs/tools/browser_check.py docs/_build/html --out docs/_build/browser

clean:
	rm -rf out .pytest_cache docs/_build docs/api/generated docs/gallery
