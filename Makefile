# Two entry points (see README): `make run` and `make test`.
PY ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test test-fast typecheck lint bench soak chromium clean

$(BIN)/python:
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

## Install and start the app with the bundled demo show.
run: $(STAMP)
	$(BIN)/swarmshow demo

## Install everything the tests need (Debian's chromium included) and run the suite.
test: $(STAMP) chromium
	$(BIN)/ruff check .
	$(MAKE) typecheck
	$(BIN)/python -m pytest

## The fast tests only (no browser, no cluster or server process, no long flights): under a minute.
test-fast: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -m "not slow and not browser and not integration" -q

## mypy (strict on sim/ and formations/, see pyproject.toml) and tsc on the editor's // @ts-check modules.
## tsc comes from the npm registry through npx; without node/npm it is skipped with a note.
typecheck: $(STAMP)
	$(BIN)/mypy
	@if command -v npx >/dev/null 2>&1; then npx --yes -p typescript@5 tsc --noEmit -p .; \
	else echo "typecheck: npx not found, tsc skipped (install node and npm)"; fi

## Debian's chromium for browser tests (playwright cannot download browsers here), and libsndfile for the
## music (the soundfile wheels bundle it; a platform without a wheel needs Debian's).
chromium:
	@if [ ! -x /usr/bin/chromium ]; then \
		if [ "$$(id -u)" = 0 ]; then apt-get update -qq && apt-get install -y -qq chromium libsndfile1 >/dev/null; \
		else sudo apt-get update -qq && sudo apt-get install -y -qq chromium libsndfile1 >/dev/null; fi; \
	fi

lint: $(STAMP)
	$(BIN)/ruff check .

## Every benchmark (slow); writes benchmarks/results.json.
bench: $(STAMP)
	$(BIN)/python -m pytest -m slow -p no:cacheprovider benchmarks tests

## Crash, fuzz and load soak tests (slow; also part of `make bench`).
soak: $(STAMP)
	$(BIN)/python -m pytest -m slow -p no:cacheprovider tests/test_hardening_crash.py tests/test_api_fuzz.py benchmarks/bench_api.py

clean:
	rm -rf $(VENV) build *.egg-info
