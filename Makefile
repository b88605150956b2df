# mvkp — quick start: `make demo`, `make test`.
BUILD ?= build
PREFIX ?= /usr/local
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release

.PHONY: all deps configure build test demo install uninstall deb docs clean loadtest serve-latency

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

# Library, headers, CMake package, pkg-config file, CLI and Python module under
# PREFIX; `make uninstall` removes what the last install wrote (its manifest).
install: build
	cmake --install $(BUILD) --prefix $(PREFIX)

uninstall:
	@bash scripts/uninstall.sh $(BUILD)/install_manifest.txt

# Debian packages (CPack): libmvkp-dev, mvkp (CLI + server), python3-mvkp,
# written to $(BUILD)/packages/.
deb: build
	rm -rf $(BUILD)/packages
	cd $(BUILD) && cpack -G DEB -B "$$(pwd)/packages"
	rm -rf $(BUILD)/packages/_CPack_Packages
	@for f in $(BUILD)/packages/*.deb; do echo "$$f: $$(dpkg-deb -f $$f Depends)"; done

# API reference (Doxygen) of the public headers: $(BUILD)/docs/html/index.html.
docs: configure
	cmake --build $(BUILD) --target docs

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
