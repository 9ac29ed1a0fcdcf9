# The whole set-up on a fresh machine with Python >= 3.11: `make demo` or `make test`.
# Both create .venv and install the project into it (editable, with the dev tools) when needed.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
INSTALLED := $(VENV)/.installed

.PHONY: demo test lint typecheck pytest slow wheel-check bench docs site clean

# The main job: a robot crosses a 128x128 world it does not know, frame by frame, under the
# monitor; the frame program is schemas/navigation.any compiled against the measured profiles.
demo: $(INSTALLED)
	$(BIN)/anytime compile domains/navigation/anytime_navigation/schemas/navigation.any --schema navigate --time-grid 0:3000:250
	$(BIN)/anytime navigate --out out/
	@echo "The pictures are in out/: a planning and an execution view per frame (PNG), the"
	@echo "whole run as out/run.gif, and the monitor's decisions in out/events.jsonl."

test: lint typecheck pytest

lint: $(INSTALLED)
	$(BIN)/ruff check anytime domains/navigation domains/routing domains/motion tests benchmarks docs conftest.py .ci
	$(BIN)/ruff format --check anytime domains/navigation domains/routing domains/motion tests benchmarks docs conftest.py .ci

typecheck: $(INSTALLED)
	$(BIN)/mypy

# In parallel, one worker per (logical) core with pytest-xdist; a file's tests on one worker, in
# order, but for a few long files (conftest.py's SPREAD). To debug, run `$(BIN)/pytest` itself:
# it runs serially (or `make pytest PYTEST_WORKERS=0`).
PYTEST_WORKERS ?= logical
pytest: $(INSTALLED)
	$(BIN)/pytest -n $(PYTEST_WORKERS) --dist loadfile

# The install a user gets: both wheels built, installed into a fresh environment outside the
# repository and run from another directory (CI runs it after `make test`).
wheel-check: $(INSTALLED)
	.ci/wheel-check $(BIN)/python

# Long checks, kept out of `make test`.
slow: $(INSTALLED)
	$(BIN)/pytest -m slow

# Every benchmark of benchmarks/ (quick settings where they exist), their tables written into
# docs/benchmarks.md; a few minutes, kept out of `make test`.
bench: $(INSTALLED)
	$(BIN)/python benchmarks/write_page.py

# The option lists of docs/cli.md, from the command line's own --help, and the API reference
# pages (docs/reference/), from the public packages' names (the tests check both).
docs: $(INSTALLED)
	$(BIN)/python docs/cli_help.py
	$(BIN)/python docs/api_pages.py

# The documentation site (site/): the pages of docs/ and the API reference from the
# docstrings, warnings as errors (CI builds it).
site: $(INSTALLED)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet

$(INSTALLED): pyproject.toml domains/navigation/pyproject.toml domains/routing/pyproject.toml \
		domains/motion/pyproject.toml
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info < (3, 11))' || \
		{ echo "anytime-compose needs Python >= 3.11 (set PYTHON=...)"; exit 1; }
	@echo "Setting up $(VENV) (once): installing anytime-compose, its three plugins and the tools"
	@echo "the tests use, from the package index; this takes a few minutes."
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]' -e domains/navigation \
		-e 'domains/routing[measure]' -e domains/motion
	@echo "Compiling the navigation planner's searches (numba, once; about 20 to 60 seconds)."
	$(BIN)/python -c 'from anytime_navigation.planning.planner import compile_searches; compile_searches()'
	@echo "$(VENV) is ready."
	touch $@

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache .hypothesis *.egg-info site
