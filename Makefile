# The whole set-up on a fresh machine with Python >= 3.11: `make demo` or `make test`.
# Both create .venv and install the project into it (editable, with the dev tools) when needed.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
INSTALLED := $(VENV)/.installed

.PHONY: demo test lint typecheck pytest slow clean

demo: $(INSTALLED)
	$(BIN)/anytime parse schemas/navigation.any
	$(BIN)/anytime compile schemas/navigation.any --schema navigate --library schemas/profiles \
		--time-grid 0:600:50 --resolution 10

test: lint typecheck pytest

lint: $(INSTALLED)
	$(BIN)/ruff check anytime domains tests benchmarks
	$(BIN)/ruff format --check anytime domains tests benchmarks

typecheck: $(INSTALLED)
	$(BIN)/mypy anytime

pytest: $(INSTALLED)
	$(BIN)/pytest

# Long checks, kept out of `make test`.
slow: $(INSTALLED)
	$(BIN)/pytest -m slow

$(INSTALLED): pyproject.toml
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info < (3, 11))' || \
		{ echo "anytime-compose needs Python >= 3.11 (set PYTHON=...)"; exit 1; }
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $@

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache .hypothesis *.egg-info
