# The two commands of the README: `make demo` (the main job on the shipped example) and
# `make test` (the whole suite, ruff and mypy). Each creates .venv and installs what it needs.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: demo test verify lint golden clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q torch==2.13.0
	$(BIN)/python -m pip install -q -e '.[dev,learn]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/mitlc fmt specs/paper/case1.mitl
	$(BIN)/mitlc parse specs/paper/case1.mitl

lint: $(STAMP)
	$(BIN)/ruff check mitlc tests
	$(BIN)/mypy

test: lint
	$(BIN)/pytest -q

# Longer seeded checks (the slow marker), beyond the default suite.
verify: $(STAMP)
	$(BIN)/pytest -q -m slow

# Rewrite golden files from the current output; read `git diff tests/golden` before committing.
golden: $(STAMP)
	$(BIN)/pytest -q tests --update-golden

clean:
	rm -rf $(VENV) build dist .pytest_cache .mypy_cache .ruff_cache .hypothesis
