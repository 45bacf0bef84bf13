# The two commands a newcomer needs: `make run` and `make test`.
SHELL := /bin/bash
PY := .venv/bin/python
DRONES ?= 0
WEB_PORT ?= 8000
MQTT_PORT ?= 1883
BROKER ?= mosquitto
export WEB_PORT MQTT_PORT BROKER

.PHONY: run test bench loadtest lint format services-up services-down test-services-up test-services-down firmware-test

run:
	@scripts/bootstrap.sh run
	@$(PY) scripts/devrun.py --drones $(DRONES) --web-port $(WEB_PORT)

test:
	@scripts/bootstrap.sh test
	@scripts/test.sh

bench:
	@scripts/bootstrap.sh test
	@scripts/bench.sh

# A fleet of lightweight load drones against the whole ground side (docs/scaling.md).
loadtest:
	@scripts/bootstrap.sh test
	@$(PY) scripts/loadtest.py --drones $(if $(filter 0,$(DRONES)),1000,$(DRONES)) --broker $(BROKER)

lint:
	@$(PY) -m ruff check .
	@$(PY) -m ruff format --check .

format:
	@$(PY) -m ruff format .
	@$(PY) -m ruff check --fix .

services-up:
	@scripts/services.sh start run
services-down:
	@scripts/services.sh stop run
test-services-up:
	@scripts/services.sh start test
test-services-down:
	@scripts/services.sh stop test

firmware-test:
	@$(MAKE) -s -C firmware/arming_switch test
