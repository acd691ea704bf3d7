# The two commands of the README. Both install missing Debian packages first.
PRESET ?= release
BUILD_DIR := build/$(PRESET)
DEMO_OUT ?= demo-out

.PHONY: deps build demo test clean

deps:
	@bash scripts/install-deps.sh

build: deps
	@cmake --preset $(PRESET) >/dev/null
	@cmake --build --preset $(PRESET)

demo: build
	$(BUILD_DIR)/occmap demo --out $(DEMO_OUT)

test: build
	ctest --preset $(PRESET)

clean:
	rm -rf build
