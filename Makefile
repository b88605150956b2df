# mvkp — quick start: `make demo`, `make test`.
BUILD ?= build
PREFIX ?= /usr/local
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release

.PHONY: all deps configure build test demo install uninstall clean loadtest serve-latency

all: build

deps:
	@bash scripts/install-deps.sh

$(BUILD)/CMakeCache.txt:
	cmake -S . -B $(BUILD) $(CMAKE_FLAGS) -DCMAKE_INSTALL_PREFIX=$(PREFIX)

configure: deps $(BUILD)/CMakeCache.txt

build: configure
	cmake --build $(BUILD) -j $(JOBS)

test: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

demo: build
	@bash scripts/demo.sh $(BUILD)/mvkp

install: build
	cmake --install $(BUILD) --prefix $(PREFIX)

uninstall:
	@if [ -f $(BUILD)/install_manifest.txt ]; then xargs rm -fv < $(BUILD)/install_manifest.txt; else echo "nothing installed from $(BUILD)"; fi

clean:
	rm -rf $(BUILD)

# 16 clients for 60 s against `mvkp serve` on loopback (issue 7): throughput,
# p50/p99, errors, RSS; then the concurrency bound exceeded on purpose.
loadtest: build
	@bash scripts/loadtest.sh $(BUILD)/mvkp out/loadtest 60

# POST /api/recognize against 100 exhibits, 640x480 JPEGs, 2 server threads
# (issue 7: median <= 25 ms, p99 <= 60 ms end to end on loopback).
serve-latency: build
	@bash scripts/serve-latency.sh $(BUILD)/mvkp out/serve-latency
